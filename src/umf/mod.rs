//! The `umf` family: text to a group of any size (`docs/spec/umf.md`). The first person comes from
//! Pyramid Flow (coarse-to-fine stages with a jump-renoise between them), every further person
//! from Semi-Noise Flow over a context of everyone before, then one decode.
//!
//! - `family`: [`Umf`], the loaded model (`Model::umf`);
//! - [`spec`]: the family's manifest section and the interface it requires of its graphs;
//! - `networks`: the loaded graphs;
//! - [`pyramid`]: the resolution ladder and its block-correlated jump noise;
//! - `group`: the sampler, [`Umf::generate_group`].
//!
//! Like every family, this folder imports only from `crate::shared`, `crate::motion` and itself.

mod family;
mod group;
pub(crate) mod networks;
pub mod pyramid;
pub mod spec;

pub use family::Umf;
pub use group::{
    Group, GroupNoise, GroupNoiseShape, GroupOptions, MAX_PEOPLE, STREAM_JUMP_NOISE,
    STREAM_PRIOR_NOISE, STREAM_REACTION_NOISE,
};
