//! The recentring of an ARMFlow joint stream (`armflow/session/recentre.rs`).

use crate::ffi::armflow::reactor;
use crate::ffi::boundary::troupe_status;
use crate::ffi::session::{troupe_session, with_session};
use crate::Recentring;

/// Turns an ARMFlow session's recentring on (`enabled` nonzero) or off: before each token, when
/// the actor's root is farther than `distance` metres (in [0.1, 100]; 1 is the demo's) on the
/// floor from where the networks' frame is centred, the centre moves to the actor and the
/// networks' state is rebuilt around it from the last 8 tokens of both people's motion, which
/// the session keeps while recentring is on (67 KB at the demo model's size). What the session
/// returns (frames and poses) stays in the stream's frame; a model trained near the origin then
/// keeps its quality however far the actor walks. The result does not depend on how frames are
/// split into calls. Turning it off keeps the centre where it is; `distance` is then ignored.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a distance out of
/// range; the session keeps its setting), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow session, or
/// one that runs the VAE over windows or whose VAE looks ahead), `TROUPE_ERR_POISONED`,
/// `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_set_recentring(
    session: *mut troupe_session,
    enabled: i32,
    distance: f32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_armflow_session_set_recentring", |s| {
            let recentring = (enabled != 0).then_some(Recentring {
                distance: f64::from(distance),
            });
            Ok(reactor(s, "recentring")?.set_recentring(recentring)?)
        })
    }
}
