//! The `magnet` family's manifest fields: the checkpoint's architecture, the codebook, the
//! normalisation statistics, the noise schedule, the released sampling configurations and the
//! four graphs (`onnx/README.md`, "Family `magnet`"; `docs/spec/magnet.md`).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::layout::{
    BETAS, BODY_JOINTS, DECODER_COND_DIM, ENCODER_COND_DIM, FRAMES_PER_TOKEN, FRAME_DIM,
    FRAME_LAYOUT, POSE_DIM, STATS_DIM, TOKEN_TRANSFORMS,
};
use super::schedule::{cosine_tables, level_table};
use crate::shared::bundle_io::{ConditionSpec, MotionSpec};
use crate::shared::checks::ensure;
use crate::shared::graph_spec::{contract, float, sym, DType, Dim, GraphSpec, TensorSpec};

/// The most people a MAGNet checkpoint may be trained for (the released ones have 2 to 4).
pub const MAX_PERSONS: usize = 8;

/// The manifest fields of a `magnet` bundle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MagnetSpec {
    /// The checkpoint's architecture.
    pub model: MagnetModelSpec,
    /// The VQ codebook the latents snap to before decoding.
    pub codebook: CodebookSpec,
    /// The features' normalisation (361 means and standard deviations, §1.3).
    pub statistics: StatisticsSpec,
    /// The noise schedule's tables and the step -> level tables.
    pub schedule: ScheduleSpec,
    /// The released sampling configurations this model runs, by the official YAML's name.
    pub sampling: BTreeMap<String, SamplingSpec>,
    /// The ONNX graphs of the bundle.
    pub graphs: MagnetGraphs,
}

/// A checkpoint's architecture (§2.2, §1.4).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MagnetModelSpec {
    /// Frames per token (4: the VQ-VAE's temporal factor).
    pub frames_per_token: usize,
    /// SMPL-X body joints without the pelvis (21).
    pub body_joints: usize,
    /// People the checkpoint was trained for (P).
    pub persons: usize,
    /// Tokens per window (Tm; 16 released).
    pub window: usize,
    /// Transformer layers.
    pub layers: usize,
    /// Attention heads.
    pub heads: usize,
    /// Feed-forward width.
    pub d_feedforward: usize,
    /// Width of the noise-level (and, in `concat` mode, person) embedding.
    pub embed_dim: usize,
    /// `concat` or `add`.
    pub person_embedding_mode: String,
    /// Discrete diffusion levels (1000).
    pub max_t: usize,
    /// The pose VQ-VAE.
    pub vq: VqSpec,
    /// Floats per token: `vq.d_latent + 36 * persons`.
    pub token_dim: usize,
}

/// The pose VQ-VAE's sizes.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct VqSpec {
    /// Latent width.
    pub d_latent: usize,
    /// Hidden width.
    pub d_hidden: usize,
    /// Codebook rows.
    pub code_nb: usize,
    /// Residual blocks per stage.
    pub depth: usize,
    /// The codebook rows' norm bound.
    pub r_max: f32,
}

/// The codebook file: raw little-endian float32, `[code_nb, d_latent]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CodebookSpec {
    /// File name in the bundle.
    pub file: String,
    /// Always `float32`.
    pub dtype: String,
    /// `[code_nb, d_latent]`.
    pub shape: Vec<usize>,
}

/// Normalisation statistics of the per-person features (§1.3).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StatisticsSpec {
    /// 361 means.
    pub mean: Vec<f32>,
    /// 361 standard deviations (positive).
    pub std: Vec<f32>,
}

/// The cosine schedule's float32 tables and the level tables (§3.1, §3.2).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ScheduleSpec {
    /// `cosine`.
    pub kind: String,
    /// The cosine schedule's offset (0.008).
    pub s: f64,
    /// Levels (1000).
    pub max_t: usize,
    /// ᾱ per level, float32.
    pub abar: Vec<f32>,
    /// √ᾱ per level (square roots taken in float64, then rounded).
    pub sqrt_abar: Vec<f32>,
    /// √(1 − ᾱ) per level.
    pub sqrt_one_minus_abar: Vec<f32>,
    /// For each step count a configuration uses: the level of each step index.
    pub levels: BTreeMap<String, Vec<i64>>,
}

/// What a sampling configuration does (§5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Task {
    /// Everyone's future from everyone's past (§5.2).
    Joint,
    /// Person 0 given throughout; the others predicted from their past (§5.3).
    PartnerPrediction,
    /// Person 0 given, clean, over each whole window: the live partner (§5.4).
    MotionControlLive,
    /// As `motion_control_live`, with its own schedule (§5.5).
    PartnerInpainting,
    /// Key tokens given, the rest of one window generated (§5.6).
    Inbetweening,
    /// Two copies exchanging tokens, leader and follower (§5.7).
    AgenticTurnTaking,
    /// Two copies, each owning one person's history (§5.8).
    AgenticSync,
    /// Partner prediction, then joint generation from its end (§5.10).
    Pp2joint,
}

impl Task {
    /// The manifest's name.
    pub fn name(self) -> &'static str {
        match self {
            Task::Joint => "joint",
            Task::PartnerPrediction => "partner_prediction",
            Task::MotionControlLive => "motion_control_live",
            Task::PartnerInpainting => "partner_inpainting",
            Task::Inbetweening => "inbetweening",
            Task::AgenticTurnTaking => "agentic_turn_taking",
            Task::AgenticSync => "agentic_sync",
            Task::Pp2joint => "pp2joint",
        }
    }

    /// Whether the task gives person 0's whole motion (the rolling tasks and pp2joint).
    pub fn takes_ground_truth(self) -> bool {
        matches!(
            self,
            Task::PartnerPrediction
                | Task::MotionControlLive
                | Task::PartnerInpainting
                | Task::Pp2joint
        )
    }

    /// The fewest people the task needs.
    pub fn min_persons(self) -> usize {
        match self {
            Task::Joint | Task::Inbetweening => 1,
            _ => 2,
        }
    }
}

/// How step indices are laid over a window's tokens (§4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScheduleKind {
    /// Every token at the same level.
    FullSequence,
    /// The pyramid: each group one step behind the previous one.
    CausalUncertainty,
    /// Groups offset by a share of the steps (`offset_proportion`).
    Autoregressive,
}

/// Whether the post-processing rebuilds partner relations from chained transitions (§5.0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RootMode {
    /// Rebuild them.
    Temporal,
    /// Keep them.
    TemporalPartner,
}

/// One x0-space correction (§6.4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct X0GuidanceSpec {
    /// Its weight (2 DD100, 3 trio).
    pub weight: f32,
    /// The share of the run it starts at.
    pub start: f32,
    /// The share of the run it ends at.
    pub end: f32,
}

/// Guidance (§6): the mask modes' weights, in order, and the two x0 corrections.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuidanceSpec {
    /// `(mode, weight)`: `clean`, `full`, `subset`, `partial`, `person<i>`, `~person<i>`.
    pub scales: Vec<(String, f32)>,
    /// `subset`'s share of the context.
    pub subset_ratio: f32,
    /// `partial`'s blend towards noise.
    pub partial_level: f32,
    /// The smoothing correction, or none.
    pub smoothing: Option<X0GuidanceSpec>,
    /// The foot-skating correction, or none.
    pub foot_skating: Option<X0GuidanceSpec>,
}

/// One sampling configuration (§5.12), lengths in frames as the YAML has them. Unknown keys are
/// refused, naming the key (a misspelt `stepz` is not silently the default).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingSpec {
    /// What it does.
    pub task: Task,
    /// DDIM steps (N).
    pub steps: usize,
    /// DDIM η.
    pub eta: f32,
    /// The scheduling matrix.
    pub schedule: ScheduleKind,
    /// `sampling_subseq_len`.
    pub subseq_len: usize,
    /// Frames an AR window advances.
    pub ar_seq_stride: usize,
    /// The `autoregressive` schedule's offset.
    pub offset_proportion: f64,
    /// Frames to generate (`sampling_seq_len`).
    pub seq_len: usize,
    /// Context frames (`context_seq_len`).
    pub context_len: usize,
    /// Samples generated at once (S).
    pub samples: usize,
    /// The post-processing's mode.
    pub root_mode: RootMode,
    /// The post-window Laplacian smoothing's λ, or none.
    pub temporal_smoothing: Option<f32>,
    /// The first window index smoothing applies to.
    pub smoothing_start: usize,
    /// Whether transforms are cleaned after each window (§5.0).
    pub update_history_transforms: bool,
    /// In-betweening's key frames.
    #[serde(default)]
    pub keyframes: Vec<usize>,
    /// Guidance.
    pub guidance: GuidanceSpec,
    /// The official run's seed.
    pub seed: u64,
}

/// The graphs of a `magnet` bundle, by role.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MagnetGraphs {
    /// The DFoT denoiser: a window of tokens and their levels to x0.
    pub denoiser: GraphSpec,
    /// The VQ encoder (not snapped).
    pub vq_encoder: GraphSpec,
    /// The VQ decoder.
    pub vq_decoder: GraphSpec,
    /// The x0 corrections' gradient through the decoder, on the latents: of
    /// `weights[0] * smoothing + weights[1] * foot skating`, from one forward and one backward.
    pub guidance: GraphSpec,
}

impl MagnetSpec {
    pub(crate) fn validate(
        &self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Result<(), String> {
        let m = &self.model;
        ensure(
            motion.layout == FRAME_LAYOUT && motion.frame_dim == FRAME_DIM,
            || {
                format!(
                    "motion: a magnet bundle's frames are `{FRAME_LAYOUT}` ({FRAME_DIM} floats), \
                 the manifest says `{}` ({})",
                    motion.layout, motion.frame_dim
                )
            },
        )?;
        ensure(condition.dim == 0, || {
            format!(
                "condition.dim is {}: MAGNet takes no condition",
                condition.dim
            )
        })?;
        ensure(
            m.frames_per_token == FRAMES_PER_TOKEN && m.body_joints == BODY_JOINTS,
            || {
                format!(
                    "model: frames_per_token {} and body_joints {} must be {FRAMES_PER_TOKEN} \
                 and {BODY_JOINTS}",
                    m.frames_per_token, m.body_joints
                )
            },
        )?;
        ensure(
            self.graphs
                .guidance
                .inputs
                .first()
                .is_none_or(|x0| x0.shape.len() != 4),
            || {
                "graphs.guidance takes whole windows `[B, Tm, P, D]`, as earlier exporters wrote \
                 it; troupe now gives it person-sequences `[N, Tm, D]` (and leaves out people \
                 whose window is given): re-export the bundle with \
                 `python3 onnx/cli.py magnet export` (the same preset or --checkpoint)"
                    .into()
            },
        )?;
        ensure((1..=MAX_PERSONS).contains(&m.persons), || {
            format!("model.persons {} is not in 1..={MAX_PERSONS}", m.persons)
        })?;
        ensure(m.window >= 3, || {
            format!("model.window {} must be at least 3 tokens", m.window)
        })?;
        ensure(m.max_t >= 2, || "model.max_t must be at least 2".into())?;
        ensure(m.vq.d_latent > 0 && m.vq.code_nb > 0, || {
            "model.vq.d_latent and code_nb must be positive".into()
        })?;
        ensure(
            m.token_dim == m.vq.d_latent + TOKEN_TRANSFORMS * m.persons,
            || {
                format!(
                    "model.token_dim {} must be vq.d_latent {} + {TOKEN_TRANSFORMS} x persons {}",
                    m.token_dim, m.vq.d_latent, m.persons
                )
            },
        )?;
        ensure(
            m.person_embedding_mode == "concat" || m.person_embedding_mode == "add",
            || {
                format!(
                    "model.person_embedding_mode `{}`: concat or add",
                    m.person_embedding_mode
                )
            },
        )?;
        let c = &self.codebook;
        ensure(
            c.dtype == "float32" && c.shape == [m.vq.code_nb, m.vq.d_latent],
            || {
                format!(
                    "codebook: {} {:?}, expected float32 [{}, {}]",
                    c.dtype, c.shape, m.vq.code_nb, m.vq.d_latent
                )
            },
        )?;
        let st = &self.statistics;
        ensure(
            st.mean.len() == STATS_DIM && st.std.len() == STATS_DIM,
            || {
                format!(
                    "statistics: {} means and {} stds, expected {STATS_DIM} each",
                    st.mean.len(),
                    st.std.len()
                )
            },
        )?;
        ensure(
            st.mean.iter().all(|v| v.is_finite())
                && st.std.iter().all(|v| v.is_finite() && *v > 0.0),
            || "statistics: means must be finite and stds finite and positive".into(),
        )?;
        self.validate_schedule()?;
        ensure(!self.sampling.is_empty(), || {
            "sampling: no configuration".into()
        })?;
        for (name, s) in &self.sampling {
            self.validate_sampling(s)
                .map_err(|e| format!("sampling.{name}: {e}"))?;
            ensure(
                self.schedule.levels.contains_key(&s.steps.to_string()),
                || {
                    format!(
                        "sampling.{name}: schedule.levels has no table for {} steps",
                        s.steps
                    )
                },
            )?;
        }
        Ok(())
    }

    fn validate_schedule(&self) -> Result<(), String> {
        let s = &self.schedule;
        let t = self.model.max_t;
        ensure(s.kind == "cosine" && s.max_t == t, || {
            format!(
                "schedule: kind `{}` over {} levels; this runtime runs the cosine schedule over \
                 model.max_t {t}",
                s.kind, s.max_t
            )
        })?;
        let (abar, sqrt_abar, sqrt_rest) = cosine_tables(t, s.s);
        for (name, declared, computed) in [
            ("abar", &s.abar, &abar),
            ("sqrt_abar", &s.sqrt_abar, &sqrt_abar),
            ("sqrt_one_minus_abar", &s.sqrt_one_minus_abar, &sqrt_rest),
        ] {
            ensure(declared.len() == t, || {
                format!("schedule.{name} holds {} values, not {t}", declared.len())
            })?;
            if let Some(i) = (0..t)
                .find(|&i| !declared[i].is_finite() || (declared[i] - computed[i]).abs() > 1e-6)
            {
                return Err(format!(
                    "schedule.{name}[{i}] is {}, the cosine schedule (s = {}) gives {}",
                    declared[i], s.s, computed[i]
                ));
            }
        }
        for (steps, table) in &s.levels {
            let n: usize = steps
                .parse()
                .map_err(|_| format!("schedule.levels: `{steps}` is not a step count"))?;
            ensure(n >= 1 && *table == level_table(n, t), || {
                format!("schedule.levels.{steps} is not the level table of {steps} steps")
            })?;
        }
        Ok(())
    }

    /// A sampling configuration this model can run (the manifest's, or a caller's).
    pub(crate) fn validate_sampling(&self, s: &SamplingSpec) -> Result<(), String> {
        let m = &self.model;
        ensure(s.steps >= 1 && s.samples >= 1, || {
            "steps and samples must be at least 1".into()
        })?;
        ensure(s.steps < m.max_t, || {
            format!("steps {} must be below max_t {}", s.steps, m.max_t)
        })?;
        ensure(m.persons >= s.task.min_persons(), || {
            format!(
                "{} needs at least {} people; the model has {}",
                s.task.name(),
                s.task.min_persons(),
                m.persons
            )
        })?;
        ensure((0.0..=1.0).contains(&s.eta), || {
            format!("eta {} must be in [0, 1]", s.eta)
        })?;
        ensure(
            s.offset_proportion.is_finite() && (0.0..=1.0).contains(&s.offset_proportion),
            || "offset_proportion must be in [0, 1]".into(),
        )?;
        let f = FRAMES_PER_TOKEN;
        let context = s.context_len / f;
        ensure(context < m.window, || {
            format!(
                "context_len {} frames is {} tokens, not fewer than the window's {}",
                s.context_len, context, m.window
            )
        })?;
        ensure(
            s.ar_seq_stride >= f && s.ar_seq_stride / f < m.window,
            || {
                format!(
                    "ar_seq_stride {} frames must be at least {f} and below the window",
                    s.ar_seq_stride
                )
            },
        )?;
        ensure(
            (1..=m.window).contains(&s.subseq_len) && s.seq_len >= f,
            || {
                format!(
                    "subseq_len {} must be 1 to the window's {} tokens, and seq_len at least \
                     one token",
                    s.subseq_len, m.window
                )
            },
        )?;
        if let Some(lambda) = s.temporal_smoothing {
            ensure(lambda.is_finite(), || {
                "temporal_smoothing must be finite".into()
            })?;
        }
        for &k in &s.keyframes {
            // A key frame sets token k / 4 from frames k..k + 4 (the official 63 reads 63..66, §11 A10).
            ensure(k < s.seq_len, || {
                format!("key frame {k} is past seq_len {}", s.seq_len)
            })?;
        }
        let g = &s.guidance;
        for (mode, w) in &g.scales {
            check_mode(mode, m.persons)?;
            ensure(w.is_finite(), || {
                format!("guidance weight of `{mode}` is not finite")
            })?;
        }
        ensure(!g.scales.is_empty(), || "guidance.scales is empty".into())?;
        for x in [g.smoothing, g.foot_skating].into_iter().flatten() {
            ensure(
                x.weight.is_finite() && x.start.is_finite() && x.end.is_finite(),
                || "guidance: x0 corrections must be finite".into(),
            )?;
        }
        Ok(())
    }

    /// Each graph as declared, next to the interface the runtime requires of it.
    pub(crate) fn graph_contract(&self) -> Vec<(&'static str, &GraphSpec, GraphSpec)> {
        let m = &self.model;
        let n = Dim::Fixed;
        let (w, p, d, lat) = (m.window, m.persons, m.token_dim, m.vq.d_latent);
        let window = |name: &str| float(name, vec![sym("B"), n(w), n(p), n(d)]);
        let levels = TensorSpec {
            name: "levels".into(),
            dtype: DType::Int64,
            shape: vec![sym("B"), n(w), n(p)],
        };
        let g = &self.graphs;
        vec![
            (
                "denoiser",
                &g.denoiser,
                contract(&g.denoiser, vec![window("x"), levels], vec![window("x0")]),
            ),
            (
                "vq_encoder",
                &g.vq_encoder,
                contract(
                    &g.vq_encoder,
                    vec![
                        float("pose", vec![sym("N"), sym("T"), n(POSE_DIM)]),
                        float("condition", vec![sym("N"), sym("T"), n(ENCODER_COND_DIM)]),
                    ],
                    vec![float("latents", vec![sym("N"), sym("Z"), n(lat)])],
                ),
            ),
            (
                "vq_decoder",
                &g.vq_decoder,
                contract(
                    &g.vq_decoder,
                    vec![
                        float("latents", vec![sym("N"), sym("Z"), n(lat)]),
                        float("condition", vec![sym("N"), sym("Z"), n(DECODER_COND_DIM)]),
                    ],
                    vec![float("pose", vec![sym("N"), sym("T"), n(POSE_DIM)])],
                ),
            ),
            (
                "guidance",
                &g.guidance,
                contract(
                    &g.guidance,
                    vec![
                        float("x0", vec![sym("N"), n(w), n(d)]),
                        float("betas", vec![sym("N"), n(BETAS)]),
                        float("weights", vec![n(2)]),
                    ],
                    vec![float("latent_gradient", vec![sym("N"), n(w), n(lat)])],
                ),
            ),
        ]
    }
}

/// A guidance mode the model can run (§6.2).
pub(crate) fn check_mode(mode: &str, persons: usize) -> Result<(), String> {
    if matches!(mode, "clean" | "full" | "subset" | "partial") {
        return Ok(());
    }
    let person = mode.strip_prefix('~').unwrap_or(mode);
    match person
        .strip_prefix("person")
        .and_then(|i| i.parse::<usize>().ok())
    {
        Some(i) if i < persons => Ok(()),
        _ => Err(format!(
            "guidance mode `{mode}`: clean, full, subset, partial, person<i> or ~person<i> with \
             i < {persons}"
        )),
    }
}
