//! The names of the C functions before 1.0 gave every family call its family's prefix. Each
//! is the function it forwards to, under its old name, kept exported so that programs built
//! against an older header keep linking; they leave with 2.0 (`docs/ABI.md`). The header marks
//! them deprecated, naming the replacement.
#![allow(deprecated)]

use std::ffi::c_char;

use crate::ffi::arflow::troupe_arflow_options;
use crate::ffi::armflow::clip::troupe_clip_noise;
use crate::ffi::boundary::troupe_status;
use crate::ffi::model::troupe_model;
use crate::ffi::session::troupe_session;
use crate::ffi::umf::group::{troupe_group_noise, troupe_group_options};

/// Deprecated name of `troupe_armflow_clip_tokens`, kept until 2.0.
///
/// # Safety
/// As `troupe_armflow_clip_tokens`.
#[deprecated(note = "use troupe_armflow_clip_tokens")]
#[no_mangle]
pub unsafe extern "C" fn troupe_model_clip_tokens(model: Option<&troupe_model>) -> usize {
    // SAFETY: the contract of `troupe_armflow_clip_tokens`, which the caller upholds.
    unsafe { crate::ffi::armflow::clip::troupe_armflow_clip_tokens(model) }
}

/// Deprecated name of `troupe_armflow_clip_generate`, kept until 2.0.
///
/// # Safety
/// As `troupe_armflow_clip_generate`.
#[deprecated(note = "use troupe_armflow_clip_generate")]
#[no_mangle]
pub unsafe extern "C" fn troupe_clip_generate(
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
    // SAFETY: the contract of `troupe_armflow_clip_generate`, which the caller upholds.
    unsafe {
        crate::ffi::armflow::clip::troupe_armflow_clip_generate(
            model,
            actor,
            n_actor_frames,
            condition,
            condition_len,
            seed,
            steps,
            noise,
            frames,
            frames_capacity,
            reactor_latents,
            latents_capacity,
        )
    }
}

/// Deprecated name of `troupe_session_set_penetration_guard` (0.2: the guard serves every
/// streaming family), kept until 2.0.
///
/// # Safety
/// As `troupe_session_set_penetration_guard`.
#[deprecated(note = "use troupe_session_set_penetration_guard")]
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_set_penetration_guard(
    session: *mut troupe_session,
    enabled: i32,
    d_safe: f32,
    max_speed: f32,
) -> troupe_status {
    // SAFETY: the contract of `troupe_session_set_penetration_guard`, which the caller upholds.
    unsafe {
        crate::ffi::session_motion::guard::troupe_session_set_penetration_guard(
            session, enabled, d_safe, max_speed,
        )
    }
}

/// Deprecated name of `troupe_session_set_root_smoothing` (0.2: the smoothing serves every
/// streaming family), kept until 2.0.
///
/// # Safety
/// As `troupe_session_set_root_smoothing`.
#[deprecated(note = "use troupe_session_set_root_smoothing")]
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_set_root_smoothing(
    session: *mut troupe_session,
    enabled: i32,
    time_constant: f32,
) -> troupe_status {
    // SAFETY: the contract of `troupe_session_set_root_smoothing`, which the caller upholds.
    unsafe {
        crate::ffi::session_motion::smoothing::troupe_session_set_root_smoothing(
            session,
            enabled,
            time_constant,
        )
    }
}

/// Deprecated name of `troupe_session_set_foot_lock` (0.2: the foot lock serves every stream
/// whose frames carry contact labels), kept until 2.0.
///
/// # Safety
/// As `troupe_session_set_foot_lock`.
#[deprecated(note = "use troupe_session_set_foot_lock")]
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_set_foot_lock(
    session: *mut troupe_session,
    enabled: i32,
    contact_threshold: f32,
    release_frames: u32,
    max_stretch: f32,
) -> troupe_status {
    // SAFETY: the contract of `troupe_session_set_foot_lock`, which the caller upholds.
    unsafe {
        crate::ffi::session_motion::foot_lock::troupe_session_set_foot_lock(
            session,
            enabled,
            contact_threshold,
            release_frames,
            max_stretch,
        )
    }
}

/// Deprecated name of `troupe_armflow_session_queue_noise` (0.2: ARMFlow's own calls are named
/// for it), kept until 2.0.
///
/// # Safety
/// As `troupe_armflow_session_queue_noise`.
#[deprecated(note = "use troupe_armflow_session_queue_noise")]
#[no_mangle]
pub unsafe extern "C" fn troupe_session_queue_noise(
    session: *mut troupe_session,
    actor_noise: *const f32,
    reactor_noise: *const f32,
    len: usize,
) -> troupe_status {
    // SAFETY: the contract of `troupe_armflow_session_queue_noise`, which the caller upholds.
    unsafe {
        crate::ffi::armflow::noise::troupe_armflow_session_queue_noise(
            session,
            actor_noise,
            reactor_noise,
            len,
        )
    }
}

/// Deprecated name of `troupe_umf_options_size`, kept until 2.0.
#[deprecated(note = "use troupe_umf_options_size")]
#[no_mangle]
pub extern "C" fn troupe_group_options_size() -> usize {
    crate::ffi::umf::group::troupe_umf_options_size()
}

/// Deprecated name of `troupe_umf_options_init`, kept until 2.0.
///
/// # Safety
/// As `troupe_umf_options_init`.
#[deprecated(note = "use troupe_umf_options_init")]
#[no_mangle]
pub unsafe extern "C" fn troupe_group_options_init(
    model: Option<&troupe_model>,
    options: *mut troupe_group_options,
    options_size: usize,
) -> troupe_status {
    // SAFETY: the contract of `troupe_umf_options_init`, which the caller upholds.
    unsafe { crate::ffi::umf::group::troupe_umf_options_init(model, options, options_size) }
}

/// Deprecated name of `troupe_umf_stages`, kept until 2.0.
///
/// # Safety
/// As `troupe_umf_stages`.
#[deprecated(note = "use troupe_umf_stages")]
#[no_mangle]
pub unsafe extern "C" fn troupe_model_group_stages(model: Option<&troupe_model>) -> usize {
    // SAFETY: the contract of `troupe_umf_stages`, which the caller upholds.
    unsafe { crate::ffi::umf::group::troupe_umf_stages(model) }
}

/// Deprecated name of `troupe_umf_tokens`, kept until 2.0.
///
/// # Safety
/// As `troupe_umf_tokens`.
#[deprecated(note = "use troupe_umf_tokens")]
#[no_mangle]
pub unsafe extern "C" fn troupe_model_group_tokens(model: Option<&troupe_model>) -> usize {
    // SAFETY: the contract of `troupe_umf_tokens`, which the caller upholds.
    unsafe { crate::ffi::umf::group::troupe_umf_tokens(model) }
}

/// Deprecated name of `troupe_umf_noise_lengths`, kept until 2.0.
///
/// # Safety
/// As `troupe_umf_noise_lengths`.
#[deprecated(note = "use troupe_umf_noise_lengths")]
#[no_mangle]
pub unsafe extern "C" fn troupe_group_noise_lengths(
    model: Option<&troupe_model>,
    people: u32,
    prior_len: *mut usize,
    jumps_len: *mut usize,
    reactions_len: *mut usize,
) -> troupe_status {
    // SAFETY: the contract of `troupe_umf_noise_lengths`, which the caller upholds.
    unsafe {
        crate::ffi::umf::group::troupe_umf_noise_lengths(
            model,
            people,
            prior_len,
            jumps_len,
            reactions_len,
        )
    }
}

/// Deprecated name of `troupe_umf_generate`, kept until 2.0.
///
/// # Safety
/// As `troupe_umf_generate`.
#[deprecated(note = "use troupe_umf_generate")]
#[no_mangle]
pub unsafe extern "C" fn troupe_group_generate(
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
    // SAFETY: the contract of `troupe_umf_generate`, which the caller upholds.
    unsafe {
        crate::ffi::umf::group::troupe_umf_generate(
            model,
            options,
            condition,
            condition_len,
            people,
            noise,
            motion,
            motion_capacity,
            latents,
            latents_capacity,
        )
    }
}

/// Deprecated name of `troupe_magnet_people`, kept until 2.0.
///
/// # Safety
/// As `troupe_magnet_people`.
#[deprecated(note = "use troupe_magnet_people")]
#[no_mangle]
pub unsafe extern "C" fn troupe_model_magnet_people(model: Option<&troupe_model>) -> usize {
    // SAFETY: the contract of `troupe_magnet_people`, which the caller upholds.
    unsafe { crate::ffi::magnet::troupe_magnet_people(model) }
}

/// Deprecated name of `troupe_magnet_config_count`, kept until 2.0.
///
/// # Safety
/// As `troupe_magnet_config_count`.
#[deprecated(note = "use troupe_magnet_config_count")]
#[no_mangle]
pub unsafe extern "C" fn troupe_model_magnet_config_count(model: Option<&troupe_model>) -> usize {
    // SAFETY: the contract of `troupe_magnet_config_count`, which the caller upholds.
    unsafe { crate::ffi::magnet::troupe_magnet_config_count(model) }
}

/// Deprecated name of `troupe_magnet_config`, kept until 2.0.
///
/// # Safety
/// As `troupe_magnet_config`.
#[deprecated(note = "use troupe_magnet_config")]
#[no_mangle]
pub unsafe extern "C" fn troupe_model_magnet_config(
    model: Option<&troupe_model>,
    index: usize,
) -> *const c_char {
    // SAFETY: the contract of `troupe_magnet_config`, which the caller upholds.
    unsafe { crate::ffi::magnet::troupe_magnet_config(model, index) }
}

/// Deprecated name of `troupe_magnet_session_set_partner_opening`, kept until 2.0.
///
/// # Safety
/// As `troupe_magnet_session_set_partner_opening`.
#[deprecated(note = "use troupe_magnet_session_set_partner_opening")]
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_partner_opening(
    session: *mut troupe_session,
    frames: *const f32,
    n_frames: usize,
) -> troupe_status {
    // SAFETY: the contract of `troupe_magnet_session_set_partner_opening`, which the caller upholds.
    unsafe {
        crate::ffi::magnet::session::troupe_magnet_session_set_partner_opening(
            session, frames, n_frames,
        )
    }
}

/// Deprecated name of `troupe_magnet_session_set_early_emission`, kept until 2.0.
///
/// # Safety
/// As `troupe_magnet_session_set_early_emission`.
#[deprecated(note = "use troupe_magnet_session_set_early_emission")]
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_early_emission(
    session: *mut troupe_session,
    early: i32,
) -> troupe_status {
    // SAFETY: the contract of `troupe_magnet_session_set_early_emission`, which the caller upholds.
    unsafe { crate::ffi::magnet::session::troupe_magnet_session_set_early_emission(session, early) }
}

/// Deprecated name of `troupe_magnet_session_set_live_config`, kept until 2.0.
///
/// # Safety
/// As `troupe_magnet_session_set_live_config`.
#[deprecated(note = "use troupe_magnet_session_set_live_config")]
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_live_config(
    session: *mut troupe_session,
    config: *const c_char,
) -> troupe_status {
    // SAFETY: the contract of `troupe_magnet_session_set_live_config`, which the caller upholds.
    unsafe { crate::ffi::magnet::session::troupe_magnet_session_set_live_config(session, config) }
}

/// Deprecated name of `troupe_arflow_session_set_options`, kept until 2.0.
///
/// # Safety
/// As `troupe_arflow_session_set_options`.
#[deprecated(note = "use troupe_arflow_session_set_options")]
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_arflow_options(
    session: *mut troupe_session,
    options: *const troupe_arflow_options,
) -> troupe_status {
    // SAFETY: the contract of `troupe_arflow_session_set_options`, which the caller upholds.
    unsafe { crate::ffi::arflow::troupe_arflow_session_set_options(session, options) }
}

/// Deprecated name of `troupe_motion_penetration_metrics`, kept until 2.0.
///
/// # Safety
/// As `troupe_motion_penetration_metrics`.
#[deprecated(note = "use troupe_motion_penetration_metrics")]
#[no_mangle]
pub unsafe extern "C" fn troupe_penetration_metrics(
    first: *const f32,
    second: *const f32,
    n_frames: usize,
    frames_intersecting: *mut usize,
    frequency: *mut f64,
    depth_sum: *mut f64,
    max_depth: *mut f64,
) -> troupe_status {
    // SAFETY: the contract of `troupe_motion_penetration_metrics`, which the caller upholds.
    unsafe {
        crate::ffi::motion::troupe_motion_penetration_metrics(
            first,
            second,
            n_frames,
            frames_intersecting,
            frequency,
            depth_sum,
            max_depth,
        )
    }
}
