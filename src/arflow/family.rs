//! [`Arflow`]: a loaded ARFlow model, what `Model::arflow` gives. Generates a reactor for a
//! whole actor clip ([`Arflow::generate`]); the online variant also streams, frame by frame
//! ([`Arflow::online`]).

use std::any::Any;
use std::sync::Arc;

use ndarray::{Array2, ArrayView2};

use crate::arflow::networks::Networks;
use crate::arflow::sampler::{self, ArflowOptions};
use crate::arflow::spec::ArflowSpec;
use crate::arflow::stream::OnlineStream;
use crate::family::section::FamilySection;
use crate::family::session::Session;
use crate::family::{family_as, Family, SessionOptions, StreamOptions};
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::{BundleIo, ConditionSpec, MotionSpec};
use crate::shared::error::Result;
use crate::shared::graph_spec::GraphSpec;
use crate::shared::noise::NormalSource;
use crate::shared::snapshot::SnapshotReader;

/// A loaded `arflow` bundle. Cheap to clone; clones and streams share its graphs.
#[derive(Debug, Clone)]
pub struct Arflow {
    nets: Arc<Networks>,
}

impl Arflow {
    pub(crate) fn new(nets: Networks) -> Self {
        Self {
            nets: Arc::new(nets),
        }
    }

    /// The bundle's `arflow` manifest section.
    pub fn spec(&self) -> &ArflowSpec {
        &self.nets.spec
    }

    /// Whether the bundle is the online variant, which streams (`Model::session`).
    pub fn streams(&self) -> bool {
        self.nets.streams()
    }

    /// ARFlow's offline generation: the reactor's `interhuman262` features `[T, 262]` for the
    /// actor's `actor` `[T, 262]` (1 to `model.max_frames` frames, one world frame for both),
    /// with the bundle's sampler settings changed by `options` (guidance strength λ, weight w,
    /// η, d_safe, ...; `docs/ARFLOW.md`). With the online variant's causal network, frame `n`
    /// of the result depends only on the actor's frames up to `n`.
    pub fn generate(&self, actor: ArrayView2<f32>, options: &ArflowOptions) -> Result<Array2<f32>> {
        let sampling = options.apply(&self.nets.spec.sampler)?;
        let mut normals = NormalSource::seeded(options.seed, sampling.stream);
        sampler::generate(&self.nets, actor, &sampling, &mut normals)
    }

    /// [`Arflow::generate`] with the run's standard normals given instead of drawn from the
    /// seed: each draw (the start noise when σ > 0, then one ε per step when η > 0, each
    /// `T * 262` normals) takes the next ones from `normals`, as another implementation's
    /// recorded draws would be replayed. Returns the reactor and how many normals it took; a
    /// run that needs more than given is an error naming the draw.
    pub fn generate_with_normals(
        &self,
        actor: ArrayView2<f32>,
        options: &ArflowOptions,
        normals: &[f32],
    ) -> Result<(Array2<f32>, usize)> {
        let sampling = options.apply(&self.nets.spec.sampler)?;
        let mut queue = NormalSource::queue(normals);
        let reactor = sampler::generate(&self.nets, actor, &sampling, &mut queue)?;
        Ok((reactor, queue.used()))
    }

    /// Starts the online variant's stream: the bundle's sampler settings changed by `options`
    /// (its seed too).
    pub(crate) fn online(&self, options: &ArflowOptions) -> Result<OnlineStream> {
        let sampling = options.apply(&self.nets.spec.sampler)?;
        OnlineStream::new(Arc::clone(&self.nets), sampling, options.seed)
    }
}

impl Family for Arflow {
    fn name(&self) -> &'static str {
        "arflow"
    }

    /// ARFlow has no latent tokens.
    fn frames_per_token(&self) -> usize {
        0
    }

    fn latent_dim(&self) -> usize {
        self.nets.spec.model.dim
    }

    /// A frame out for each frame in.
    fn latency_frames(&self) -> usize {
        0
    }

    fn max_output_frames(&self, n: usize) -> usize {
        n
    }

    fn session(&self, options: &SessionOptions) -> Result<Session> {
        if let Some(capacity) = options.context_capacity {
            // Only the whole history, which `session_defaults` reports.
            if capacity != self.nets.spec.model.max_frames {
                return Err(crate::shared::error::Error::Unsupported(format!(
                    "an ARFlow stream keeps its whole history ({} frames); it takes no context \
                     capacity ({capacity} given)",
                    self.nets.spec.model.max_frames
                )));
            }
        }
        let options = ArflowOptions {
            seed: options.seed,
            steps: options.steps.map(|s| s as usize),
            ..ArflowOptions::default()
        };
        Ok(Session::new(self.online(&options)?))
    }

    /// The sampler's steps; the context is the whole history the position encoding covers.
    fn restore(&self, payload: &mut SnapshotReader) -> Result<Session> {
        Ok(Session::new(OnlineStream::restore(
            Arc::clone(&self.nets),
            payload,
        )?))
    }

    fn session_defaults(&self) -> Result<SessionOptions> {
        let spec = &self.nets.spec;
        Ok(SessionOptions {
            seed: 0,
            steps: Some(spec.sampler.steps.min(u32::MAX as usize) as u32),
            context_capacity: Some(spec.model.max_frames),
        })
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

impl crate::family::sealed::Sealed for ArflowOptions {}

impl StreamOptions for ArflowOptions {
    #[allow(private_interfaces)]
    fn open(self, family: &dyn Family) -> Result<Session> {
        let arflow: &Arflow = family_as(family, "arflow", "an ARFlow stream")?;
        Ok(Session::new(arflow.online(&self)?))
    }
}

// The section's own checks are inherent methods of `ArflowSpec` (`spec.rs`), called by path.
impl FamilySection for ArflowSpec {
    fn name(&self) -> &'static str {
        "arflow"
    }
    fn validate(&self, motion: &MotionSpec, condition: &ConditionSpec) -> Result<(), String> {
        ArflowSpec::validate(self, motion, condition)
    }
    fn graph_contract<'a>(
        &'a self,
        _: &MotionSpec,
        _: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)> {
        ArflowSpec::graph_contract(self)
    }
    fn load(&self, files: &BundleFiles, io: BundleIo) -> Result<Box<dyn Family>> {
        Ok(Box::new(Arflow::new(Networks::load(
            files,
            io,
            self.clone(),
        )?)))
    }
}
