//! [`Magnet`]: a loaded MAGNet model, what `Model::magnet` gives. Runs the official code's
//! released tasks ([`Magnet::generate`]) and streams a live partner to a user
//! ([`Magnet::partner`]).

use std::any::Any;
use std::sync::Arc;

use ndarray::{ArrayView2, ArrayView3};

use crate::family::section::FamilySection;
use crate::family::session::Session;
use crate::family::{family_as, Family, SessionOptions, StreamOptions};
use crate::magnet::draws::Draws;
use crate::magnet::generate::{
    configuration, default_live_config, generate, injected_draws, output_shape, MagnetOptions,
    MagnetOutput,
};
use crate::magnet::layout::FRAMES_PER_TOKEN;
use crate::magnet::live::{check_persons, LivePartner, LiveSettings};
use crate::magnet::networks::Networks;
use crate::magnet::spec::{MagnetSpec, SamplingSpec};
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::{BundleIo, ConditionSpec, MotionSpec};
use crate::shared::error::Result;
use crate::shared::graph_spec::GraphSpec;
use crate::shared::snapshot::SnapshotReader;

/// Options of a live partner stream. Fields left `None` take the configuration's defaults.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PartnerOptions {
    /// Seed of troupe's generator.
    pub seed: u64,
    /// DDIM steps per chunk.
    pub steps: Option<u32>,
    /// Context tokens per window (`Tc`, 1 to window - 1; the stride is the rest).
    pub context_capacity: Option<usize>,
    /// The partner's opening frames, `[context frames, 145]` row-major (also
    /// [`LivePartner::set_partner_opening`]). A stream needs them before the user's first frame.
    pub opening: Option<Vec<f32>>,
    /// The sampling configuration: a released name or JSON; `None` is the bundle's first
    /// `motion_control_live` configuration.
    pub live_config: Option<String>,
    /// Emit each chunk's partner frames as soon as they are generated: `4 (Tm - Tc)` frames
    /// less latency, but the next chunk's smoothing no longer reaches them.
    pub early_emission: bool,
}

/// A loaded `magnet` bundle. Cheap to clone; clones and partners share its graphs.
#[derive(Debug, Clone)]
pub struct Magnet {
    nets: Arc<Networks>,
}

impl Magnet {
    pub(crate) fn new(nets: Networks) -> Self {
        Self {
            nets: Arc::new(nets),
        }
    }

    /// The loaded graphs (the family's own tests call them directly).
    #[cfg(test)]
    pub(crate) fn networks(&self) -> &Networks {
        &self.nets
    }

    /// The bundle's `magnet` manifest section.
    pub fn spec(&self) -> &MagnetSpec {
        &self.nets.spec
    }

    /// Runs the sampling configuration `config` (one of the bundle's released ones, by the
    /// official YAML's name: `dd100`, `dd100_partner_prediction`, ..., see
    /// [`MagnetSpec::sampling`]; or a whole configuration as JSON, the fields of those entries)
    /// on a clip of `frames` `[F, P, 145]` (per person and frame: betas, the 21 body joints'
    /// 6-D rotations, the root's pose in the world, y up; `onnx/README.md`, "Family `magnet`"),
    /// every person present unless `mask` `[F, P]` says otherwise. What the frames are depends
    /// on the task: the context (its first `context_len` frames) for joint generation,
    /// turn-taking and sync; person 0's whole motion (and the others' first `context_len`
    /// frames) for partner prediction, the live partner, inpainting and pp2joint; the key
    /// frames for in-betweening. Returns the sampled tokens and the frames they decode to,
    /// every person's root in the input's world frame.
    pub fn generate(
        &self,
        config: &str,
        frames: ArrayView3<f32>,
        mask: Option<ArrayView2<bool>>,
        options: &MagnetOptions,
    ) -> Result<MagnetOutput> {
        let cfg = configuration(&self.nets, config, options)?;
        generate(&self.nets, cfg, frames, mask, injected_draws(options)?)
    }

    /// [`Magnet::generate`] with a configuration of the caller's (checked as the manifest's
    /// are: the task fits the model, lengths fit the window) and, optionally, every draw of the
    /// run.
    pub fn generate_with(
        &self,
        sampling: &SamplingSpec,
        frames: ArrayView3<f32>,
        mask: Option<ArrayView2<bool>>,
        draws: Option<Vec<Vec<f32>>>,
    ) -> Result<MagnetOutput> {
        generate(
            &self.nets,
            sampling.clone(),
            frames,
            mask,
            draws.map(Draws::injected),
        )
    }

    /// The shape `[S, F, P, 145]` of the frames [`Magnet::generate`] returns for
    /// `input_frames` frames of input, without running it (the same checks of the
    /// configuration and the input's length).
    pub fn output_shape(
        &self,
        config: &str,
        input_frames: usize,
        options: &MagnetOptions,
    ) -> Result<[usize; 4]> {
        let cfg = configuration(&self.nets, config, options)?;
        output_shape(&self.nets, &cfg, input_frames)
    }

    /// The sampling configuration a default live partner runs.
    pub fn live_configuration(&self) -> Result<SamplingSpec> {
        Ok(self.live_settings(&PartnerOptions::default())?.sampling)
    }

    /// Starts a live partner stream (a two-person model's `motion_control_live`
    /// configuration). Give the partner's opening frames before the user's first frame.
    pub(crate) fn partner(&self, options: PartnerOptions) -> Result<LivePartner> {
        let settings = self.live_settings(&options)?;
        LivePartner::new(Arc::clone(&self.nets), settings)
    }

    /// The settings a partner with `options` starts with.
    fn live_settings(&self, options: &PartnerOptions) -> Result<LiveSettings> {
        check_persons(&self.nets)?;
        let name = match &options.live_config {
            Some(name) => name.clone(),
            None => default_live_config(&self.nets)?,
        };
        let mut sampling = configuration(
            &self.nets,
            &name,
            &MagnetOptions {
                samples: Some(1),
                steps: options.steps.map(|s| s as usize),
                seed: Some(options.seed),
                ..Default::default()
            },
        )?;
        if let Some(tc) = options.context_capacity {
            sampling.context_len = tc.saturating_mul(FRAMES_PER_TOKEN);
        }
        Ok(LiveSettings {
            sampling,
            seed: options.seed,
            early: options.early_emission,
            opening: options.opening.clone(),
        })
    }
}

impl Family for Magnet {
    fn name(&self) -> &'static str {
        "magnet"
    }

    fn frames_per_token(&self) -> usize {
        FRAMES_PER_TOKEN
    }

    fn latent_dim(&self) -> usize {
        self.nets.spec.model.token_dim
    }

    /// The live partner's with the default (final) emission: a window of user frames,
    /// `4 Tm - 1` (a session's own latency follows its options).
    fn latency_frames(&self) -> usize {
        self.nets.spec.model.window * FRAMES_PER_TOKEN - 1
    }

    /// Joint positions become SMPL-X frames by inverse kinematics, frame by frame: no latency.
    /// `n` plus the frames a stream may hold back, under one window (`4 Tm`).
    fn max_output_frames(&self, n: usize) -> usize {
        n.saturating_add(self.nets.spec.model.window * FRAMES_PER_TOKEN)
    }

    fn session(&self, options: &SessionOptions) -> Result<Session> {
        Ok(Session::new(self.partner(options.clone().into())?))
    }

    fn restore(&self, payload: &mut SnapshotReader) -> Result<Session> {
        Ok(Session::new(LivePartner::restore(
            Arc::clone(&self.nets),
            payload,
        )?))
    }

    /// The default live configuration's steps and context tokens.
    fn session_defaults(&self) -> Result<SessionOptions> {
        let live = self.live_configuration()?;
        Ok(SessionOptions {
            seed: 0,
            steps: Some(live.steps.min(u32::MAX as usize) as u32),
            context_capacity: Some(live.context_len / FRAMES_PER_TOKEN),
        })
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// The common options, everything else the configuration's.
impl From<SessionOptions> for PartnerOptions {
    fn from(common: SessionOptions) -> Self {
        Self {
            seed: common.seed,
            steps: common.steps,
            context_capacity: common.context_capacity,
            ..Self::default()
        }
    }
}

impl crate::family::sealed::Sealed for PartnerOptions {}

impl StreamOptions for PartnerOptions {
    #[allow(private_interfaces)]
    fn open(self, family: &dyn Family) -> Result<Session> {
        let magnet: &Magnet = family_as(family, "magnet", "a live partner stream")?;
        Ok(Session::new(magnet.partner(self)?))
    }
}

// The section's own checks are inherent methods of `MagnetSpec` (`spec.rs`), called by path.
impl FamilySection for MagnetSpec {
    fn name(&self) -> &'static str {
        "magnet"
    }
    fn validate(&self, motion: &MotionSpec, condition: &ConditionSpec) -> Result<(), String> {
        MagnetSpec::validate(self, motion, condition)
    }
    fn graph_contract<'a>(
        &'a self,
        _: &MotionSpec,
        _: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)> {
        MagnetSpec::graph_contract(self)
    }
    fn load(&self, files: &BundleFiles, io: BundleIo) -> Result<Box<dyn Family>> {
        Ok(Box::new(Magnet::new(Networks::load(
            files,
            io,
            self.clone(),
        )?)))
    }
}
