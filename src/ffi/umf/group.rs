//! `troupe_umf_generate`: text-to-group generation with a `umf` bundle.

use crate::ffi::boundary::{
    self, check_struct_size, checked_mul, non_null, read_versioned, troupe_status, write_versioned,
    FfiError, FfiResult, TROUPE_ERR_BUFFER_TOO_SMALL, TROUPE_ERR_INVALID_ARG, TROUPE_ERR_SHAPE,
};
use crate::ffi::model::{optional_condition, property, troupe_model};
use crate::manifest::UmfSpec;
use crate::{GroupNoise, GroupNoiseShape, GroupOptions, Method, Model, Solver, Umf};

/// Forward Euler.
pub const TROUPE_SOLVER_EULER: u32 = 1;
/// The 3/8-rule fourth-order Runge-Kutta (torchdiffeq's `rk4`, UMF's solver).
pub const TROUPE_SOLVER_RK4: u32 = 2;
/// The most pyramid stages `troupe_group_options` can describe.
pub const TROUPE_MAX_STAGES: usize = 8;

/// Options of `troupe_umf_generate`. Fill with `troupe_umf_options_init` (the bundle's
/// defaults), then change fields. Fields are only ever appended; `struct_size` tells the library
/// which version the caller has.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_group_options {
    /// `sizeof(troupe_group_options)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// Pyramid stages of the bundle; must equal `troupe_umf_stages`.
    pub stage_count: u32,
    /// Seed of the portable noise generator, for draws not given as `troupe_group_noise`.
    pub seed: u64,
    /// Classifier-free guidance scale, finite; 1 runs the conditional branch only.
    pub cfg_scale: f32,
    /// Solver of each further person: `TROUPE_SOLVER_EULER` or `TROUPE_SOLVER_RK4`.
    pub reaction_solver: u32,
    /// Intervals of the further persons' solve, >= 1.
    pub reaction_steps: u32,
    /// Must be 0.
    pub reserved: u32,
    /// Solver of each pyramid stage, coarsest first (the first `stage_count` are read).
    pub stage_solver: [u32; TROUPE_MAX_STAGES],
    /// Intervals of each pyramid stage, >= 1.
    pub stage_steps: [u32; TROUPE_MAX_STAGES],
}

/// Every random draw of one generation, given instead of seeded. Arrays are row-major float32;
/// each pointer is borrowed for the call and its length is in floats.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_group_noise {
    /// First person's start at the coarsest stage, `[stage 0 tokens][latent_dim]`.
    pub prior: *const f32,
    /// Length of `prior`.
    pub prior_len: usize,
    /// Block noise of each jump, concatenated in stage order: `[stage k tokens][latent_dim]` for
    /// k = 1, 2, ...
    pub jumps: *const f32,
    /// Length of `jumps`.
    pub jumps_len: usize,
    /// Noise half of each further person's start, `[people - 1][tokens][latent_dim]`.
    pub reactions: *const f32,
    /// Length of `reactions`.
    pub reactions_len: usize,
}

/// `sizeof(troupe_group_options)` in this library, for bindings to check their mirror.
#[no_mangle]
pub extern "C" fn troupe_umf_options_size() -> usize {
    std::mem::size_of::<troupe_group_options>()
}

/// The size of the first published `troupe_group_options`.
const OPTIONS_V1_SIZE: usize = 96;
const _: () = assert!(std::mem::size_of::<troupe_group_options>() == OPTIONS_V1_SIZE);

fn solver_code(method: Method) -> u32 {
    match method {
        Method::Euler => TROUPE_SOLVER_EULER,
        Method::Rk4 => TROUPE_SOLVER_RK4,
    }
}

fn solver_from(code: u32, steps: u32, what: &str) -> FfiResult<Solver> {
    let method = match code {
        TROUPE_SOLVER_EULER => Method::Euler,
        TROUPE_SOLVER_RK4 => Method::Rk4,
        other => {
            return Err(FfiError::new(
                TROUPE_ERR_INVALID_ARG,
                format!("{what} {other} is neither TROUPE_SOLVER_EULER nor TROUPE_SOLVER_RK4"),
            ))
        }
    };
    Ok(Solver { method, steps })
}

/// The model behind a handle and its `umf` fields, or an error for NULL or another family.
fn umf_model(model: Option<&troupe_model>) -> FfiResult<(&Model, &Umf)> {
    let model = &boundary::required(model, "model")?.model;
    let umf = model
        .umf()
        .map_err(|_| model.wrong_family("umf", "group generation"))?;
    Ok((model, umf))
}

/// The options `troupe_umf_options_init` writes: the bundle's solvers and CFG scale, seed 0.
fn option_defaults(spec: &UmfSpec, size: usize) -> FfiResult<troupe_group_options> {
    let stages = &spec.sampler.prior;
    if stages.len() > TROUPE_MAX_STAGES {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!(
                "the bundle has {} stages; the C API describes at most {TROUPE_MAX_STAGES}",
                stages.len()
            ),
        ));
    }
    let mut defaults = troupe_group_options {
        struct_size: size as u32,
        stage_count: stages.len() as u32,
        seed: 0,
        cfg_scale: spec.sampler.cfg_scale,
        reaction_solver: solver_code(spec.sampler.reaction.method),
        reaction_steps: spec.sampler.reaction.steps,
        reserved: 0,
        stage_solver: [0; TROUPE_MAX_STAGES],
        stage_steps: [0; TROUPE_MAX_STAGES],
    };
    for (k, solver) in stages.iter().enumerate() {
        defaults.stage_solver[k] = solver_code(solver.method);
        defaults.stage_steps[k] = solver.steps;
    }
    Ok(defaults)
}

/// Fills `options` with the defaults of `model`'s bundle (solvers per stage and for further
/// persons, CFG scale) and seed 0, and sets `struct_size`. Pass `sizeof(troupe_group_options)`
/// as `options_size`: the library writes only that many bytes.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`options_size`
/// smaller than the first version, or a bundle with more than `TROUPE_MAX_STAGES` stages),
/// `TROUPE_ERR_UNSUPPORTED` (not a `umf` bundle). Thread-safe.
///
/// ```c
/// troupe_group_options opt;
/// troupe_umf_options_init(model, &opt, sizeof opt);
/// opt.stage_solver[0] = TROUPE_SOLVER_EULER; opt.stage_steps[0] = 45;
/// ```
///
/// # Safety
/// `model` must be a live handle; `options` must be writable for `options_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_umf_options_init(
    model: Option<&troupe_model>,
    options: *mut troupe_group_options,
    options_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_umf_options_init",
        || {},
        || {
            non_null(options, "options")?;
            check_struct_size(options_size, OPTIONS_V1_SIZE, "troupe_group_options")?;
            let spec = umf_model(model)?.1.spec();
            let defaults = option_defaults(spec, options_size)?;
            // SAFETY: writable for `options_size` bytes per the contract; no padding (asserted).
            unsafe { write_versioned(options, options_size, &defaults) };
            Ok(())
        },
    )
}

/// Pyramid stages of a `umf` bundle (0 for other bundles or NULL). Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_umf_stages(model: Option<&troupe_model>) -> usize {
    property(model, |m| {
        m.umf().map_or(0, |u| u.spec().pyramid.stages.len())
    })
}

/// Latent tokens per person of a `umf` bundle at full resolution (0 for other bundles or
/// NULL). A person's latent is `tokens * troupe_model_latent_dim` floats. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_umf_tokens(model: Option<&troupe_model>) -> usize {
    property(model, |m| m.umf().map_or(0, |u| u.spec().latent.tokens))
}

/// Writes the lengths, in floats, of the three arrays of a `troupe_group_noise` for `people`
/// people. Any out-pointer may be NULL.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG` (model), `TROUPE_ERR_INVALID_ARG` (people outside
/// 1..=256), `TROUPE_ERR_UNSUPPORTED` (not a `umf` bundle). Thread-safe.
///
/// # Safety
/// `model` must be a live handle; each non-NULL out-pointer writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_umf_noise_lengths(
    model: Option<&troupe_model>,
    people: u32,
    prior_len: *mut usize,
    jumps_len: *mut usize,
    reactions_len: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_umf_noise_lengths",
        || {},
        || {
            let shape = umf_model(model)?.1.group_noise_shape(people as usize)?;
            for (out, value) in [
                (prior_len, shape.prior),
                (jumps_len, shape.jumps.iter().sum()),
                (reactions_len, shape.reactions * shape.reaction),
            ] {
                if !out.is_null() {
                    // SAFETY: non-NULL, writable per the contract.
                    unsafe { *out = value };
                }
            }
            Ok(())
        },
    )
}

/// Generates a group of `people` persons for `condition` and writes their motion, row-major
/// float32 `[people][clip_frames][frame_dim]`, into `motion` (capacity `motion_capacity`
/// floats), and, when `latents` is not NULL, their latents `[people][tokens][latent_dim]` into
/// `latents` (capacity `latents_capacity` floats).
///
/// `condition` holds `troupe_model_condition_dim` floats, the prior text feature then the
/// reaction text feature; NULL (with `condition_len` 0) is the bundle's null condition.
/// `options` NULL means the bundle's defaults with seed 0. `noise` NULL draws every random value
/// from `options->seed`; otherwise it supplies them all (lengths from
/// `troupe_umf_noise_lengths`). Inputs are borrowed for the call. Nothing is written unless
/// the call succeeds.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (people outside
/// 1..=256, bad options, non-finite input: the message says which), `TROUPE_ERR_UNSUPPORTED`
/// (not a `umf` bundle),
/// `TROUPE_ERR_SHAPE` (condition or noise length), `TROUPE_ERR_BUFFER_TOO_SMALL` (the message
/// gives the floats needed), `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number
/// of threads may generate on one model at once.
///
/// ```c
/// size_t n = 2 * troupe_model_clip_frames(model) * troupe_model_frame_dim(model);
/// float *motion = malloc(n * sizeof *motion);
/// troupe_status st = troupe_umf_generate(model, NULL, text, text_len, 2, NULL,
///                                          motion, n, NULL, 0);
/// ```
///
/// # Safety
/// `model` must be a live handle; `options` NULL or readable for its `struct_size`;
/// `condition` readable for `condition_len` floats; `noise` NULL or a readable struct whose
/// arrays are readable for their lengths; `motion` writable for `motion_capacity` floats and
/// `latents` (if not NULL) for `latents_capacity`, neither overlapping an input.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_umf_generate(
    model: Option<&troupe_model>,
    options: *const troupe_group_options,
    condition: *const f32,
    condition_len: usize,
    people: u32,
    noise: *const troupe_group_noise,
    motion: *mut f32,
    motion_capacity: usize,
    latents: *mut f32,
    latents_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_umf_generate",
        || {},
        || {
            let (model, umf) = umf_model(model)?;
            let spec = umf.spec();
            let people_n = people as usize;
            let mut opts = if options.is_null() {
                GroupOptions::default()
            } else {
                // SAFETY: readable per the contract.
                unsafe { read_group_options(spec, options) }?
            };
            // SAFETY: readable for `condition_len` floats per the contract.
            let condition = unsafe { optional_condition(model, condition, condition_len) }?;
            // The noise's shape doubles as the check of `people`.
            let shape = umf.group_noise_shape(people_n)?;
            if !noise.is_null() {
                // SAFETY: readable per the contract.
                opts.noise = Some(unsafe { read_noise(&*noise, &shape) }?);
            }
            let frames = checked_mul(people_n, model.clip_frames(), "people * clip_frames")?;
            let need = checked_mul(frames, model.frame_dim(), "motion floats")?;
            non_null(motion, "motion")?;
            if motion_capacity < need {
                return Err(FfiError::new(
                    TROUPE_ERR_BUFFER_TOO_SMALL,
                    format!("the motion needs {need} floats, the buffer holds {motion_capacity}"),
                ));
            }
            let latent_need = people_n * spec.latent.tokens * spec.latent.dim;
            if !latents.is_null() && latents_capacity < latent_need {
                return Err(FfiError::new(
                    TROUPE_ERR_BUFFER_TOO_SMALL,
                    format!(
                        "the latents need {latent_need} floats, the buffer holds {latents_capacity}"
                    ),
                ));
            }
            let group = umf.generate_group(condition, people_n, &opts)?;
            let out = group.motion.as_slice().expect("standard layout");
            // SAFETY: `motion` is non-NULL and writable for motion_capacity >= need floats.
            unsafe { std::ptr::copy_nonoverlapping(out.as_ptr(), motion, out.len()) };
            if !latents.is_null() {
                let z = group.latents.as_slice().expect("standard layout");
                // SAFETY: non-NULL and writable for latents_capacity >= latent_need floats.
                unsafe { std::ptr::copy_nonoverlapping(z.as_ptr(), latents, z.len()) };
            }
            Ok(())
        },
    )
}

/// # Safety
/// `options` must be readable for its `struct_size` bytes.
unsafe fn read_group_options(
    spec: &UmfSpec,
    options: *const troupe_group_options,
) -> FfiResult<GroupOptions> {
    // SAFETY: forwarded contract.
    let o = unsafe {
        read_versioned(
            options,
            OPTIONS_V1_SIZE,
            || option_defaults(spec, OPTIONS_V1_SIZE),
            "options",
            "troupe_umf_options_init",
        )
    }?;
    if o.reserved != 0 {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            "options.reserved must be 0",
        ));
    }
    let count = o.stage_count as usize;
    if count > TROUPE_MAX_STAGES {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("options.stage_count {count} exceeds TROUPE_MAX_STAGES ({TROUPE_MAX_STAGES})"),
        ));
    }
    let prior = (0..count)
        .map(|k| {
            solver_from(
                o.stage_solver[k],
                o.stage_steps[k],
                &format!("options.stage_solver[{k}]"),
            )
        })
        .collect::<FfiResult<Vec<_>>>()?;
    Ok(GroupOptions {
        seed: o.seed,
        cfg_scale: Some(o.cfg_scale),
        prior: Some(prior),
        reaction: Some(solver_from(
            o.reaction_solver,
            o.reaction_steps,
            "options.reaction_solver",
        )?),
        noise: None,
    })
}

/// Copies the caller's noise arrays, split as `shape` says.
///
/// # Safety
/// Each array must be readable for its length.
unsafe fn read_noise(noise: &troupe_group_noise, shape: &GroupNoiseShape) -> FfiResult<GroupNoise> {
    let read = |ptr: *const f32, len: usize, want: usize, what: &str| -> FfiResult<Vec<f32>> {
        if len != want {
            return Err(FfiError::new(
                TROUPE_ERR_SHAPE,
                format!("noise.{what}_len is {len}, expected {want}"),
            ));
        }
        // SAFETY: readable for `len` floats per the contract.
        Ok(unsafe { boundary::slice(ptr, len, &format!("noise.{what}")) }?.to_vec())
    };
    let prior = read(noise.prior, noise.prior_len, shape.prior, "prior")?;
    let jumps = read(
        noise.jumps,
        noise.jumps_len,
        shape.jumps.iter().sum(),
        "jumps",
    )?;
    let reactions = read(
        noise.reactions,
        noise.reactions_len,
        shape.reactions * shape.reaction,
        "reactions",
    )?;
    let mut rest = &jumps[..];
    Ok(GroupNoise {
        prior,
        jumps: shape
            .jumps
            .iter()
            .map(|&n| {
                let (head, tail) = rest.split_at(n);
                rest = tail;
                head.to_vec()
            })
            .collect(),
        // `reaction` is tokens x dim, positive in any loaded bundle; max(1) keeps chunks total.
        reactions: reactions
            .chunks(shape.reaction.max(1))
            .map(<[f32]>::to_vec)
            .collect(),
    })
}
