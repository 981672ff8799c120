//! What only a MAGNet live partner stream takes: the partner's opening frames, the sampling
//! configuration, and when frames are sent.

use std::ffi::c_char;

use crate::ffi::boundary::{self, checked_mul, troupe_status, FfiResult};
use crate::ffi::session::{family_stream, troupe_session, with_session};
use crate::{LivePartner, Session};

/// The live partner behind a session, for what only it takes.
fn partner<'a>(session: &'a mut Session, what: &str) -> FfiResult<&'a mut LivePartner> {
    family_stream(session, "magnet", what)
}

/// Sets the partner's opening frames of a MAGNet live partner session: `n_frames` frames
/// (the configuration's context, `4 * context_capacity`) of `troupe_model_frame_dim` floats,
/// row-major, borrowed for the call; kept across resets. A stream needs them before the user's
/// first frame. Only before the first step or after `troupe_session_reset`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (the wrong number of
/// frames, a NaN or infinite value, a stream already started), `TROUPE_ERR_UNSUPPORTED` (not a
/// MAGNet session), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// ```c
/// troupe_magnet_session_set_partner_opening(session, partner_frames, 32);
/// ```
///
/// # Safety
/// `session` must be a live handle; `frames` readable for `n_frames * 145` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_session_set_partner_opening(
    session: *mut troupe_session,
    frames: *const f32,
    n_frames: usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_magnet_session_set_partner_opening", |s| {
            let n = checked_mul(n_frames, s.frame_dim(), "n_frames * frame_dim")?;
            let frames = boundary::slice(frames, n, "frames")?;
            Ok(partner(s, "the partner's opening frames")?.set_partner_opening(frames)?)
        })
    }
}

/// Makes a MAGNet live partner session send each chunk's frames as soon as they are generated
/// (`early` nonzero: `4 * (window - context)` frames less latency; the next chunk's smoothing no
/// longer reaches them) or once final (0, the default). Only before the first step or after
/// `troupe_session_reset`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a stream already
/// started), `TROUPE_ERR_UNSUPPORTED` (not a MAGNet session), `TROUPE_ERR_POISONED`,
/// `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_session_set_early_emission(
    session: *mut troupe_session,
    early: i32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_magnet_session_set_early_emission", |s| {
            Ok(partner(s, "early emission")?.set_early_emission(early != 0)?)
        })
    }
}

/// Makes a MAGNet live partner session run the sampling configuration `config` (a
/// NUL-terminated name from `troupe_magnet_config`, or a whole configuration as JSON;
/// borrowed for the call), for instance one with the x0 guidance off. Only before the first
/// step or after `troupe_session_reset`; set opening frames after it when its context differs.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not a MAGNet session),
/// `TROUPE_ERR_INVALID_ARG` (an unknown name, bad JSON, a configuration that is not `motion_control_live`, a stream already
/// started), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; `config` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn troupe_magnet_session_set_live_config(
    session: *mut troupe_session,
    config: *const c_char,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_magnet_session_set_live_config", |s| {
            let config = boundary::required_str(config, "config")?;
            Ok(partner(s, "a live configuration")?.set_live_config(config)?)
        })
    }
}
