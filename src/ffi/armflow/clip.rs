//! `troupe_armflow_clip_generate`: the official ARMFlow clip loop (see `crate::armflow::clip`).

use ndarray::ArrayView2;

use crate::ffi::boundary::{
    self, check_struct_size, non_null, read_versioned, troupe_status, write_versioned, FfiError,
    FfiResult, TROUPE_ERR_INVALID_ARG,
};
use crate::ffi::model::{optional_condition, property, troupe_model};
use crate::{Armflow, ClipNoise, ClipOptions, Model};

/// The settings of one `troupe_armflow_clip_generate_with_options` call. Fill with
/// `troupe_armflow_clip_options_init` (the bundle's defaults), then change fields. Fields are
/// only ever appended; `struct_size` tells the library which version the caller has.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_armflow_clip_options {
    /// `sizeof(troupe_armflow_clip_options)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// MeanFlow steps per token, >= 1 (`_init`: the bundle's, 1 for the official models).
    pub steps: u32,
    /// Seed of the draws when no noise is given.
    pub seed: u64,
    /// Classifier-free guidance scale, finite; 1 disables guidance (`_init`: the bundle's
    /// `sampler.cfg_scale`, which the official sampler applies).
    pub cfg_scale: f32,
    /// Must be 0.
    pub reserved: u32,
}

const CLIP_OPTIONS_V1_SIZE: usize = 24;
const _: () = assert!(std::mem::size_of::<troupe_armflow_clip_options>() == CLIP_OPTIONS_V1_SIZE);

/// `sizeof(troupe_armflow_clip_options)` in this library, for bindings to check their mirror.
#[no_mangle]
pub extern "C" fn troupe_armflow_clip_options_size() -> usize {
    std::mem::size_of::<troupe_armflow_clip_options>()
}

/// The model behind a handle and its ARMFlow API, or an error for NULL or another family.
fn armflow_model(model: Option<&troupe_model>) -> FfiResult<(&Model, &Armflow)> {
    let model = &boundary::required(model, "model")?.model;
    let armflow = model
        .armflow()
        .map_err(|_| model.wrong_family("armflow", "clip generation"))?;
    Ok((model, armflow))
}

/// The options `troupe_armflow_clip_options_init` writes: the bundle's sampler, seed 0.
fn clip_option_defaults(armflow: &Armflow, size: usize) -> troupe_armflow_clip_options {
    let sampler = &armflow.spec().sampler;
    troupe_armflow_clip_options {
        struct_size: size as u32,
        steps: sampler.steps,
        seed: 0,
        cfg_scale: sampler.cfg_scale,
        reserved: 0,
    }
}

/// Fills `options` with `model`'s sampler settings (MeanFlow steps, CFG scale) and seed 0, and
/// sets `struct_size`. Pass `sizeof(troupe_armflow_clip_options)` as `options_size`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`options_size` smaller
/// than the first version), `TROUPE_ERR_UNSUPPORTED` (not an `armflow` bundle). Thread-safe.
///
/// # Safety
/// `model` must be a live handle; `options` writable for `options_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_clip_options_init(
    model: Option<&troupe_model>,
    options: *mut troupe_armflow_clip_options,
    options_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_armflow_clip_options_init",
        || {},
        || {
            let (_, armflow) = armflow_model(model)?;
            non_null(options, "options")?;
            check_struct_size(
                options_size,
                CLIP_OPTIONS_V1_SIZE,
                "troupe_armflow_clip_options",
            )?;
            let defaults = clip_option_defaults(armflow, options_size);
            // SAFETY: writable for `options_size` bytes; no padding (asserted).
            unsafe { write_versioned(options, options_size, &defaults) };
            Ok(())
        },
    )
}

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

/// Runs the official ARMFlow sampler on one actor clip with the bundle's settings (its MeanFlow
/// steps when `steps` is 0, and its CFG scale, `sampler.cfg_scale`, as the official sampler
/// applies it): `troupe_armflow_clip_generate_with_options` with `steps` and `seed` set and
/// the rest of `troupe_armflow_clip_options_init`'s defaults. Writes the reactor motion,
/// row-major float32 `[clip_frames][frame_dim]`, into `frames` (capacity `frames_capacity`
/// floats), and, when `reactor_latents` is not NULL, the reactor tokens
/// `[clip_tokens][latent_dim]` into it (capacity `latents_capacity` floats).
///
/// `actor` holds `n_actor_frames` frames (1 to `troupe_model_clip_frames`), zero-padded to the
/// clip. `condition` holds `troupe_model_condition_dim` floats (NULL with `condition_len` 0:
/// the null condition). `noise` NULL draws from `seed` (the draws a session with that seed
/// makes for those tokens); otherwise it supplies every draw, the way to reproduce another
/// implementation's run exactly. Inputs are borrowed for the call; nothing is written unless
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
            let options = ClipOptions {
                seed,
                steps: (steps != 0).then_some(steps),
                ..ClipOptions::default()
            };
            // SAFETY: the pointers are as `generate_clip`'s contract states, per ours.
            unsafe {
                generate_clip(
                    model,
                    options,
                    actor,
                    n_actor_frames,
                    condition,
                    condition_len,
                    noise,
                    [
                        (frames, frames_capacity),
                        (reactor_latents, latents_capacity),
                    ],
                )
            }
        },
    )
}

/// `troupe_armflow_clip_generate` with every setting of the sampler: `options` NULL takes the
/// bundle's (`troupe_armflow_clip_options_init`). Guidance (`cfg_scale` other than 1) runs a
/// null row beside each conditional one, the actor token and the context zeroed, and takes
/// `u_null + cfg_scale * (u_cond - u_null)`, as the official sampler does.
///
/// ```c
/// troupe_armflow_clip_options opt;
/// troupe_armflow_clip_options_init(model, &opt, sizeof opt);
/// opt.cfg_scale = 2.0f;
/// troupe_status st = troupe_armflow_clip_generate_with_options(model, &opt, actor, n, NULL, 0,
///                                                             NULL, frames, n_frames, NULL, 0);
/// ```
///
/// Returns what `troupe_armflow_clip_generate` returns, and `TROUPE_ERR_INVALID_ARG` for
/// options out of range (0 steps, a non-finite or too large CFG scale, a non-zero `reserved`,
/// a wrong `struct_size`). Thread-safe: any number of threads may generate on one model at
/// once.
///
/// # Safety
/// As `troupe_armflow_clip_generate`; `options` NULL or readable for its `struct_size`.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_armflow_clip_generate_with_options(
    model: Option<&troupe_model>,
    options: *const troupe_armflow_clip_options,
    actor: *const f32,
    n_actor_frames: usize,
    condition: *const f32,
    condition_len: usize,
    noise: *const troupe_clip_noise,
    frames: *mut f32,
    frames_capacity: usize,
    reactor_latents: *mut f32,
    latents_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_armflow_clip_generate_with_options",
        || {},
        || {
            let (_, armflow) = armflow_model(model)?;
            let o = if options.is_null() {
                clip_option_defaults(armflow, CLIP_OPTIONS_V1_SIZE)
            } else {
                // SAFETY: readable for its `struct_size` per the contract.
                unsafe {
                    read_versioned(
                        options,
                        CLIP_OPTIONS_V1_SIZE,
                        || Ok(clip_option_defaults(armflow, CLIP_OPTIONS_V1_SIZE)),
                        "troupe_armflow_clip_options",
                        "troupe_armflow_clip_options_init",
                    )
                }?
            };
            if o.reserved != 0 {
                return Err(FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    "troupe_armflow_clip_options.reserved must be 0",
                ));
            }
            let options = ClipOptions {
                seed: o.seed,
                steps: Some(o.steps),
                cfg_scale: Some(o.cfg_scale),
                noise: None,
            };
            // SAFETY: the pointers are as `generate_clip`'s contract states, per ours.
            unsafe {
                generate_clip(
                    model,
                    options,
                    actor,
                    n_actor_frames,
                    condition,
                    condition_len,
                    noise,
                    [
                        (frames, frames_capacity),
                        (reactor_latents, latents_capacity),
                    ],
                )
            }
        },
    )
}

/// The clip calls' shared body: reads the inputs, generates, writes `out`'s frames and (when
/// not NULL) reactor latents.
///
/// # Safety
/// As `troupe_armflow_clip_generate`'s contract states for the same arguments.
#[allow(clippy::too_many_arguments)]
unsafe fn generate_clip(
    model: Option<&troupe_model>,
    mut options: ClipOptions,
    actor: *const f32,
    n_actor_frames: usize,
    condition: *const f32,
    condition_len: usize,
    noise: *const troupe_clip_noise,
    out: [(*mut f32, usize); 2],
) -> FfiResult {
    let [(frames, frames_capacity), (reactor_latents, latents_capacity)] = out;
    let (model, armflow) = armflow_model(model)?;
    let d = model.frame_dim();
    let n = boundary::checked_mul(n_actor_frames, d, "n_actor_frames * frame_dim")?;
    // SAFETY: readable for `n` floats per the contract.
    let actor = unsafe { boundary::slice(actor, n, "actor") }?;
    // SAFETY: readable for `condition_len` floats per the contract.
    let condition = unsafe { optional_condition(model, condition, condition_len) }?;
    // SAFETY: NULL or readable per the contract.
    options.noise = unsafe { noise.as_ref() }.map(read_noise).transpose()?;
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
