//! The C entry points of the `armflow` family: joint positions in and out of a session, the
//! penetration guard, the root smoothing, the foot lock, recentring, and the official clip loop. Sessions
//! themselves are family-neutral (`ffi/session.rs`).

pub mod clip;
pub mod foot_lock;
pub mod guard;
pub mod joints;
pub mod recentring;
pub mod smoothing;

#[cfg(test)]
mod rollback_tests;
