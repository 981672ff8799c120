//! The penetration guard of any session whose frames carry joints (`family/motion/guard.rs`).

use crate::ffi::boundary::troupe_status;
use crate::ffi::session::{troupe_session, with_session};

/// Turns a session's penetration guard on (`enabled` nonzero) or off, for the frames sent from
/// now on (every streaming family: ARMFlow, ARFlow, MAGNet): each sent frame is shifted in the
/// floor plane out of the input person's body (joints nearer than `d_safe` metres, in [0, 0.5]), never faster than `max_speed` metres
/// per second (in (0, 10]); `docs/ARFLOW.md` states the rule and what it measured. The defaults
/// are 0.05 m and 2 m/s. `d_safe` and `max_speed` are ignored when turning it off.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a value out of range),
/// `TROUPE_ERR_UNSUPPORTED` (a stream whose frames the stage does not know), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`.
/// One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_penetration_guard(
    session: *mut troupe_session,
    enabled: i32,
    d_safe: f32,
    max_speed: f32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_penetration_guard", |s| {
            let guard = (enabled != 0).then_some(crate::PenetrationGuard {
                d_safe: d_safe as f64,
                max_speed: max_speed as f64,
            });
            Ok(s.set_penetration_guard(guard)?)
        })
    }
}
