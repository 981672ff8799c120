//! What only an ARMFlow stream takes when it opens (`troupe_armflow_session_options`), beside
//! the options every stream takes (`troupe_session_options`), and the call that opens an ARMFlow
//! session with both.

use crate::ffi::boundary::{
    self, check_struct_size, non_null, read_versioned, troupe_status, write_versioned, FfiResult,
};
use crate::ffi::model::troupe_model;
use crate::ffi::session::{
    actor_latent_code, actor_latent_of, read_common_options, troupe_session, troupe_session_options,
};
use crate::{Model, ReactorOptions};

/// Options only an ARMFlow stream takes. Fill with `troupe_armflow_session_options_init`, then
/// change fields. Fields are only ever appended; `struct_size` tells the library which version
/// the caller has.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_armflow_session_options {
    /// `sizeof(troupe_armflow_session_options)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// Classifier-free guidance scale, finite; the stream guides only above 1, as the official
    /// sampler does. Changeable later with `troupe_session_set_cfg_scale`.
    pub cfg_scale: f32,
    /// `TROUPE_ACTOR_LATENT_SAMPLE` (the official choice) or `TROUPE_ACTOR_LATENT_MEAN`.
    pub actor_latent: i32,
    /// Nonzero: run the VAE over windows of frames (the reference path) rather than the
    /// bundle's per-token steps; slower, and recentring is then unavailable.
    pub vae_windows: i32,
}

/// `sizeof(troupe_armflow_session_options)` in this library, for bindings to check their mirror.
/// Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_armflow_session_options_size() -> usize {
    std::mem::size_of::<troupe_armflow_session_options>()
}

/// The size of the first published `troupe_armflow_session_options`.
const OPTIONS_V1_SIZE: usize = 16;
// Version 1 has no padding, so copying its bytes copies only initialised fields.
const _: () = assert!(std::mem::size_of::<troupe_armflow_session_options>() == OPTIONS_V1_SIZE);

/// The bundle's defaults for `model`, or `TROUPE_ERR_UNSUPPORTED` for another family's model.
fn defaults(model: &Model, size: usize) -> FfiResult<troupe_armflow_session_options> {
    let sampler = &model.armflow()?.spec().sampler;
    Ok(troupe_armflow_session_options {
        struct_size: size as u32,
        cfg_scale: sampler.cfg_scale,
        actor_latent: actor_latent_code(sampler.actor_latent),
        vae_windows: 0,
    })
}

/// Fills `options` with the defaults of `model`'s bundle (its CFG scale and actor latent, the
/// VAE's per-token steps) and sets `struct_size`. Pass `sizeof(troupe_armflow_session_options)`
/// as `options_size`: the library writes only that many bytes (zeroing fields it does not know).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (an `options_size`
/// smaller than the first version of the struct), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow
/// model). Thread-safe.
///
/// # Safety
/// `model` must be a live handle; `options` must be writable for `options_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_options_init(
    model: Option<&troupe_model>,
    options: *mut troupe_armflow_session_options,
    options_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_armflow_session_options_init",
        || {},
        || {
            let model = &boundary::required(model, "model")?.model;
            non_null(options, "options")?;
            check_struct_size(
                options_size,
                OPTIONS_V1_SIZE,
                "troupe_armflow_session_options",
            )?;
            let defaults = defaults(model, options_size)?;
            // SAFETY: writable for `options_size` bytes per the contract; no padding (asserted).
            unsafe { write_versioned(options, options_size, &defaults) };
            Ok(())
        },
    )
}

/// Starts an ARMFlow stream on `model` (the reactor to an actor, from the null condition) with
/// the options every stream takes (`options`, NULL: the bundle's defaults) and ARMFlow's own
/// (`armflow`, NULL: the bundle's defaults). The deprecated `cfg_scale` and `actor_latent` fields
/// of `options` are not read: `armflow` says them.
///
/// On success `*out` receives a new handle owned by the caller (free with
/// `troupe_session_free`); it keeps `model` alive. On failure `*out` is set to NULL.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (bad option values or
/// `struct_size`), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow model), `TROUPE_ERR_INFERENCE`,
/// `TROUPE_ERR_PANIC`. Thread-safe with respect to `model`.
///
/// ```c
/// troupe_armflow_session_options arm;
/// troupe_armflow_session_options_init(model, &arm, sizeof arm);
/// arm.cfg_scale = 2.0f;
/// troupe_session *session = NULL;
/// troupe_status st = troupe_armflow_session_new(model, NULL, &arm, &session);
/// ```
///
/// # Safety
/// `model` must be a live handle; `options` and `armflow` NULL or readable for their
/// `struct_size`; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_new(
    model: Option<&troupe_model>,
    options: *const troupe_session_options,
    armflow: *const troupe_armflow_session_options,
    out: *mut *mut troupe_session,
) -> troupe_status {
    boundary::call(
        "troupe_armflow_session_new",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL; writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            let model = &boundary::required(model, "model")?.model;
            let family = model.armflow()?;
            let common = if options.is_null() {
                crate::SessionOptions::default()
            } else {
                // SAFETY: readable per the contract.
                unsafe { read_common_options(model, options) }?
            };
            let own = if armflow.is_null() {
                defaults(model, OPTIONS_V1_SIZE)?
            } else {
                // SAFETY: readable for its `struct_size` per the contract.
                unsafe {
                    read_versioned(
                        armflow,
                        OPTIONS_V1_SIZE,
                        || defaults(model, OPTIONS_V1_SIZE),
                        "armflow",
                        "troupe_armflow_session_options_init",
                    )
                }?
            };
            let reactor = family.reactor(ReactorOptions {
                cfg_scale: Some(own.cfg_scale),
                actor_latent: Some(actor_latent_of(own.actor_latent, "armflow.actor_latent")?),
                vae_windows: own.vae_windows != 0,
                ..common.into()
            })?;
            // SAFETY: checked non-NULL above.
            unsafe { *out = troupe_session::into_raw(reactor.into()) };
            Ok(())
        },
    )
}
