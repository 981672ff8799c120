//! The `magnet` family: multi-agent diffusion forcing (MAGNet; `docs/spec/magnet.md`). One
//! denoiser over windows of tokens (4 frames of one person each), DDIM with a noise level per
//! token, scheduled by matrices: joint generation of a group, partner prediction and inpainting,
//! in-betweening, turn-taking, synchronous agents and a live partner, all from one network.
//!
//! - `family`: [`Magnet`], the loaded model (`Model::magnet`): the tasks and live partners;
//! - [`spec`]: the family's manifest section and the interface it requires of its graphs;
//! - [`layout`]: the token layout and troupe's frame layout for MAGNet;
//! - `networks`: the loaded graphs and the codebook;
//! - [`schedule`]: the noise schedule, level tables and the DDIM step;
//! - `matrices`: the scheduling matrices;
//! - `guidance`: the mask modes and the x0 corrections;
//! - `tasks`: every sampling entry point;
//! - `transforms`, `motion`: rigid transforms, frames <-> tokens, roots in the world;
//! - [`draws`]: troupe's generator or the caller's draws;
//! - `live`: the live partner as a stream, [`LivePartner`];
//! - `generate`: configurations and the sampler's entry, [`Magnet::generate`].
//!
//! Like every family, this folder imports only from `crate::shared`, `crate::motion` and itself.
//! The Python reference it is tested against is `onnx/troupe_onnx/magnet/`.

pub mod draws;
mod family;
mod generate;
mod guidance;
pub mod layout;
pub(crate) mod live;
mod matrices;
mod motion;
pub(crate) mod networks;
pub mod schedule;
pub mod spec;
mod tasks;
pub mod transforms;

pub use draws::{Draws, STREAM_MAGNET};
pub use family::{Magnet, PartnerOptions};
pub use generate::{MagnetOptions, MagnetOutput};
pub use live::{LivePartner, DECODER_CONTEXT_TOKENS, ENCODER_CONTEXT_TOKENS};
