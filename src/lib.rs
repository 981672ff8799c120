//! # troupe
//!
//! An embeddable runtime for real-time generators of multi-person motion. troupe loads a model
//! *bundle* (a `troupe.json` manifest plus ONNX graphs, see `onnx/README.md`) and runs the
//! sampling loop in Rust on tract.
//!
//! One shape for every family: a [`Model`] answers what every bundle answers and opens streams
//! ([`Model::session`]); everything else is the family's own type, [`Model::armflow`],
//! [`Model::umf`], [`Model::magnet`] and [`Model::arflow`]. A [`Session`] is one stream of any
//! family that streams (ARMFlow's reactor, MAGNet's live partner, ARFlow's online variant): the
//! other person's frames come back as the input's arrive.
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
//! `Send` and used from one thread at a time. Loading a model optimises its graphs on up to one
//! scoped thread per core ([`set_load_threads`] bounds them), all joined before it returns; no
//! other call starts a thread unless [`set_compute_threads`] opts in to a pool that the matrix
//! products split over.
//!
//! Limits: every size that comes from a file or a caller is checked against [`LIMITS`] before
//! anything is allocated for it.
//!
//! Layout (see `docs/ARCHITECTURE.md`): `shared` machinery at the bottom (what a family and a
//! stream are, bundle files, graphs, noise, solvers, errors), [`motion`] and [`viewer`] above
//! it, one folder per model family above those ([`armflow`], [`umf`], [`magnet`], [`arflow`]),
//! each importing only from `shared`, `motion` and itself, then [`Model`] and [`manifest`],
//! which know every family by name, and the C ABI (`ffi`) on top.

#![warn(missing_docs)]

/// The Rust samples of the README and the docs, run as doc tests (`build.rs` gathers them).
#[cfg(doctest)]
#[doc = include_str!(concat!(env!("OUT_DIR"), "/doc_samples.md"))]
pub struct DocSamples;

pub mod arflow;
pub mod armflow;
mod family;
// The C API (`include/troupe.h`). Its items are public only so that the fuzz targets and tests
// can call the C entry points in-process; Rust programs use the API above, which has the
// stability promise (`docs/ABI.md` is the C API's).
#[doc(hidden)]
pub mod ffi;
pub mod magnet;
pub mod manifest;
mod model;
pub mod motion;
pub(crate) mod shared;
pub mod umf;
pub mod viewer;

// `clip`, `noise`, `solver` and `pyramid` keep the public paths they had before the family
// folders (`troupe::noise::fill_normals`, ...).
pub use arflow::{Arflow, ArflowOptions};
pub use armflow::clip;
pub use armflow::{
    meanflow_grid, Armflow, Clip, ClipNoise, ClipOptions, Reactor, ReactorOptions, Recentring,
    TokenNoise, HISTORY_TOKENS,
};
pub use family::motion::{PenetrationGuard, RootSmoothing};
pub use family::session::{step_sessions, step_sessions_joints, Session};
pub use family::stream::{Capabilities, Capability, StepOutput, TokenTrace};
pub use family::{SessionOptions, StreamOptions};
pub use magnet::{LivePartner, Magnet, MagnetOptions, MagnetOutput, PartnerOptions};
pub use manifest::{ActorLatent, ConditionLabel, Manifest, Weights};
pub use model::Model;
pub use motion::FootLockOptions;
pub use shared::attention::kernel as attention_kernel;
pub use shared::error::{Error, Result};
#[doc(hidden)]
pub use shared::graph::{evaluate_operation, load_graph_for_fuzzing, optimised_plan, PlanRunner};
pub use shared::isa::kernels;
pub use shared::limits::{Limits, LIMITS};
pub use shared::noise;
pub use shared::progress::{with_call_budget, with_progress, CallBudget};
pub use shared::sealed::seal as seal_snapshot;
pub use shared::solver::{self, Method, Solver};
pub use shared::text::tokenizer::ClipTokenizer;
pub use shared::threads::{compute_threads, load_threads, set_compute_threads, set_load_threads};
pub use umf::pyramid;
pub use umf::{
    Group, GroupNoise, GroupNoiseShape, GroupOptions, Umf, MAX_PEOPLE, STREAM_JUMP_NOISE,
    STREAM_PRIOR_NOISE, STREAM_REACTION_NOISE,
};
