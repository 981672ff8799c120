//! The C entry points of the `armflow` family: its session options, recentring, noise queued
//! per token and the official clip loop. Sessions and their motion stages are family-neutral
//! (`ffi/session.rs`, `ffi/session_motion/`).

pub mod clip;
pub mod noise;
pub mod options;
pub mod recentring;

#[cfg(test)]
mod rollback_tests;

use crate::ffi::boundary::FfiResult;
use crate::ffi::session::family_stream;
use crate::{Reactor, Session};

/// The ARMFlow reactor behind a session, for what only it takes (`TROUPE_ERR_UNSUPPORTED`
/// naming `what` on another family's session).
pub(crate) fn reactor<'a>(session: &'a mut Session, what: &str) -> FfiResult<&'a mut Reactor> {
    family_stream(session, "armflow", what)
}
