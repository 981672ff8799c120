//! The `armflow` family: online reaction (`docs/spec/armflow.md`). An actor's frames stream in
//! and a [`Reactor`] answers with the reactor's, one latent token per step: VAE encoder → causal
//! context encoder with a key/value cache → MeanFlow velocity → VAE decoder. The official clip
//! loop runs the same networks over a whole clip.
//!
//! - `family`: [`Armflow`], the loaded model (`Model::armflow`): its reactors and clips;
//! - [`spec`]: the family's manifest section and the interface it requires of its graphs;
//! - `networks`: the loaded graphs and their typed calls;
//! - `context`: the context encoder, its dense layers in graphs and its attention in Rust;
//! - `kv_cache`: the paged key/value cache it attends over, and its capacity policy;
//! - `meanflow`: the sampler's time grid;
//! - `session`: [`Reactor`] streams, one or many at once (`session/lanes.rs`, the batched token
//!   loop);
//! - [`clip`]: the official clip loop, [`Armflow::generate_clip`].
//!
//! Like every family, this folder imports only from `crate::shared`, `crate::motion` and itself.

pub mod clip;
mod context;
mod family;
mod kv_cache;
mod meanflow;
pub(crate) mod networks;
mod session;
pub mod spec;

pub use clip::{Clip, ClipNoise, ClipOptions};
pub use family::Armflow;
pub use meanflow::meanflow_grid;
// The guard and the smoothing are every session's now (`Session::set_penetration_guard`); their
// types keep the paths they had here.
pub use crate::family::motion::{PenetrationGuard, RootSmoothing};
pub use session::{Reactor, ReactorOptions, Recentring, TokenNoise, HISTORY_TOKENS};
