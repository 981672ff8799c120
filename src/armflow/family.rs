//! [`Armflow`]: a loaded ARMFlow model, what `Model::armflow` gives. Streams reactors to an
//! actor ([`Armflow::reactor`]) and runs the official clip loop ([`Armflow::generate_clip`]).

use std::any::Any;
use std::sync::Arc;

use ndarray::ArrayView2;

use crate::armflow::clip::{Clip, ClipNoise, ClipOptions};
use crate::armflow::networks::Networks;
use crate::armflow::session::{Reactor, ReactorOptions};
use crate::armflow::spec::{ArmFlowSpec, ClipSpec};
use crate::family::section::FamilySection;
use crate::family::session::Session;
use crate::family::{family_as, Family, SessionOptions, StreamOptions};
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::{BundleIo, ConditionFeedback, ConditionSpec, MotionSpec};
use crate::shared::error::Result;
use crate::shared::graph_spec::GraphSpec;
use crate::shared::snapshot::SnapshotReader;
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::PromptEncoder;

/// A loaded `armflow` bundle. Cheap to clone; clones and reactors share its graphs.
#[derive(Debug, Clone)]
pub struct Armflow {
    nets: Arc<Networks>,
}

impl Armflow {
    pub(crate) fn new(nets: Networks) -> Self {
        Self {
            nets: Arc::new(nets),
        }
    }

    /// The bundle's `armflow` manifest section.
    pub fn spec(&self) -> &ArmFlowSpec {
        &self.nets.spec
    }

    /// The official clip, for a bundle with a `clip` section.
    pub fn clip_spec(&self) -> Option<&ClipSpec> {
        self.nets.spec.clip.as_ref()
    }

    /// Whether the bundle has per-token VAE steps (O(1) per token, no windows).
    pub fn has_vae_steps(&self) -> bool {
        self.nets.has_vae_steps()
    }

    /// Starts a reactor stream; options left unset take the bundle's defaults.
    pub(crate) fn reactor(&self, options: ReactorOptions) -> Result<Reactor> {
        Reactor::new(Arc::clone(&self.nets), options)
    }

    /// The context `c` the encoder gives after `[<sos>, pairs...]`, computed from scratch in one
    /// causal pass (no cache). `pairs` holds `(actor || reactor)` tokens, row-major
    /// `[n, 2 * latent_dim]`; positions are `0..=n`. A reactor's cached stream gives the same
    /// context while its history fits in the context capacity. [`crate::Error::Unsupported`] for a
    /// bundle that feeds each token the reactor's placement (`condition.feedback`): pairs alone
    /// do not carry it.
    pub fn recompute_context(&self, condition: Option<&[f32]>, pairs: &[f32]) -> Result<Vec<f32>> {
        self.nets.recompute_context(condition, pairs)
    }

    /// The draws [`Armflow::generate_clip`] makes for `seed` when none are given.
    pub fn clip_noise(&self, seed: u64) -> Result<ClipNoise> {
        self.nets.clip_noise(seed)
    }

    /// Runs the official ARMFlow sampler on one actor clip (see `armflow/clip.rs`): `actor` is
    /// `[frames, frame_dim]` with 1 to `clip.frames` frames (zero-padded to `clip.frames`);
    /// `condition` the text condition (`None`: the null condition; a prompt's is
    /// `Model::encode_prompt`'s). Needs a bundle with a
    /// `clip` section, exported from the official layout (`onnx/cli.py armflow export --preset
    /// interhuman | interx`).
    ///
    /// ```no_run
    /// use ndarray::Array2;
    /// use troupe::{ClipOptions, Model};
    /// let model = Model::load("onnx/bundles/armflow-tiny-interhuman")?;
    /// let actor = Array2::<f32>::zeros((120, model.frame_dim()));
    /// let clip = model.armflow()?.generate_clip(actor.view(), None, &ClipOptions::default())?;
    /// assert_eq!(clip.frames.nrows(), 300);
    /// # Ok::<(), troupe::Error>(())
    /// ```
    pub fn generate_clip(
        &self,
        actor: ArrayView2<f32>,
        condition: Option<&[f32]>,
        options: &ClipOptions,
    ) -> Result<Clip> {
        self.nets.generate_clip(actor, condition, options)
    }
}

impl Family for Armflow {
    fn name(&self) -> &'static str {
        "armflow"
    }

    fn frames_per_token(&self) -> usize {
        self.nets.spec.latent.frames_per_token
    }

    fn latent_dim(&self) -> usize {
        self.nets.spec.latent.dim
    }

    fn latency_frames(&self) -> usize {
        self.nets.spec.latency_frames()
    }

    fn max_output_frames(&self, n: usize) -> usize {
        let fpt = self.frames_per_token();
        n.div_ceil(fpt).saturating_mul(fpt)
    }

    fn clip_frames(&self) -> usize {
        self.clip_spec().map_or(0, |c| c.frames)
    }

    fn prompt_encoder(&self) -> Option<PromptEncoder<'_>> {
        self.nets.prompt_encoder()
    }

    fn text_branch(&self) -> Option<TextBranch<'_>> {
        self.nets.text_branch()
    }

    fn session(&self, options: &SessionOptions) -> Result<Session> {
        Ok(Session::new(self.reactor(options.clone().into())?))
    }

    fn session_defaults(&self) -> Result<SessionOptions> {
        let spec = &self.nets.spec;
        Ok(SessionOptions {
            seed: 0,
            steps: Some(spec.sampler.steps),
            context_capacity: Some(spec.context.capacity_tokens),
        })
    }

    fn restore(&self, payload: &mut SnapshotReader) -> Result<Session> {
        Ok(Session::new(Reactor::restore(
            Arc::clone(&self.nets),
            payload,
        )?))
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// The common options, everything else the bundle's.
impl From<SessionOptions> for ReactorOptions {
    fn from(common: SessionOptions) -> Self {
        Self {
            seed: common.seed,
            steps: common.steps,
            context_capacity: common.context_capacity,
            ..Self::default()
        }
    }
}

impl crate::family::sealed::Sealed for ReactorOptions {}

impl StreamOptions for ReactorOptions {
    #[allow(private_interfaces)]
    fn open(self, family: &dyn Family) -> Result<Session> {
        let armflow: &Armflow = family_as(family, "armflow", "a reactor stream")?;
        Ok(Session::new(armflow.reactor(self)?))
    }
}

// The section's own checks are inherent methods of `ArmFlowSpec` (`spec.rs`), called by path.
impl FamilySection for ArmFlowSpec {
    fn name(&self) -> &'static str {
        "armflow"
    }
    fn validate(&self, motion: &MotionSpec, _: &ConditionSpec) -> Result<(), String> {
        ArmFlowSpec::validate(self, motion.frame_dim)
    }
    fn validate_feedback(&self, _: &ConditionFeedback, motion: &MotionSpec) -> Result<(), String> {
        ArmFlowSpec::validate_feedback(self, motion)
    }
    fn graph_contract<'a>(
        &'a self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)> {
        ArmFlowSpec::graph_contract(self, motion, condition)
    }
    fn text_graphs(&self) -> (Option<&GraphSpec>, Option<&GraphSpec>) {
        let g = &self.graphs;
        (g.text_encoder.as_ref(), g.text_branch.as_ref())
    }
    fn load(&self, files: &BundleFiles, io: BundleIo) -> Result<Box<dyn Family>> {
        Ok(Box::new(Armflow::new(Networks::load(
            files,
            io,
            self.clone(),
        )?)))
    }
}
