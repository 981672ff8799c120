//! The C entry points of the `armflow` family: streaming sessions (one or many per call) and
//! the official clip loop with its text branch.

pub mod clip;
pub mod joints;
pub mod session;

#[cfg(test)]
mod rollback_tests;
