//! The C entry points of the `armflow` family: joint positions in and out of a session, and
//! the official clip loop with its text branch. Sessions themselves are family-neutral
//! (`ffi/session.rs`).

pub mod clip;
pub mod joints;

#[cfg(test)]
mod rollback_tests;
