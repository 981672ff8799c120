//! `troupe_armflow_clip_generate`: the official ARMFlow clip loop (see `crate::armflow::clip`).

use ndarray::ArrayView2;

use crate::ffi::boundary::{self, non_null, troupe_status, FfiResult};
use crate::ffi::model::{optional_condition, property, troupe_model};
use crate::{ClipNoise, ClipOptions};

/// The random draws of one clip, given instead of seeded. Arrays are row-major float32, each
/// borrowed for the call; lengths are in floats.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_clip_noise {
    /// Standard normals of the actor posterior sample, `[clip_tokens][latent_dim]`.
    pub actor_posterior: *const f32,
    /// Length of `actor_posterior`.
    pub actor_posterior_len: usize,
    /// The one noise token every reactor token starts from, `[latent_dim]`.
    pub reactor_noise: *const f32,
    /// Length of `reactor_noise`.
    pub reactor_noise_len: usize,
}

/// Tokens of the official clip of an `armflow` bundle exported from the official layout (75
/// InterHuman, 37 InterX); 0 for other bundles or NULL. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_clip_tokens(model: Option<&troupe_model>) -> usize {
    property(model, |m| {
        m.armflow()
            .ok()
            .and_then(|a| a.clip_spec())
            .map_or(0, |c| c.tokens)
    })
}

/// Runs the official ARMFlow sampler on one actor clip and writes the reactor motion, row-major
/// float32 `[clip_frames][frame_dim]`, into `frames` (capacity `frames_capacity` floats), and,
/// when `reactor_latents` is not NULL, the reactor tokens `[clip_tokens][latent_dim]` into it
/// (capacity `latents_capacity` floats).
///
/// `actor` holds `n_actor_frames` frames (1 to `troupe_model_clip_frames`), zero-padded to the
/// clip. `condition` holds `troupe_model_condition_dim` floats (NULL with `condition_len` 0:
/// the null condition). `steps` is the MeanFlow steps per token, 0 for the bundle's default.
/// `noise` NULL draws from `seed` (the draws a session with that seed makes for those tokens);
/// otherwise it supplies every draw. Inputs are borrowed for the call; nothing is written unless
/// the call succeeds.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not an `armflow`
/// bundle), `TROUPE_ERR_INVALID_ARG` (a bundle without a clip, a clip of 0 or too many frames, non-finite input, bad noise length: the message says
/// which), `TROUPE_ERR_SHAPE` (condition length), `TROUPE_ERR_BUFFER_TOO_SMALL`,
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may generate
/// on one model at once.
///
/// # Safety
/// `model` must be a live handle; `actor` readable for `n_actor_frames * frame_dim` floats;
/// `condition` for `condition_len`; `noise` NULL or a readable struct whose arrays are readable
/// for their lengths; `frames` writable for `frames_capacity` floats and `reactor_latents` (if
/// not NULL) for `latents_capacity`, neither overlapping an input.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_armflow_clip_generate(
    model: Option<&troupe_model>,
    actor: *const f32,
    n_actor_frames: usize,
    condition: *const f32,
    condition_len: usize,
    seed: u64,
    steps: u32,
    noise: *const troupe_clip_noise,
    frames: *mut f32,
    frames_capacity: usize,
    reactor_latents: *mut f32,
    latents_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_armflow_clip_generate",
        || {},
        || {
            let model = &boundary::required(model, "model")?.model;
            let d = model.frame_dim();
            let n = boundary::checked_mul(n_actor_frames, d, "n_actor_frames * frame_dim")?;
            // SAFETY: readable for `n` floats per the contract.
            let actor = unsafe { boundary::slice(actor, n, "actor") }?;
            // SAFETY: readable for `condition_len` floats per the contract.
            let condition = unsafe { optional_condition(model, condition, condition_len) }?;
            let options = ClipOptions {
                seed,
                steps: (steps != 0).then_some(steps),
                // SAFETY: NULL or readable per the contract.
                noise: unsafe { noise.as_ref() }.map(read_noise).transpose()?,
            };
            let armflow = model
                .armflow()
                .map_err(|_| model.wrong_family("armflow", "clip generation"))?;
            let tokens = armflow.clip_spec().map_or(0, |c| c.tokens);
            let need = model.clip_frames() * d;
            let latent_need = tokens * model.latent_dim();
            non_null(frames, "frames")?;
            boundary::room(need, frames_capacity, "the frames")?;
            if !reactor_latents.is_null() {
                boundary::room(latent_need, latents_capacity, "the reactor latents")?;
            }
            let actor = ArrayView2::from_shape((n_actor_frames, d), actor)
                .expect("n_actor_frames * frame_dim floats");
            let clip = armflow.generate_clip(actor, condition, &options)?;
            let out = clip.frames.as_slice().expect("standard layout");
            // SAFETY: non-NULL, writable for frames_capacity >= need floats.
            unsafe { std::ptr::copy_nonoverlapping(out.as_ptr(), frames, out.len()) };
            if !reactor_latents.is_null() {
                let z = clip.reactor_latents.as_slice().expect("standard layout");
                // SAFETY: non-NULL, writable for latents_capacity >= latent_need floats.
                unsafe { std::ptr::copy_nonoverlapping(z.as_ptr(), reactor_latents, z.len()) };
            }
            Ok(())
        },
    )
}

fn read_noise(n: &troupe_clip_noise) -> FfiResult<ClipNoise> {
    // SAFETY: the arrays are readable for their lengths per troupe_armflow_clip_generate's contract.
    let (a, r) = unsafe {
        (
            boundary::slice(
                n.actor_posterior,
                n.actor_posterior_len,
                "noise.actor_posterior",
            )?,
            boundary::slice(n.reactor_noise, n.reactor_noise_len, "noise.reactor_noise")?,
        )
    };
    Ok(ClipNoise {
        actor_posterior: a.to_vec(),
        reactor_noise: r.to_vec(),
    })
}
