//! The `arflow` family's manifest fields: the network's sizes, the feature normaliser, the
//! sampler's defaults and the one graph (`onnx/README.md`, "Family `arflow`";
//! `docs/spec/arflow.md`).

use serde::{Deserialize, Serialize};

use crate::shared::bundle_io::{ConditionSpec, MotionSpec};
use crate::shared::checks::ensure;
use crate::shared::graph_spec::{contract, float, sym, DType, Dim, GraphSpec, TensorSpec};

/// The feature layout ARFlow bundles speak (the guidance reads joint positions from it).
pub const LAYOUT: &str = "interhuman262";
/// Floats per frame.
pub const FRAME_DIM: usize = 262;
/// The joint positions' floats at the start of a frame (22 joints x 3).
pub const POSITIONS: usize = 66;

/// The manifest fields of an `arflow` bundle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ArflowSpec {
    /// The network's sizes.
    pub model: ArflowModelSpec,
    /// The linear normaliser the flow runs behind.
    pub normalizer: NormalizerSpec,
    /// The sampler's defaults.
    pub sampler: ArflowSampling,
    /// The ONNX graphs.
    pub graphs: ArflowGraphs,
}

/// The network (`onnx/troupe_onnx/arflow/networks.py`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ArflowModelSpec {
    /// Features per frame.
    pub dim: usize,
    /// Transformer width.
    pub width: usize,
    /// Decoder layers.
    pub layers: usize,
    /// Attention heads.
    pub heads: usize,
    /// Feed-forward width.
    pub feedforward: usize,
    /// Width of the optional condition (0: none).
    pub condition_dim: usize,
    /// Whether self-attention sees only earlier frames (the online variant).
    pub causal: bool,
    /// Frames the position encoding covers: the longest clip.
    pub max_frames: usize,
}

/// `normalised = (feature - mean) / std`, per feature.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NormalizerSpec {
    /// One mean per feature.
    pub mean: Vec<f32>,
    /// One positive standard deviation per feature.
    pub std: Vec<f32>,
}

/// How the stochastic direction mixes with the projection direction (`docs/spec/arflow.md` §4;
/// the paper does not say which).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mixing {
    /// `d = (1 − η) v + η ε`.
    Linear,
    /// `d = √(1 − η²) v + η ε`.
    VariancePreserving,
}

/// The sampler's settings (`docs/spec/arflow.md` §2-§5; every open point an option).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArflowSampling {
    /// Euler steps M (>= 1).
    pub steps: usize,
    /// The guidance strength λ (>= 0; 0: no guidance).
    pub guidance: f32,
    /// The reweighting toward the actor, w in [0, 1] (1: none).
    pub weight: f32,
    /// The stochastic direction's share η in [0, 1) (0: deterministic).
    pub eta: f32,
    /// The penetration loss's safe distance, metres.
    pub d_safe: f32,
    /// A squared hinge (else linear).
    pub squared: bool,
    /// Back-project with the guided x̂_1 (else the network's).
    pub guided_backprojection: bool,
    /// How the stochastic direction mixes in.
    pub mixing: Mixing,
    /// The start noise: x_0 = a + σ ε (0: none).
    pub sigma: f32,
    /// troupe's Philox stream for the draws.
    #[serde(default = "stream_default")]
    pub stream: u32,
}

/// troupe's Philox stream for ARFlow's draws.
pub const STREAM_ARFLOW: u32 = 9;

fn stream_default() -> u32 {
    STREAM_ARFLOW
}

/// The graphs of an `arflow` bundle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ArflowGraphs {
    /// `(x [B, T, D], t [B]) -> x1 [B, T, D]`: the network's x̂_1.
    pub denoiser: GraphSpec,
    /// The online variant one frame at a time, for streams: `(x [B, 1, D], t [B], position
    /// [B], cache_k, cache_v [B, L, H, C, W/H], cache_mask [B, C]) -> (x1 [B, 1, D], k, v
    /// [B, L, H, 1, W/H])`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoiser_step: Option<GraphSpec>,
}

impl ArflowSampling {
    /// The settings' ranges.
    pub(crate) fn validate(&self) -> Result<(), String> {
        ensure((1..=1000).contains(&self.steps), || {
            format!("steps {} is not in 1..=1000", self.steps)
        })?;
        ensure(
            self.guidance.is_finite() && self.guidance >= 0.0 && self.guidance <= 1e3,
            || {
                format!(
                    "the guidance strength λ {} is not in [0, 1000]",
                    self.guidance
                )
            },
        )?;
        ensure((0.0..=1.0).contains(&self.weight), || {
            format!("the weight w {} is not in [0, 1]", self.weight)
        })?;
        ensure((0.0..1.0).contains(&self.eta), || {
            format!("η {} is not in [0, 1)", self.eta)
        })?;
        ensure((0.0..=1.0).contains(&self.d_safe), || {
            format!("d_safe {} m is not in [0, 1] m", self.d_safe)
        })?;
        ensure((0.0..=10.0).contains(&self.sigma), || {
            format!("σ {} is not in [0, 10]", self.sigma)
        })
    }
}

impl ArflowSpec {
    pub(crate) fn validate(
        &self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Result<(), String> {
        let m = &self.model;
        ensure(
            motion.layout == LAYOUT && motion.frame_dim == FRAME_DIM && m.dim == FRAME_DIM,
            || {
                format!(
                    "motion: an arflow bundle's frames are `{LAYOUT}` ({FRAME_DIM} floats), the \
                     manifest says `{}` ({}) and model.dim {}",
                    motion.layout, motion.frame_dim, m.dim
                )
            },
        )?;
        ensure(condition.dim == 0 && m.condition_dim == 0, || {
            "condition: troupe's arflow bundles take no condition yet (c = ∅)".into()
        })?;
        ensure(m.max_frames >= 1, || {
            "model.max_frames must be positive".into()
        })?;
        let n = &self.normalizer;
        ensure(
            n.mean.len() == FRAME_DIM && n.std.len() == FRAME_DIM,
            || format!("normalizer: {FRAME_DIM} means and standard deviations"),
        )?;
        ensure(
            n.mean.iter().all(|v| v.is_finite()) && n.std.iter().all(|v| v.is_finite() && *v > 0.0),
            || "normalizer: finite means, finite positive standard deviations".into(),
        )?;
        self.sampler.validate().map_err(|e| format!("sampler: {e}"))
    }

    /// Each graph as declared, next to the interface the runtime requires of it.
    pub(crate) fn graph_contract(&self) -> Vec<(&'static str, &GraphSpec, GraphSpec)> {
        let d = Dim::Fixed(self.model.dim);
        let frames = |name: &str| float(name, vec![sym("B"), sym("T"), d.clone()]);
        let g = &self.graphs;
        let m = &self.model;
        let mut contracts = vec![(
            "denoiser",
            &g.denoiser,
            contract(
                &g.denoiser,
                vec![frames("x"), float("t", vec![sym("B")])],
                vec![frames("x1")],
            ),
        )];
        if let Some(step) = &g.denoiser_step {
            let (l, h, dh) = (m.layers, m.heads, m.width / m.heads.max(1));
            let kv = |name: &str, c: Dim| {
                float(
                    name,
                    vec![sym("B"), Dim::Fixed(l), Dim::Fixed(h), c, Dim::Fixed(dh)],
                )
            };
            let one = |name: &str| float(name, vec![sym("B"), Dim::Fixed(1), d.clone()]);
            let position = TensorSpec {
                name: "position".into(),
                dtype: DType::Int64,
                shape: vec![sym("B")],
            };
            contracts.push((
                "denoiser_step",
                step,
                contract(
                    step,
                    vec![
                        one("x"),
                        float("t", vec![sym("B")]),
                        position,
                        kv("cache_k", sym("C")),
                        kv("cache_v", sym("C")),
                        float("cache_mask", vec![sym("B"), sym("C")]),
                    ],
                    vec![one("x1"), kv("k", Dim::Fixed(1)), kv("v", Dim::Fixed(1))],
                ),
            ));
        }
        contracts
    }
}
