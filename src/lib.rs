//! # troupe
//!
//! An embeddable runtime for real-time generators of multi-person motion. troupe loads a model
//! *bundle* (a `troupe.json` manifest plus ONNX graphs, see `onnx/README.md`) and runs the
//! sampling loop in Rust on tract.
//!
//! The online reaction model (ARMFlow): an actor's motion streams in frame by frame, and a
//! [`Session`] answers with the reactor's motion, one latent token (4 frames) at a time.
//!
//! ```no_run
//! use ndarray::Array2;
//! use troupe::{Model, SessionOptions};
//!
//! let model = Model::load("onnx/bundles/armflow-tiny")?;    // load and optimise once
//! let mut session = model.session(SessionOptions { seed: 7, ..Default::default() })?;
//! let actor = Array2::<f32>::zeros((1, model.frame_dim())); // one frame from the engine
//! let reactor = session.step(actor.view())?;                // 0 or 4 frames back
//! # Ok::<(), troupe::Error>(())
//! ```
//!
//! Threading: [`Model`] is `Send + Sync` and shared by any number of sessions; a [`Session`] is
//! `Send` and used from one thread at a time.

#![warn(missing_docs)]

mod bundle;
pub mod clip;
mod error;
pub mod ffi;
mod graph;
mod group;
mod kv_cache;
mod logging;
pub mod manifest;
mod model;
pub mod noise;
pub mod pyramid;
mod session;
pub mod solver;

pub use clip::{Clip, ClipNoise, ClipOptions};
pub use error::{Error, Result};
pub use group::{
    Group, GroupNoise, GroupNoiseShape, GroupOptions, MAX_PEOPLE, STREAM_JUMP_NOISE,
    STREAM_PRIOR_NOISE, STREAM_REACTION_NOISE,
};
pub use manifest::{ActorLatent, Manifest};
pub use model::Model;
pub use session::{
    meanflow_grid, step_sessions, Session, SessionOptions, StepOutput, TokenNoise, TokenTrace,
};
pub use solver::{Method, Solver};
