//! [`Umf`]: a loaded UMF model, what `Model::umf` gives. Generates whole groups from a text
//! condition ([`Umf::generate_group`]); it does not stream.

use std::any::Any;

use crate::family::section::FamilySection;
use crate::family::Family;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::{BundleIo, ConditionSpec, MotionSpec};
use crate::shared::error::Result;
use crate::shared::graph_spec::GraphSpec;
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::PromptEncoder;
use crate::umf::group::{Group, GroupNoise, GroupNoiseShape, GroupOptions};
use crate::umf::networks::Networks;
use crate::umf::spec::UmfSpec;

/// A loaded `umf` bundle.
#[derive(Debug)]
pub struct Umf {
    nets: Networks,
}

impl Umf {
    pub(crate) fn new(nets: Networks) -> Self {
        Self { nets }
    }

    /// The bundle's `umf` manifest section.
    pub fn spec(&self) -> &UmfSpec {
        &self.nets.spec
    }

    /// Generates `people` persons' motion for `condition` (`[prior text ; reaction text]`,
    /// `condition_dim` floats; `None` is the bundle's null condition; a prompt's is
    /// `Model::encode_prompt`'s).
    ///
    /// ```no_run
    /// use troupe::{GroupOptions, Model};
    /// let model = Model::load("onnx/bundles/umf-tiny")?;
    /// let group = model.umf()?.generate_group(None, 3, &GroupOptions::default())?;
    /// assert_eq!(group.motion.shape()[0], 3);
    /// # Ok::<(), troupe::Error>(())
    /// ```
    pub fn generate_group(
        &self,
        condition: Option<&[f32]>,
        people: usize,
        options: &GroupOptions,
    ) -> Result<Group> {
        self.nets.generate_group(condition, people, options)
    }

    /// The noise [`Umf::generate_group`] draws for `seed` and `people` when none is given:
    /// Philox normals (see [`crate::noise`]) on streams [`crate::STREAM_PRIOR_NOISE`],
    /// [`crate::STREAM_JUMP_NOISE`] (turned into block noise by each jump's covariance factor)
    /// and [`crate::STREAM_REACTION_NOISE`].
    pub fn group_noise(&self, seed: u64, people: usize) -> Result<GroupNoise> {
        self.nets.group_noise(seed, people)
    }

    /// The shape of the [`GroupNoise`] of `people` people (1 to [`crate::MAX_PEOPLE`]).
    pub fn group_noise_shape(&self, people: usize) -> Result<GroupNoiseShape> {
        self.nets.group_noise_shape(people)
    }
}

impl Family for Umf {
    fn name(&self) -> &'static str {
        "umf"
    }

    /// UMF's tokens are global queries, not spans of frames.
    fn frames_per_token(&self) -> usize {
        0
    }

    fn latent_dim(&self) -> usize {
        self.nets.spec.latent.dim
    }

    fn latency_frames(&self) -> usize {
        0
    }

    fn max_output_frames(&self, _n: usize) -> usize {
        0
    }

    fn clip_frames(&self) -> usize {
        self.nets.spec.clip_frames
    }

    fn prompt_encoder(&self) -> Option<PromptEncoder<'_>> {
        self.nets.prompt_encoder()
    }

    fn text_branch(&self) -> Option<TextBranch<'_>> {
        self.nets.text_branch()
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

// The section's own checks are inherent methods of `UmfSpec` (`spec.rs`), called by path.
impl FamilySection for UmfSpec {
    fn name(&self) -> &'static str {
        "umf"
    }
    fn validate(&self, _: &MotionSpec, condition: &ConditionSpec) -> Result<(), String> {
        UmfSpec::validate(self, condition)
    }
    fn graph_contract<'a>(
        &'a self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)> {
        UmfSpec::graph_contract(self, motion, condition)
    }
    fn text_graphs(&self) -> (Option<&GraphSpec>, Option<&GraphSpec>) {
        let g = &self.graphs;
        (g.text_encoder.as_ref(), g.text_branch.as_ref())
    }
    /// Each text branch reads CLIP features of `text.prior_dim` floats.
    fn text_token_dim(&self, _: &ConditionSpec) -> usize {
        self.text.prior_dim
    }
    fn load(&self, files: &BundleFiles, io: BundleIo) -> Result<Box<dyn Family>> {
        Ok(Box::new(Umf::new(Networks::load(files, io, self.clone())?)))
    }
}
