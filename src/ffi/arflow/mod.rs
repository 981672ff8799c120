//! The C entry points of the `arflow` family: offline generation with penetration guidance.

use crate::arflow::spec::{ArflowSampling, Mixing};
use crate::arflow::{Arflow, OnlineStream};
use crate::ffi::boundary::{
    self, check_struct_size, checked_mul, non_null, read_versioned, room, troupe_status,
    write_versioned, FfiError, FfiResult, TROUPE_ERR_INVALID_ARG,
};
use crate::ffi::model::troupe_model;
use crate::ffi::session::{family_stream, troupe_session, with_session};
use crate::{ArflowOptions, Model};

/// `troupe_arflow_options.flags`: a squared hinge in the penetration loss (else linear).
pub const TROUPE_ARFLOW_SQUARED_HINGE: u32 = 1;
/// `troupe_arflow_options.flags`: back-project with the network's x̂_1, not the guided one.
pub const TROUPE_ARFLOW_UNGUIDED_BACKPROJECTION: u32 = 2;
/// `troupe_arflow_options.flags`: mix the stochastic direction as `√(1 − η²) v + η ε` (else
/// `(1 − η) v + η ε`).
pub const TROUPE_ARFLOW_VARIANCE_PRESERVING: u32 = 4;

const KNOWN_FLAGS: u32 = TROUPE_ARFLOW_SQUARED_HINGE
    | TROUPE_ARFLOW_UNGUIDED_BACKPROJECTION
    | TROUPE_ARFLOW_VARIANCE_PRESERVING;

/// ARFlow's sampler settings for one `troupe_arflow_generate` call. Fill with
/// `troupe_arflow_options_init` (the bundle's defaults), then change fields. Fields are only
/// ever appended; `struct_size` tells the library which version the caller has.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_arflow_options {
    /// `sizeof(troupe_arflow_options)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// Euler steps M, >= 1.
    pub steps: u32,
    /// The guidance strength λ, >= 0 (0: no guidance).
    pub guidance: f32,
    /// The reweighting toward the actor w, in [0, 1] (1: none).
    pub weight: f32,
    /// The stochastic share η, in [0, 1) (0: deterministic).
    pub eta: f32,
    /// The penetration loss's safe distance, metres, in [0, 1].
    pub d_safe: f32,
    /// The start noise σ (0: the flow starts at the actor exactly).
    pub sigma: f32,
    /// `TROUPE_ARFLOW_*` flags.
    pub flags: u32,
    /// Seed of troupe's generator (used when η > 0 or σ > 0).
    pub seed: u64,
}

const OPTIONS_V1_SIZE: usize = 40;
const _: () = assert!(std::mem::size_of::<troupe_arflow_options>() == OPTIONS_V1_SIZE);

/// `sizeof(troupe_arflow_options)` in this library, for bindings to check their mirror.
#[no_mangle]
pub extern "C" fn troupe_arflow_options_size() -> usize {
    std::mem::size_of::<troupe_arflow_options>()
}

/// The model behind a handle and its ARFlow API, or an error for NULL or another family.
fn arflow_model(model: Option<&troupe_model>) -> FfiResult<(&Model, &Arflow)> {
    let model = &boundary::required(model, "model")?.model;
    let arflow = model
        .arflow()
        .map_err(|_| model.wrong_family("arflow", "ARFlow generation"))?;
    Ok((model, arflow))
}

/// The options `troupe_arflow_options_init` writes: the bundle's sampler settings, seed 0.
fn option_defaults(s: &ArflowSampling, size: usize) -> troupe_arflow_options {
    let flag = |on: bool, f: u32| if on { f } else { 0 };
    troupe_arflow_options {
        struct_size: size as u32,
        steps: s.steps as u32,
        guidance: s.guidance,
        weight: s.weight,
        eta: s.eta,
        d_safe: s.d_safe,
        sigma: s.sigma,
        flags: flag(s.squared, TROUPE_ARFLOW_SQUARED_HINGE)
            | flag(
                !s.guided_backprojection,
                TROUPE_ARFLOW_UNGUIDED_BACKPROJECTION,
            )
            | flag(
                s.mixing == Mixing::VariancePreserving,
                TROUPE_ARFLOW_VARIANCE_PRESERVING,
            ),
        seed: 0,
    }
}

/// Fills `options` with `model`'s sampler defaults (`docs/ARFLOW.md`: 5 steps, λ 2, w 0.7,
/// η 0, d_safe 0.02 m, linear hinge, guided back-projection, σ 0) and seed 0, and sets
/// `struct_size`. Pass `sizeof(troupe_arflow_options)` as `options_size`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`options_size` smaller
/// than the first version), `TROUPE_ERR_UNSUPPORTED` (not an `arflow` bundle). Thread-safe.
///
/// # Safety
/// `model` must be a live handle; `options` writable for `options_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_arflow_options_init(
    model: Option<&troupe_model>,
    options: *mut troupe_arflow_options,
    options_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_arflow_options_init",
        || {},
        || {
            let (_, arflow) = arflow_model(model)?;
            non_null(options, "options")?;
            check_struct_size(options_size, OPTIONS_V1_SIZE, "troupe_arflow_options")?;
            let sampler = &arflow.spec().sampler;
            let defaults = option_defaults(sampler, options_size);
            // SAFETY: writable for `options_size` bytes; no padding (asserted).
            unsafe { write_versioned(options, options_size, &defaults) };
            Ok(())
        },
    )
}

/// Reads the caller's options.
///
/// # Safety
/// `options` must be readable for its `struct_size` bytes.
unsafe fn read_options(
    bundle: &ArflowSampling,
    options: *const troupe_arflow_options,
) -> FfiResult<ArflowOptions> {
    // SAFETY: per the contract.
    let o = unsafe {
        read_versioned(
            options,
            OPTIONS_V1_SIZE,
            || Ok(option_defaults(bundle, OPTIONS_V1_SIZE)),
            "troupe_arflow_options",
            "troupe_arflow_options_init",
        )
    }?;
    if o.flags & !KNOWN_FLAGS != 0 {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!(
                "troupe_arflow_options: unknown flags {:#x}",
                o.flags & !KNOWN_FLAGS
            ),
        ));
    }
    Ok(ArflowOptions {
        steps: Some(o.steps as usize),
        guidance: Some(o.guidance),
        weight: Some(o.weight),
        eta: Some(o.eta),
        d_safe: Some(o.d_safe),
        squared: Some(o.flags & TROUPE_ARFLOW_SQUARED_HINGE != 0),
        guided_backprojection: Some(o.flags & TROUPE_ARFLOW_UNGUIDED_BACKPROJECTION == 0),
        mixing: Some(if o.flags & TROUPE_ARFLOW_VARIANCE_PRESERVING != 0 {
            Mixing::VariancePreserving
        } else {
            Mixing::Linear
        }),
        sigma: Some(o.sigma),
        seed: o.seed,
    })
}

/// ARFlow's generation: the reactor's frames for the actor's. `actor` holds `n_frames`
/// `interhuman262` frames (row-major float32 `[n_frames][262]`, one world frame for both people,
/// borrowed for the call); the reactor's `n_frames` frames go into `out` (capacity
/// `out_capacity_frames` frames). `options` NULL runs the bundle's defaults with seed 0. With an
/// online bundle (a causal network) frame `n` of the result depends only on the actor's frames up
/// to `n`. Nothing is written unless it succeeds.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not an `arflow`
/// bundle), `TROUPE_ERR_INVALID_ARG` (settings out of range, a NaN or infinite value, 0 frames or more than the bundle's
/// `model.max_frames`), `TROUPE_ERR_BUFFER_TOO_SMALL`, `TROUPE_ERR_CANCELLED`,
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may generate on
/// one model at once. Reports progress (steps done) to the calling thread's progress callback.
///
/// ```c
/// troupe_arflow_options opt;
/// troupe_arflow_options_init(model, &opt, sizeof opt);
/// opt.guidance = 0.0f;
/// troupe_status st = troupe_arflow_generate(model, &opt, actor, n, reactor, n);
/// ```
///
/// # Safety
/// `model` must be a live handle; `options` NULL or readable for its `struct_size`; `actor`
/// readable for `n_frames * 262` floats; `out` writable for `out_capacity_frames * 262` floats
/// and not overlapping `actor`.
#[no_mangle]
pub unsafe extern "C" fn troupe_arflow_generate(
    model: Option<&troupe_model>,
    options: *const troupe_arflow_options,
    actor: *const f32,
    n_frames: usize,
    out: *mut f32,
    out_capacity_frames: usize,
) -> troupe_status {
    boundary::call(
        "troupe_arflow_generate",
        || {},
        || {
            // SAFETY: per the contract, which `generate` shares.
            unsafe {
                generate(
                    model,
                    options,
                    (actor, n_frames),
                    None,
                    (out, out_capacity_frames),
                )
            }
            .map(|_| ())
        },
    )
}

/// `troupe_arflow_generate` with the run's standard normals given instead of drawn from the
/// seed: `draws` holds `draws_len` normals (borrowed for the call), and each draw (the start
/// noise when σ > 0, then one ε per step when η > 0, each `n_frames * 262` normals) takes the
/// next ones, as another implementation's recorded draws are replayed. `*draws_used` (when
/// not NULL) receives how many it took; a run that needs more than given fails with
/// `TROUPE_ERR_INVALID_ARG`, naming the draw. Nothing is written unless the call succeeds.
///
/// Returns what `troupe_arflow_generate` returns. Thread-safe: any number of threads may
/// generate on one model at once.
///
/// # Safety
/// As `troupe_arflow_generate`; `draws` readable for `draws_len` floats; `draws_used` NULL or
/// writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_arflow_generate_with_draws(
    model: Option<&troupe_model>,
    options: *const troupe_arflow_options,
    actor: *const f32,
    n_frames: usize,
    draws: *const f32,
    draws_len: usize,
    draws_used: *mut usize,
    out: *mut f32,
    out_capacity_frames: usize,
) -> troupe_status {
    boundary::call(
        "troupe_arflow_generate_with_draws",
        || {},
        || {
            // SAFETY: readable for `draws_len` floats per the contract.
            let normals = unsafe { boundary::slice(draws, draws_len, "draws") }?;
            // SAFETY: per the contract, which `generate` shares.
            let used = unsafe {
                generate(
                    model,
                    options,
                    (actor, n_frames),
                    Some(normals),
                    (out, out_capacity_frames),
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
/// As `troupe_arflow_generate`'s contract states for the same arguments.
unsafe fn generate(
    model: Option<&troupe_model>,
    options: *const troupe_arflow_options,
    (actor, n_frames): (*const f32, usize),
    normals: Option<&[f32]>,
    (out, out_capacity_frames): (*mut f32, usize),
) -> FfiResult<usize> {
    let (model, arflow) = arflow_model(model)?;
    let opts = if options.is_null() {
        ArflowOptions::default()
    } else {
        let sampler = &arflow.spec().sampler;
        // SAFETY: per the contract.
        unsafe { read_options(sampler, options) }?
    };
    let dim = model.frame_dim();
    let len = checked_mul(n_frames, dim, "n_frames * 262")?;
    non_null(actor, "actor")?;
    non_null(out, "out")?;
    room(n_frames, out_capacity_frames, "out (frames)")?;
    // SAFETY: readable for `n_frames * 262` floats per the contract.
    let input = unsafe { std::slice::from_raw_parts(actor, len) };
    let input = ndarray::ArrayView2::from_shape((n_frames, dim), input).expect("sized above");
    let (reactor, used) = match normals {
        Some(normals) => arflow.generate_with_normals(input, &opts, normals)?,
        None => (arflow.generate(input, &opts)?, 0),
    };
    let values = reactor.as_slice().expect("standard layout");
    // SAFETY: `out` is writable for at least `n_frames * 262` floats (checked room).
    unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), out, values.len()) };
    Ok(used)
}

/// Sets an ARFlow stream's sampler settings (`options`, filled by `troupe_arflow_options_init`;
/// its seed too); a new step count only before the first frame or after `troupe_session_reset`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (settings out of range,
/// unknown flags), `TROUPE_ERR_UNSUPPORTED` (not an ARFlow stream), `TROUPE_ERR_POISONED`,
/// `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; `options` readable for its `struct_size`.
#[no_mangle]
pub unsafe extern "C" fn troupe_arflow_session_set_options(
    session: *mut troupe_session,
    options: *const troupe_arflow_options,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_arflow_session_set_options", |s| {
            non_null(options, "options")?;
            let stream = family_stream::<OnlineStream>(s, "arflow", "ARFlow's settings")?;
            let bundle = stream.bundle_sampling().clone();
            // SAFETY: readable for its `struct_size` per the contract.
            let options = read_options(&bundle, options)?;
            Ok(stream.set_options(&options)?)
        })
    }
}
