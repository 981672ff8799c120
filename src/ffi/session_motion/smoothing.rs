//! The root smoothing of any session whose frames carry joints (`family/motion/smoothing.rs`).

use crate::ffi::boundary::troupe_status;
use crate::ffi::session::{troupe_session, with_session};
use crate::RootSmoothing;

/// Turns a session's root smoothing on (`enabled` nonzero) or off, for the frames sent from now
/// on (every streaming family): the generated person's root path on the floor is filtered causally with time constant
/// `time_constant` seconds (in (0, 2]; 0.1 is the demo's), the whole body moving with it, before
/// the penetration guard. No frame is held back; the root lags by about the time constant.
/// `time_constant` is ignored when turning it off.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a value out of range;
/// the session keeps its setting), `TROUPE_ERR_UNSUPPORTED` (a stream whose frames the stage does not know),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_root_smoothing(
    session: *mut troupe_session,
    enabled: i32,
    time_constant: f32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_root_smoothing", |s| {
            let smoothing = (enabled != 0).then_some(RootSmoothing {
                time_constant: f64::from(time_constant),
            });
            Ok(s.set_root_smoothing(smoothing)?)
        })
    }
}
