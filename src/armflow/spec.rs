//! The `armflow` family's manifest fields: streaming VAE windows, the causal context encoder
//! and the MeanFlow sampler defaults.

use serde::{Deserialize, Serialize};

use crate::shared::bundle_io::{ConditionSpec, MotionSpec};
use crate::shared::checks::ensure;
use crate::shared::graph_spec::{contract, float, sym, DType, Dim, GraphSpec, TensorSpec};
use crate::shared::limits::{check_cfg, check_steps, product_at_most, LIMITS};
use crate::shared::text::branch::text_branch_contract;

/// The manifest fields of an `armflow` bundle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ArmFlowSpec {
    /// Latent tokens of the VAE.
    pub latent: LatentSpec,
    /// Causal context encoder.
    pub context: ContextSpec,
    /// Streaming properties of the VAE.
    pub vae: VaeSpec,
    /// Default sampler settings (sessions may override them).
    pub sampler: SamplerSpec,
    /// The official clip length, for bundles that run the official clip loop
    /// ([`crate::Armflow::generate_clip`]); absent for streaming-only bundles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clip: Option<ClipSpec>,
    /// The ONNX graphs of the bundle.
    pub graphs: ArmFlowGraphs,
}

/// The fixed clip of the official sampler: actor clips are zero-padded to `frames`, which
/// the VAE encodes to `tokens` tokens.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ClipSpec {
    /// Frames of a padded clip (300 for InterHuman, 150 for InterX).
    pub frames: usize,
    /// Tokens the encoder makes of them (75 and 37: the stride-2 convolutions floor odd
    /// lengths, and the decoder's `4 * tokens` frames are padded to `frames` by repeating the
    /// last frame).
    pub tokens: usize,
}

/// Latent tokens.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LatentSpec {
    /// Floats per token (per person).
    pub dim: usize,
    /// Multiplied into encoder outputs, divided out before decoding.
    pub scale: f32,
    /// Motion frames per latent token.
    pub frames_per_token: usize,
}

/// Causal context encoder.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ContextSpec {
    /// Model width: `2 * latent.dim` (actor || reactor).
    pub width: usize,
    /// Transformer layers (each has its own key/value cache).
    pub layers: usize,
    /// Attention heads.
    pub heads: usize,
    /// Width of one head; `heads * head_dim == width`.
    pub head_dim: usize,
    /// Default number of tokens (`<sos>` included) kept in the key/value cache.
    pub capacity_tokens: usize,
}

/// Streaming properties of the VAE.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct VaeSpec {
    /// True when the VAE is causal, so that windowed calls equal one pass over the stream.
    pub streaming: bool,
    /// Encoder window.
    pub encoder: EncoderWindow,
    /// Decoder window.
    pub decoder: DecoderWindow,
}

/// Frames the encoder reads around the frames of one token.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EncoderWindow {
    /// Frames before the token's first frame (a multiple of `frames_per_token`).
    pub context_frames: usize,
    /// Frames after the token's last frame.
    pub lookahead_frames: usize,
}

/// Tokens the decoder reads around one token.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DecoderWindow {
    /// Tokens before the decoded token.
    pub context_tokens: usize,
    /// Tokens after the decoded token.
    pub lookahead_tokens: usize,
}

/// How the actor's latent token is taken from the encoder's posterior.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActorLatent {
    /// `(mean + sqrt(exp(logvar)) * xi) * scale`, as the official sampler does.
    Sample,
    /// `mean * scale`: deterministic, no noise drawn.
    Mean,
}

/// Default sampler settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SamplerSpec {
    /// MeanFlow steps per token (1: one network call).
    pub steps: u32,
    /// Classifier-free guidance scale (1: off).
    pub cfg_scale: f32,
    /// Posterior sample or mean for actor tokens.
    pub actor_latent: ActorLatent,
}

/// The graphs of an `armflow` bundle, by role.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ArmFlowGraphs {
    /// condition -> AdaLN modulation of every layer, and `<sos>`; run when the condition changes.
    pub conditioning: GraphSpec,
    /// The context encoder's dense work as `layers + 1` graphs over token rows: graph 0 adds
    /// the positions and starts block 0 (`next_x`, `query`, `key`, `value`); graph `i` finishes
    /// block `i - 1` from its attention output and starts block `i` (an out layer first fuses
    /// the skip it pops); the last finishes the last block (`context`). The runtime runs each
    /// block's attention between them, over the key/value cache it owns.
    #[serde(default)]
    pub context_layers: Vec<GraphSpec>,
    /// The one-graph context encoder of bundles exported before the runtime ran attention: not
    /// run, only recognised, to refuse such a bundle with the command that re-exports it.
    #[doc(hidden)]
    #[serde(default, rename = "context_step", skip_serializing)]
    pub legacy_context_step: Option<serde::de::IgnoredAny>,
    /// Average-velocity MLP.
    pub velocity: GraphSpec,
    /// VAE encoder over a window of frames.
    pub vae_encoder: GraphSpec,
    /// VAE decoder over a window of tokens.
    pub vae_decoder: GraphSpec,
    /// The encoder's per-token step with explicit convolution state (`state_i` in,
    /// `next_state_i` out), for a causal VAE: O(1) per token instead of a window. Optional;
    /// given together with `vae_decoder_step`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vae_encoder_step: Option<GraphSpec>,
    /// The decoder's per-token step with explicit convolution state.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vae_decoder_step: Option<GraphSpec>,
    /// The official context call: the whole prefix `[<sos>, pairs...]` with no attention mask
    /// and no cache, giving the context at the last position. Required with `clip`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub context_full: Option<GraphSpec>,
    /// The official trainable text branch: CLIP token features and the end-of-text index to
    /// the condition vector. Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_branch: Option<GraphSpec>,
    /// CLIP's text tower: a prompt's token ids to the features the text branch reads (its
    /// width is the condition's). Optional; comes with the manifest's `tokenizer`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_encoder: Option<GraphSpec>,
}

impl ArmFlowSpec {
    /// Algorithmic latency in frames: how many actor frames after frame `t` arrive before the
    /// reactor's frame `t` is out, at worst (`frames_per_token - 1` for a streaming VAE: a
    /// token's first frame waits for its last).
    pub fn latency_frames(&self) -> usize {
        let fpt = self.latent.frames_per_token;
        fpt - 1 + self.vae.encoder.lookahead_frames + fpt * self.vae.decoder.lookahead_tokens
    }

    /// What `condition.feedback` (the reactor's placement, read from its decoded frames before
    /// every token) needs: joint positions where the runtime reads them, and each token decoded
    /// before the next is generated.
    pub(crate) fn validate_feedback(&self, motion: &MotionSpec) -> std::result::Result<(), String> {
        ensure(motion.layout == "interhuman262", || {
            format!(
                "condition.feedback reads t2m22 joint positions: motion.layout must be \
                 interhuman262, not `{}`",
                motion.layout
            )
        })?;
        ensure(self.vae.decoder.lookahead_tokens == 0, || {
            "condition.feedback needs a decoder without lookahead (each token decoded before \
             the next)"
                .into()
        })?;
        ensure(
            self.clip.is_none() && self.graphs.text_branch.is_none(),
            || {
                "condition.feedback is for streams: a bundle with it has no `clip` section and no \
             text branch"
                    .into()
            },
        )
    }

    pub(crate) fn validate(&self, frame_dim: usize) -> std::result::Result<(), String> {
        let check = |ok: bool, msg: &dyn Fn() -> String| ensure(ok, msg);
        let (l, c) = (&self.latent, &self.context);
        check(l.dim > 0 && l.frames_per_token > 0, &|| {
            "latent.dim and latent.frames_per_token must be positive".into()
        })?;
        // Latents are multiplied by the scale and decoded divided by it: far from 1 either way
        // (3.4e38, a denormal) every step overflows, so such a bundle is refused at load.
        check((1e-4..=1e4).contains(&l.scale), &|| {
            format!(
                "latent.scale must be in [1e-4, 1e4] (the official models use 0.1825), got {}",
                l.scale
            )
        })?;
        check(c.width == 2 * l.dim, &|| {
            format!(
                "context.width {} must be 2 * latent.dim = {}",
                c.width,
                2 * l.dim
            )
        })?;
        check(c.heads > 0 && c.heads * c.head_dim == c.width, &|| {
            format!(
                "context.heads {} * context.head_dim {} must equal context.width {}",
                c.heads, c.head_dim, c.width
            )
        })?;
        check(c.layers % 2 == 1, &|| {
            format!(
                "context.layers {} must be odd (in, mid, out layers)",
                c.layers
            )
        })?;
        let graphs = &self.graphs;
        check(
            !graphs.context_layers.is_empty() || graphs.legacy_context_step.is_none(),
            &|| {
                "the context encoder is one `context_step` graph, as exporters before troupe \
                 0.2 wrote it; troupe now runs attention itself between per-layer graphs: \
                 re-export the bundle with `python3 onnx/cli.py armflow export` (the same \
                 preset or --checkpoint; `demo export` for the demo model)"
                    .into()
            },
        )?;
        check(graphs.context_layers.len() == c.layers + 1, &|| {
            format!(
                "graphs.context_layers lists {} graphs, expected context.layers + 1 = {}",
                graphs.context_layers.len(),
                c.layers + 1
            )
        })?;
        check(c.capacity_tokens >= 2, &|| {
            "context.capacity_tokens must be at least 2 (<sos> and one token)".into()
        })?;
        check(
            self.vae
                .encoder
                .context_frames
                .is_multiple_of(l.frames_per_token),
            &|| {
                format!(
                    "vae.encoder.context_frames {} must be a multiple of latent.frames_per_token {}",
                    self.vae.encoder.context_frames, l.frames_per_token
                )
            },
        )?;
        let g = &self.graphs;
        check(
            g.vae_encoder_step.is_some() == g.vae_decoder_step.is_some(),
            &|| "graphs.vae_encoder_step and graphs.vae_decoder_step come together".into(),
        )?;
        check(
            g.vae_encoder_step.is_none()
                || (self.vae.streaming
                    && self.vae.encoder.lookahead_frames == 0
                    && self.vae.decoder.lookahead_tokens == 0),
            &|| "VAE step graphs need a streaming VAE without lookahead".into(),
        )?;
        if let Some(clip) = &self.clip {
            check(g.context_full.is_some(), &|| {
                "a bundle with `clip` needs graphs.context_full".into()
            })?;
            check(
                clip.tokens > 0 && clip.tokens * l.frames_per_token <= clip.frames,
                &|| {
                    format!(
                        "clip.tokens {} * latent.frames_per_token {} must be in 1..=clip.frames {}",
                        clip.tokens, l.frames_per_token, clip.frames
                    )
                },
            )?;
        }
        check_steps("sampler.steps", self.sampler.steps).map_err(|e| e.to_string())?;
        check_cfg(self.sampler.cfg_scale).map_err(|e| format!("sampler.cfg_scale: {e}"))?;
        // What the runtime allocates from these numbers alone, before a graph has produced
        // anything: bounded so that a manifest cannot make it abort.
        let most = LIMITS.max_tensor_elements;
        let (lat, fpt, d) = (l.dim as u64, l.frames_per_token as u64, frame_dim as u64);
        let mut sizes = vec![
            ("a token's frames", vec![fpt, d]),
            (
                "a token's keys and values",
                vec![2, c.layers as u64, c.width as u64],
            ),
            (
                "an encoder window",
                vec![
                    self.vae.encoder.context_frames as u64
                        + fpt
                        + self.vae.encoder.lookahead_frames as u64,
                    d,
                ],
            ),
            (
                "a decoder window",
                vec![
                    (self.vae.decoder.context_tokens + 1 + self.vae.decoder.lookahead_tokens)
                        as u64,
                    fpt,
                    d,
                ],
            ),
        ];
        if let Some(clip) = &self.clip {
            sizes.push(("a clip's frames", vec![clip.frames as u64, d]));
            sizes.push(("a clip's latents", vec![clip.tokens as u64, lat]));
            sizes.push((
                "a clip's contexts",
                vec![clip.tokens as u64 + 1, c.width as u64],
            ));
        }
        for (what, factors) in sizes {
            product_at_most(what, &factors, most)?;
        }
        Ok(())
    }

    /// Each graph as declared, next to the interface the runtime requires of it.
    pub(crate) fn graph_contract<'a>(
        &'a self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)> {
        let (c, lat, d) = (self.context.width, self.latent.dim, motion.frame_dim);
        let (f, n, s) = (float, Dim::Fixed, sym);
        let spec = contract;
        let g = &self.graphs;
        // The context layers take N token rows: the new tokens of every stream of a round.
        let rows = |names: &[&str]| -> Vec<TensorSpec> {
            names.iter().map(|m| f(m, vec![s("N"), n(c)])).collect()
        };
        let modulation = |name: &str| f(name, vec![n(6), s("N"), n(c)]);
        let layers = self.context.layers;
        let layer_contract = |i: usize| -> (Vec<TensorSpec>, Vec<TensorSpec>) {
            let starts = rows(&["next_x", "query", "key", "value"]);
            if i == 0 {
                let positions = TensorSpec {
                    name: "positions".into(),
                    dtype: DType::Int64,
                    shape: vec![s("N")],
                };
                let inputs = vec![
                    f("tokens", vec![s("N"), n(c)]),
                    positions,
                    modulation("modulation"),
                ];
                return (inputs, starts);
            }
            let mut inputs = rows(&["x", "attention"]);
            inputs.push(modulation("finish_modulation"));
            if i == layers {
                return (inputs, rows(&["context"]));
            }
            inputs.push(modulation("modulation"));
            if i > layers / 2 {
                inputs.extend(rows(&["skip"]));
            }
            (inputs, starts)
        };
        let mut contracts = vec![
            (
                "conditioning",
                &g.conditioning,
                spec(
                    &g.conditioning,
                    vec![f("condition", vec![n(1), n(condition.graph_dim())])],
                    vec![
                        f("modulation", vec![n(1), n(self.context.layers), n(6), n(c)]),
                        f("start_token", vec![n(1), n(1), n(c)]),
                    ],
                ),
            ),
            (
                "velocity",
                &g.velocity,
                spec(
                    &g.velocity,
                    vec![
                        f("actor", vec![s("B"), n(lat)]),
                        f("noisy", vec![s("B"), n(lat)]),
                        f("context", vec![s("B"), n(c)]),
                        f("r", vec![s("B")]),
                        f("t", vec![s("B")]),
                    ],
                    vec![f("velocity", vec![s("B"), n(lat)])],
                ),
            ),
            (
                "vae_encoder",
                &g.vae_encoder,
                spec(
                    &g.vae_encoder,
                    vec![f("motion", vec![n(1), s("T"), n(d)])],
                    vec![
                        f("mean", vec![n(1), s("N"), n(lat)]),
                        f("logvar", vec![n(1), s("N"), n(lat)]),
                    ],
                ),
            ),
            (
                "vae_decoder",
                &g.vae_decoder,
                spec(
                    &g.vae_decoder,
                    vec![f("latents", vec![n(1), s("N"), n(lat)])],
                    vec![f("motion", vec![n(1), s("T"), n(d)])],
                ),
            ),
        ];
        // After `conditioning`, where the graphs run.
        let layer_contracts = g.context_layers.iter().enumerate().map(|(i, declared)| {
            let (inputs, outputs) = layer_contract(i);
            ("context_layers", declared, spec(declared, inputs, outputs))
        });
        contracts.splice(1..1, layer_contracts);
        if let Some(full) = &g.context_full {
            contracts.push((
                "context_full",
                full,
                spec(
                    full,
                    vec![
                        f("tokens", vec![s("B"), s("S"), n(c)]),
                        f(
                            "modulation",
                            vec![s("B"), n(self.context.layers), n(6), n(c)],
                        ),
                    ],
                    vec![f("context", vec![s("B"), n(c)])],
                ),
            ));
        }
        if let Some(text) = &g.text_branch {
            let cond = condition.dim;
            contracts.push(("text_branch", text, text_branch_contract(text, cond, cond)));
        }
        let fpt = self.latent.frames_per_token;
        if let Some(step) = &g.vae_encoder_step {
            contracts.push((
                "vae_encoder_step",
                step,
                stateful(
                    step,
                    f("motion", vec![s("B"), n(fpt), n(d)]),
                    vec![
                        f("mean", vec![s("B"), n(1), n(lat)]),
                        f("logvar", vec![s("B"), n(1), n(lat)]),
                    ],
                ),
            ));
        }
        if let Some(step) = &g.vae_decoder_step {
            contracts.push((
                "vae_decoder_step",
                step,
                stateful(
                    step,
                    f("latents", vec![s("B"), n(1), n(lat)]),
                    vec![f("motion", vec![s("B"), n(fpt), n(d)])],
                ),
            ));
        }
        contracts
    }
}

/// The interface of a per-token VAE step: `input` then the declared `state_i` inputs (each
/// `[B, frames, channels]`, one row per stream; any two fixed sizes after `B` are accepted, as
/// bundles written channels-first hold `[B, channels, frames]` and run the same), `outputs` then
/// a `next_state_i` of the same shape for each.
fn stateful(declared: &GraphSpec, input: TensorSpec, outputs: Vec<TensorSpec>) -> GraphSpec {
    let states: Vec<TensorSpec> = declared
        .inputs
        .iter()
        .filter(|t| t.name.starts_with("state_"))
        .map(|t| {
            let shape = match t.shape.as_slice() {
                [_, first @ Dim::Fixed(_), second @ Dim::Fixed(_)] => {
                    vec![sym("B"), first.clone(), second.clone()]
                }
                // A state of any other shape is reported against the required `[B, k, C]` form.
                _ => vec![sym("B"), sym("k"), sym("C")],
            };
            float(&t.name, shape)
        })
        .collect();
    let next = states
        .iter()
        .map(|t| float(&format!("next_{}", t.name), t.shape.clone()));
    contract(
        declared,
        [vec![input], states.clone()].concat(),
        outputs.into_iter().chain(next).collect(),
    )
}
