//! The foot lock of a session's poses (`crate::motion::foot_lock`).

use crate::ffi::boundary::troupe_status;
use crate::ffi::session::{troupe_session, with_session};
use crate::motion::FootLockOptions;

/// Turns a session's foot lock on (`enabled` nonzero) or off (`interhuman262` streams: ARMFlow,
/// ARFlow; MAGNet's frames carry no contact labels), from the next pose
/// `troupe_session_step_joints` returns: while a foot's ankle contact label is at least
/// `contact_threshold` (in (0, 1]) the ankle stays where the contact began, the leg bent by
/// two-bone IK; when the label drops, or the motion's ankle is farther than `max_stretch` metres
/// (in (0, 1]) from where it is held, it returns to the motion over `release_frames` frames (1
/// to 60). No frame is held back. The defaults are 0.5, 4 frames and 0.25 m; the other values
/// are ignored when turning it off. Turning it on starts with no foot held. Feature frames
/// (`troupe_session_step`) are not changed.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a value out of range;
/// the session keeps its foot lock), `TROUPE_ERR_UNSUPPORTED` (a stream whose frames the stage does not know),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_foot_lock(
    session: *mut troupe_session,
    enabled: i32,
    contact_threshold: f32,
    release_frames: u32,
    max_stretch: f32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_foot_lock", |s| {
            let options = (enabled != 0).then_some(FootLockOptions {
                contact_threshold,
                release_frames,
                max_stretch: f64::from(max_stretch),
            });
            Ok(s.set_foot_lock(options)?)
        })
    }
}
