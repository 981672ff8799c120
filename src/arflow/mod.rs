//! The `arflow` family: action-to-reaction flow matching with physical guidance (ARFlow;
//! `docs/spec/arflow.md`). The flow starts at the actor's motion (`x_0 = a`), the network
//! predicts the reactor's (`x̂_1`), and each Euler step is corrected by the penetration loss's
//! gradient (`crate::motion::penetration`), a reprojection toward the actor and optional
//! randomness.
//!
//! - `family`: [`Arflow`], the loaded model (`Model::arflow`): whole clips and online streams;
//! - [`spec`]: the family's manifest section and the interface it requires of its graph;
//! - `networks`: the loaded graph;
//! - [`sampler`]: the guided sampler, [`Arflow::generate`];
//! - `stream`: the online variant frame by frame, [`OnlineStream`].
//!
//! Like every family, this folder imports only from `crate::shared`, `crate::motion` and itself.
//! The Python reference it is tested against is `onnx/troupe_onnx/arflow/`.

mod family;
pub(crate) mod networks;
pub mod sampler;
pub mod spec;
mod stream;

pub use family::Arflow;
pub use sampler::ArflowOptions;
pub use spec::STREAM_ARFLOW;
pub use stream::OnlineStream;
