//! The `umf` family's manifest fields: the pyramid's stages and jumps, the solvers, and the four
//! graphs of text-to-group generation (`docs/spec/umf.md`).

use serde::{Deserialize, Serialize};

use super::pyramid::{Jump, Layout};
use crate::shared::bundle_io::{ConditionSpec, MotionSpec};
use crate::shared::checks::ensure;
use crate::shared::graph_spec::{contract, float, sym, Dim, GraphSpec};
use crate::shared::solver::Solver;
use crate::shared::text::branch::text_branch_contract;

/// The manifest fields of a `umf` bundle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct UmfSpec {
    /// The latent of one person.
    pub latent: UmfLatentSpec,
    /// Frames the decoder returns per person.
    pub clip_frames: usize,
    /// How the condition vector splits between the two denoisers.
    pub text: TextSpec,
    /// The first person's coarse-to-fine stages.
    pub pyramid: PyramidSpec,
    /// Default solvers and guidance.
    pub sampler: UmfSamplerSpec,
    /// The ONNX graphs of the bundle.
    pub graphs: UmfGraphs,
}

/// One person's latent: `tokens x dim` floats.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct UmfLatentSpec {
    /// Latent tokens per person at full resolution (UMF: 16).
    pub tokens: usize,
    /// Floats per token (UMF: 64).
    pub dim: usize,
}

/// The condition vector is `[prior text ; reaction text]`: the text feature each denoiser reads
/// (UMF encodes the prompt with a separate branch for each).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TextSpec {
    /// Floats of the first person's (P-Flow) text feature.
    pub prior_dim: usize,
    /// Floats of the further persons' (S-Flow) text feature.
    pub reaction_dim: usize,
}

/// The pyramid of the first person.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PyramidSpec {
    /// How tokens pool between stages.
    pub layout: Layout,
    /// Correlation of the jump noise inside a block (UMF's code: -0.2; the paper: -1/3).
    pub gamma: f64,
    /// Divides the stage time tables before the denoiser sees them (UMF: 1000).
    pub time_scale: f64,
    /// Coarsest first.
    pub stages: Vec<StageSpec>,
}

/// One pyramid stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StageSpec {
    /// Latent tokens at this stage's resolution.
    pub tokens: usize,
    /// Flow time where the stage starts (0 for the first; set by the jump for the others).
    pub start_t: f64,
    /// Flow time where the stage ends (1 for the last).
    pub end_t: f64,
    /// Network time at local `tau = 0` and `tau = 1`, before division by `time_scale`
    /// (UMF: 0 and 412.587, then 413 and 999).
    pub timesteps: [f64; 2],
}

/// Default solvers and guidance.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct UmfSamplerSpec {
    /// One solver per pyramid stage.
    pub prior: Vec<Solver>,
    /// The solver of each further person's semi-noise flow.
    pub reaction: Solver,
    /// Classifier-free guidance scale (1: off).
    pub cfg_scale: f32,
}

/// The graphs of a `umf` bundle, by role.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct UmfGraphs {
    /// P-Flow denoiser: velocity of the first person's latent at any stage's resolution.
    pub prior: GraphSpec,
    /// S-Flow denoiser: velocity of the `[noise->context ; context->reaction]` state.
    pub reaction: GraphSpec,
    /// Context adapter: the people generated so far, pooled into one context latent.
    pub context: GraphSpec,
    /// VAE decoder: latents to motion features (denormalised).
    pub decoder: GraphSpec,
    /// The official trainable text branches: CLIP token features and the end-of-text index to
    /// the condition vector `[prior text ; reaction text]`. Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_branch: Option<GraphSpec>,
    /// CLIP's text tower: a prompt's token ids to the features both text branches read
    /// (`text.prior_dim` wide). Optional; comes with the manifest's `tokenizer`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_encoder: Option<GraphSpec>,
}

impl UmfSpec {
    /// The jump into each stage after the first.
    pub(crate) fn jumps(&self) -> crate::shared::error::Result<Vec<Jump>> {
        let p = &self.pyramid;
        p.stages
            .windows(2)
            .map(|w| Jump::new(p.layout, p.gamma, w[0].end_t))
            .collect()
    }

    pub(crate) fn validate(&self, condition: &ConditionSpec) -> Result<(), String> {
        let (l, p) = (&self.latent, &self.pyramid);
        ensure(l.tokens > 0 && l.dim > 0 && self.clip_frames > 0, || {
            "latent.tokens, latent.dim and clip_frames must be positive".into()
        })?;
        ensure(
            self.text.prior_dim + self.text.reaction_dim == condition.dim,
            || {
                format!(
                    "text.prior_dim {} + text.reaction_dim {} must equal condition.dim {}",
                    self.text.prior_dim, self.text.reaction_dim, condition.dim
                )
            },
        )?;
        ensure(
            self.graphs.text_branch.is_none() || self.text.prior_dim == self.text.reaction_dim,
            || {
                "a text_branch needs text.prior_dim == text.reaction_dim (both read CLIP's features)".into()
            },
        )?;
        ensure(!p.stages.is_empty(), || "pyramid.stages is empty".into())?;
        ensure(p.time_scale.is_finite() && p.time_scale > 0.0, || {
            format!("pyramid.time_scale {} must be positive", p.time_scale)
        })?;
        let last = p.stages.len() - 1;
        ensure(p.stages[last].tokens == l.tokens, || {
            format!(
                "the last stage has {} tokens, latent.tokens is {}",
                p.stages[last].tokens, l.tokens
            )
        })?;
        ensure(
            p.stages[0].start_t == 0.0 && p.stages[last].end_t == 1.0,
            || "the first stage must start at t = 0 and the last end at t = 1".into(),
        )?;
        for (k, s) in p.stages.iter().enumerate() {
            ensure(
                s.start_t < s.end_t && s.timesteps.iter().all(|t| t.is_finite()),
                || {
                    format!(
                    "pyramid.stages[{k}]: start_t {} must be below end_t {} and the timesteps finite",
                    s.start_t, s.end_t
                )
                },
            )?;
        }
        let jumps = self.jumps().map_err(|e| format!("pyramid: {e}"))?;
        for (k, jump) in jumps.iter().enumerate() {
            let (coarse, fine) = (&p.stages[k], &p.stages[k + 1]);
            ensure(
                p.layout.can_pool(fine.tokens) && fine.tokens == coarse.tokens * p.layout.block(),
                || {
                    format!(
                        "pyramid.stages[{}] has {} tokens; a {:?} pyramid needs {} tokens before \
                         stage {} ({} tokens)",
                        k,
                        coarse.tokens,
                        p.layout,
                        fine.tokens / p.layout.block(),
                        k + 1,
                        fine.tokens
                    )
                },
            )?;
            ensure((fine.start_t - jump.start_t).abs() < 1e-6, || {
                format!(
                    "pyramid.stages[{}].start_t is {}, but gamma {} and the previous stage's \
                     end_t {} put it at {}",
                    k + 1,
                    fine.start_t,
                    p.gamma,
                    coarse.end_t,
                    jump.start_t
                )
            })?;
        }
        let s = &self.sampler;
        ensure(s.prior.len() == p.stages.len(), || {
            format!(
                "sampler.prior has {} solvers for {} pyramid stages",
                s.prior.len(),
                p.stages.len()
            )
        })?;
        for solver in s.prior.iter().chain([&s.reaction]) {
            solver.check("sampler").map_err(|e| e.to_string())?;
        }
        ensure(s.cfg_scale.is_finite(), || {
            "sampler.cfg_scale must be finite".into()
        })
    }

    /// Each graph as declared, next to the interface the runtime requires of it.
    pub(crate) fn graph_contract<'a>(
        &'a self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)> {
        let (n, f) = (Dim::Fixed, float);
        let (tokens, dim) = (self.latent.tokens, self.latent.dim);
        let g = &self.graphs;
        let denoiser = |spec: &GraphSpec, state: &str, len: Dim, width: usize, text: usize| {
            contract(
                spec,
                vec![
                    f(state, vec![sym("B"), len.clone(), n(width)]),
                    f("timestep", vec![sym("B")]),
                    f("text", vec![sym("B"), n(text)]),
                ],
                vec![f("velocity", vec![sym("B"), len, n(width)])],
            )
        };
        let mut contracts = vec![
            (
                "prior",
                &g.prior,
                denoiser(&g.prior, "sample", sym("N"), dim, self.text.prior_dim),
            ),
            (
                "reaction",
                &g.reaction,
                denoiser(
                    &g.reaction,
                    "state",
                    n(tokens),
                    2 * dim,
                    self.text.reaction_dim,
                ),
            ),
            (
                "context",
                &g.context,
                contract(
                    &g.context,
                    vec![f("latents", vec![n(1), sym("P"), n(tokens), n(dim)])],
                    vec![f("context", vec![n(1), n(tokens), n(dim)])],
                ),
            ),
            (
                "decoder",
                &g.decoder,
                contract(
                    &g.decoder,
                    vec![f("latents", vec![sym("B"), n(tokens), n(dim)])],
                    vec![f(
                        "motion",
                        vec![sym("B"), n(self.clip_frames), n(motion.frame_dim)],
                    )],
                ),
            ),
        ];
        if let Some(text) = &g.text_branch {
            // Both text encoders read CLIP's token features, as wide as each one's output.
            let contract = text_branch_contract(text, self.text.prior_dim, condition.dim);
            contracts.push(("text_branch", text, contract));
        }
        contracts
    }
}
