//! The C entry points of the `magnet` family: its released sampling configurations and
//! `troupe_magnet_generate`.

pub mod session;

use std::ffi::{c_char, CStr};

use crate::ffi::boundary::{
    self, check_struct_size, checked_mul, non_null, read_versioned, room, troupe_status,
    write_versioned, FfiError, FfiResult, TROUPE_ERR_INVALID_ARG,
};
use crate::ffi::model::{property, troupe_model};
use crate::magnet::layout::FRAME_DIM;
use crate::{Magnet, MagnetOptions};

/// `troupe_magnet_options.flags`: use `seed` instead of the configuration's.
pub const TROUPE_MAGNET_SEED: u32 = 1;
/// `troupe_magnet_options.flags`: use `eta` instead of the configuration's.
pub const TROUPE_MAGNET_ETA: u32 = 2;
/// `troupe_magnet_options.flags`: turn the x0 corrections (smoothing, foot skating) off; three
/// to five times cheaper (`docs/MAGNET.md`), not the released behaviour.
pub const TROUPE_MAGNET_NO_X0_GUIDANCE: u32 = 4;
/// `troupe_magnet_options.flags`: use the first `keyframe_count` of `keyframes`.
pub const TROUPE_MAGNET_KEYFRAMES: u32 = 8;
/// The most key frames `troupe_magnet_options` can carry.
pub const TROUPE_MAGNET_MAX_KEYFRAMES: usize = 8;

const KNOWN_FLAGS: u32 =
    TROUPE_MAGNET_SEED | TROUPE_MAGNET_ETA | TROUPE_MAGNET_NO_X0_GUIDANCE | TROUPE_MAGNET_KEYFRAMES;

/// Changes to a released configuration for one `troupe_magnet_generate` call. Fill with
/// `troupe_magnet_options_init` (no changes), then set fields; zero counts keep the
/// configuration's value. Fields are only ever appended; `struct_size` tells the library which
/// version the caller has.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_magnet_options {
    /// `sizeof(troupe_magnet_options)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// Samples generated at once (S); 0 keeps the configuration's.
    pub samples: u32,
    /// DDIM steps; 0 keeps the configuration's.
    pub steps: u32,
    /// Frames to generate (`sampling_seq_len`); 0 keeps the configuration's.
    pub seq_len: u32,
    /// `TROUPE_MAGNET_*` flags.
    pub flags: u32,
    /// Key frames used with `TROUPE_MAGNET_KEYFRAMES`.
    pub keyframe_count: u32,
    /// Seed of troupe's generator, with `TROUPE_MAGNET_SEED`.
    pub seed: u64,
    /// DDIM η, with `TROUPE_MAGNET_ETA`.
    pub eta: f32,
    /// Must be 0.
    pub reserved: u32,
    /// In-betweening's key frames (frames `k..k + 4` set token `k / 4`).
    pub keyframes: [u32; TROUPE_MAGNET_MAX_KEYFRAMES],
}

const OPTIONS_V1_SIZE: usize = 72;
const _: () = assert!(std::mem::size_of::<troupe_magnet_options>() == OPTIONS_V1_SIZE);

/// `sizeof(troupe_magnet_options)` in this library, for bindings to check their mirror.
#[no_mangle]
pub extern "C" fn troupe_magnet_options_size() -> usize {
    std::mem::size_of::<troupe_magnet_options>()
}

/// The options `troupe_magnet_options_init` writes: every field 0, "change nothing".
fn no_changes(size: usize) -> troupe_magnet_options {
    troupe_magnet_options {
        struct_size: size as u32,
        samples: 0,
        steps: 0,
        seq_len: 0,
        flags: 0,
        keyframe_count: 0,
        seed: 0,
        eta: 0.0,
        reserved: 0,
        keyframes: [0; TROUPE_MAGNET_MAX_KEYFRAMES],
    }
}

/// Fills `options` with no changes (every field 0) and sets `struct_size`. Pass
/// `sizeof(troupe_magnet_options)` as `options_size`: the library writes only that many bytes.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, or `TROUPE_ERR_INVALID_ARG` (`options_size`
/// smaller than the first version). Thread-safe.
///
/// # Safety
/// `options` must be writable for `options_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_options_init(
    options: *mut troupe_magnet_options,
    options_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_magnet_options_init",
        || {},
        || {
            non_null(options, "options")?;
            check_struct_size(options_size, OPTIONS_V1_SIZE, "troupe_magnet_options")?;
            let empty = no_changes(options_size);
            // SAFETY: writable for `options_size` bytes per the contract; no padding (asserted).
            unsafe { write_versioned(options, options_size, &empty) };
            Ok(())
        },
    )
}

/// People a `magnet` model generates together (its checkpoint's P); 0 for other bundles or
/// NULL. Frames in and out are `[frames][people][145]`. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_people(model: Option<&troupe_model>) -> usize {
    property(model, |m| m.magnet().map_or(0, |g| g.spec().model.persons))
}

/// How many released sampling configurations a `magnet` bundle lists (0 for other bundles or
/// NULL). Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_config_count(model: Option<&troupe_model>) -> usize {
    model.map_or(0, |m| m.magnet_configs.len())
}

/// The name of released configuration `index` (`"dd100"`, `"dd100_partner_prediction"`, ...),
/// or NULL for NULL or an index out of range. Owned by the model and valid until
/// `troupe_model_free`; never free it. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_config(
    model: Option<&troupe_model>,
    index: usize,
) -> *const c_char {
    model
        .and_then(|m| m.magnet_configs.get(index))
        .map_or(std::ptr::null(), |name| name.as_ptr())
}

/// # Safety
/// `config` must be a readable NUL-terminated string.
unsafe fn config_name<'a>(config: *const c_char) -> FfiResult<&'a str> {
    non_null(config, "config")?;
    // SAFETY: non-NULL and NUL-terminated per the contract.
    let name = unsafe { CStr::from_ptr(config) };
    name.to_str()
        .map_err(|_| FfiError::new(TROUPE_ERR_INVALID_ARG, "config is not UTF-8".to_string()))
}

/// # Safety
/// `options` must be NULL or readable for its `struct_size` bytes.
unsafe fn read_options(options: *const troupe_magnet_options) -> FfiResult<MagnetOptions> {
    if options.is_null() {
        return Ok(MagnetOptions::default());
    }
    // SAFETY: readable per the contract.
    let o: troupe_magnet_options = unsafe {
        read_versioned(
            options,
            OPTIONS_V1_SIZE,
            || Ok(no_changes(OPTIONS_V1_SIZE)),
            "troupe_magnet_options",
            "troupe_magnet_options_init",
        )
    }?;
    let bad = |message: String| FfiError::new(TROUPE_ERR_INVALID_ARG, message);
    if o.flags & !KNOWN_FLAGS != 0 || o.reserved != 0 {
        return Err(bad(format!(
            "troupe_magnet_options: unknown flags {:#x} or a non-zero reserved field",
            o.flags & !KNOWN_FLAGS
        )));
    }
    let count = o.keyframe_count as usize;
    if o.flags & TROUPE_MAGNET_KEYFRAMES != 0 && count > TROUPE_MAGNET_MAX_KEYFRAMES {
        return Err(bad(format!(
            "keyframe_count {count} is above {TROUPE_MAGNET_MAX_KEYFRAMES}"
        )));
    }
    let some = |v: u32| (v > 0).then_some(v as usize);
    Ok(MagnetOptions {
        samples: some(o.samples),
        steps: some(o.steps),
        seq_len: some(o.seq_len),
        seed: (o.flags & TROUPE_MAGNET_SEED != 0).then_some(o.seed),
        eta: (o.flags & TROUPE_MAGNET_ETA != 0).then_some(o.eta),
        without_x0_guidance: o.flags & TROUPE_MAGNET_NO_X0_GUIDANCE != 0,
        keyframes: (o.flags & TROUPE_MAGNET_KEYFRAMES != 0)
            .then(|| o.keyframes[..count].iter().map(|&k| k as usize).collect()),
        draws: None,
        normals: None,
    })
}

/// The model behind a handle as MAGNet, or an error for NULL or another family.
fn magnet_model(model: Option<&troupe_model>) -> FfiResult<&Magnet> {
    let model = &boundary::required(model, "model")?.model;
    Ok(model
        .magnet()
        .map_err(|_| model.wrong_family("magnet", "MAGNet generation"))?)
}

/// Writes the shape of the frames `troupe_magnet_generate` returns for `frame_count` frames of
/// input: `*samples`, `*frames`, `*people` (each float row is 145 wide). Any out-pointer may be
/// NULL. Makes the same checks of the configuration and the input's length as the generation.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not a `magnet` bundle),
/// `TROUPE_ERR_INVALID_ARG` (an unknown configuration, options the model cannot run, too few
/// input frames). Thread-safe.
///
/// # Safety
/// `model` must be a live handle; `config` a NUL-terminated string; `options` NULL or readable
/// for its `struct_size`; each non-NULL out-pointer writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_output_shape(
    model: Option<&troupe_model>,
    config: *const c_char,
    options: *const troupe_magnet_options,
    frame_count: usize,
    samples: *mut usize,
    frames: *mut usize,
    people: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_magnet_output_shape",
        || {},
        || {
            let model = magnet_model(model)?;
            // SAFETY: per the contract.
            let (name, opts) = unsafe { (config_name(config)?, read_options(options)?) };
            let shape = model.output_shape(name, frame_count, &opts)?;
            for (out, value) in [(samples, shape[0]), (frames, shape[1]), (people, shape[2])] {
                if !out.is_null() {
                    // SAFETY: non-NULL, writable per the contract.
                    unsafe { *out = value };
                }
            }
            Ok(())
        },
    )
}

/// Runs the sampling configuration `config` (a name from `troupe_magnet_config`, or a
/// whole configuration as a JSON object with the fields of the manifest's `sampling` entries) on
/// `frame_count` frames of troupe motion, row-major float32 `[frame_count][people][145]` (per
/// person and frame: betas, the 21 body joints' 6-D rotations, the root's pose in the world, y
/// up), and writes the frames it generates, `[samples][frames][people][145]`
/// (`troupe_magnet_output_shape`), into `out` (capacity `out_capacity` floats). `present`
/// (NULL: everyone) is `[frame_count][people]` bytes, non-zero where the person is present.
/// What the input is depends on the task: the context for joint generation, turn-taking and
/// sync; person 0's whole motion for partner prediction, the live partner, inpainting and
/// pp2joint; the key frames for in-betweening. `options` NULL runs the configuration as
/// released. Inputs are borrowed for the call; nothing is written unless it succeeds.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not a `magnet` bundle),
/// `TROUPE_ERR_INVALID_ARG` (an unknown configuration, bad options, non-finite input, too few frames: the message says
/// which), `TROUPE_ERR_SHAPE`, `TROUPE_ERR_BUFFER_TOO_SMALL` (the message gives the floats
/// needed), `TROUPE_ERR_CANCELLED` (the progress callback stopped it), `TROUPE_ERR_INFERENCE`,
/// `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may generate on one model at once.
/// Reports progress (network calls done, of the run's iterations) to the calling thread's
/// progress callback.
///
/// ```c
/// size_t s, f, p;
/// troupe_magnet_output_shape(model, "dd100", NULL, n_frames, &s, &f, &p);
/// float *out = malloc(s * f * p * 145 * sizeof *out);
/// troupe_status st = troupe_magnet_generate(model, "dd100", NULL, frames, n_frames, NULL,
///                                           out, s * f * p * 145);
/// ```
///
/// # Safety
/// `model` must be a live handle; `config` a NUL-terminated string; `options` NULL or readable
/// for its `struct_size`; `frames` readable for `frame_count * people * 145` floats; `present`
/// NULL or readable for `frame_count * people` bytes; `out` writable for `out_capacity` floats
/// and not overlapping an input.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_magnet_generate(
    model: Option<&troupe_model>,
    config: *const c_char,
    options: *const troupe_magnet_options,
    frames: *const f32,
    frame_count: usize,
    present: *const u8,
    out: *mut f32,
    out_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_magnet_generate",
        || {},
        || {
            // SAFETY: per the contract, which `generate` shares.
            unsafe {
                generate(
                    model,
                    config,
                    options,
                    (frames, frame_count, present),
                    None,
                    (out, out_capacity),
                )
            }
            .map(|_| ())
        },
    )
}

/// `troupe_magnet_generate` with the run's standard normals given instead of drawn: `draws`
/// holds `draws_len` normals (borrowed for the call), and each draw the sampler makes, in the
/// order `docs/MAGNET.md` lists, takes the next ones it needs. This is how a run of another
/// implementation (the official code, with its random draws recorded) is reproduced exactly.
/// `*draws_used` (when not NULL) receives how many it took; a run that needs more than given
/// fails with `TROUPE_ERR_INVALID_ARG`, naming the draw. Nothing is written unless the call
/// succeeds.
///
/// Returns what `troupe_magnet_generate` returns. Thread-safe: any number of threads may
/// generate on one model at once.
///
/// # Safety
/// As `troupe_magnet_generate`; `draws` readable for `draws_len` floats; `draws_used` NULL or
/// writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_magnet_generate_with_draws(
    model: Option<&troupe_model>,
    config: *const c_char,
    options: *const troupe_magnet_options,
    frames: *const f32,
    frame_count: usize,
    present: *const u8,
    draws: *const f32,
    draws_len: usize,
    draws_used: *mut usize,
    out: *mut f32,
    out_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_magnet_generate_with_draws",
        || {},
        || {
            // SAFETY: readable for `draws_len` floats per the contract.
            let normals = unsafe { boundary::slice(draws, draws_len, "draws") }?.to_vec();
            // SAFETY: per the contract, which `generate` shares.
            let used = unsafe {
                generate(
                    model,
                    config,
                    options,
                    (frames, frame_count, present),
                    Some(normals),
                    (out, out_capacity),
                )
            }?;
            if !draws_used.is_null() {
                // SAFETY: non-NULL, writable per the contract.
                unsafe { *draws_used = used };
            }
            Ok(())
        },
    )
}

/// The generation calls' shared body; returns the injected normals used.
///
/// # Safety
/// As `troupe_magnet_generate`'s contract states for the same arguments.
unsafe fn generate(
    model: Option<&troupe_model>,
    config: *const c_char,
    options: *const troupe_magnet_options,
    (frames, frame_count, present): (*const f32, usize, *const u8),
    normals: Option<Vec<f32>>,
    (out, out_capacity): (*mut f32, usize),
) -> FfiResult<usize> {
    let model = magnet_model(model)?;
    // SAFETY: per the contract.
    let (name, mut opts) = unsafe { (config_name(config)?, read_options(options)?) };
    opts.normals = normals;
    let people = model.spec().model.persons;
    let shape = model.output_shape(name, frame_count, &opts)?;
    let need = checked_mul(
        checked_mul(shape[0], shape[1], "samples * frames")?,
        checked_mul(shape[2], shape[3], "people * 145")?,
        "output floats",
    )?;
    non_null(out, "out")?;
    room(need, out_capacity, "out")?;
    non_null(frames, "frames")?;
    let len = checked_mul(
        checked_mul(frame_count, people, "frames * people")?,
        FRAME_DIM,
        "input floats",
    )?;
    // SAFETY: readable for `frame_count * people * 145` floats per the contract.
    let input = unsafe { std::slice::from_raw_parts(frames, len) };
    let input = ndarray::ArrayView3::from_shape((frame_count, people, FRAME_DIM), input)
        .expect("sized above");
    let mask = if present.is_null() {
        None
    } else {
        // SAFETY: readable for `frame_count * people` bytes per the contract.
        let bytes = unsafe { std::slice::from_raw_parts(present, frame_count * people) };
        Some(
            ndarray::Array2::from_shape_vec(
                (frame_count, people),
                bytes.iter().map(|&b| b != 0).collect(),
            )
            .expect("sized above"),
        )
    };
    let result = model.generate(name, input, mask.as_ref().map(|m| m.view()), &opts)?;
    let values = result.frames.as_slice().expect("standard layout");
    // SAFETY: `out` is non-NULL and writable for out_capacity >= need floats.
    unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), out, values.len()) };
    Ok(result.normals_used)
}
