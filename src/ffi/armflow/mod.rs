//! The C entry points of the `armflow` family: its session options, recentring, noise queued
//! per token and the official clip loop. Sessions and their motion stages are family-neutral
//! (`ffi/session.rs`, `ffi/session_motion/`).

pub mod clip;
pub mod noise;
pub mod options;
pub mod recentring;

#[cfg(test)]
mod rollback_tests;
