//! The loaded graphs of an `armflow` bundle and their typed calls: conditioning, the context
//! encoder (`context.rs`) over a batch of key/value caches, the MeanFlow velocity, and the VAE
//! as windows or as per-token steps with explicit convolution state.

use tract_onnx::prelude::TValue;

use super::context::ContextEncoder;
use super::kv_cache::KvCache;
use super::spec::ArmFlowSpec;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::BundleIo;
use crate::shared::checks::check_input;
use crate::shared::error::{Error, Result};
use crate::shared::graph::{
    f32_tensor, f32_tensor_owned, load_graphs, read_f32, split_rows, stack_rows, Graph, PlanPolicy,
};
use crate::shared::graph_spec::{Dim, GraphSpec};
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::{PromptEncoder, Prompts};
use crate::shared::text::ONE_ROW_ROLES;

/// An `armflow` bundle's graphs, loaded and optimised, with its own manifest section and the
/// common facts it needs. Shared (`Arc`) by the [`crate::Model`] handles that loaded it and by
/// every [`super::Session`] of them.
#[derive(Debug)]
pub(crate) struct Networks {
    pub io: BundleIo,
    pub spec: ArmFlowSpec,
    conditioning: Graph,
    /// The context encoder: its layer graphs, and the attention between them.
    pub context: ContextEncoder,
    velocity: Graph,
    vae_encoder: Graph,
    vae_decoder: Graph,
    /// Per-token VAE steps with explicit state, when the bundle has them.
    vae_steps: Option<(Graph, Graph)>,
    /// The official unmasked whole-prefix context call (clip mode), when present.
    pub context_full: Option<Graph>,
    /// The official text branch (CLIP token features -> condition), when present.
    text_branch: Option<Graph>,
    /// CLIP's text tower and the tokenizer, when the bundle takes prompts.
    text_encoder: Option<Graph>,
    prompts: Option<Prompts>,
}

/// The convolution state of a stream's VAE steps: every `state_i` of the encoder and decoder.
#[derive(Debug, Clone)]
pub(crate) struct VaeState {
    encoder: Vec<TValue>,
    decoder: Vec<TValue>,
}

impl VaeState {
    /// Bytes of convolution state held.
    pub(crate) fn bytes(&self) -> usize {
        self.encoder
            .iter()
            .chain(&self.decoder)
            .map(|t| t.len() * 4)
            .sum()
    }

    /// How many values of the encoder's (or decoder's) state are not finite, and of how many.
    pub(crate) fn non_finite(&self, encoder: bool) -> (usize, usize) {
        let tensors = if encoder {
            &self.encoder
        } else {
            &self.decoder
        };
        tensors.iter().fold((0, 0), |(bad, total), t| {
            let values = t
                .try_as_plain_ram()
                .and_then(|v| v.as_slice::<f32>())
                .unwrap_or(&[]);
            (
                // Exponent bits all set: infinite or NaN. Branch-free, so it vectorises.
                bad + values
                    .iter()
                    .map(|v| usize::from(v.to_bits() & 0x7f80_0000 == 0x7f80_0000))
                    .sum::<usize>(),
                total + values.len(),
            )
        })
    }
}

impl VaeState {
    /// Writes every state tensor's values (their shapes are the bundle's).
    pub(crate) fn save(&self, w: &mut SnapshotWriter) -> Result<()> {
        for t in self.encoder.iter().chain(&self.decoder) {
            let values = t
                .try_as_plain_ram()
                .and_then(|v| v.as_slice::<f32>())
                .map_err(|e| Error::Inference {
                    graph: "vae_encoder_step",
                    message: format!("a VAE state tensor cannot be read: {e}"),
                })?;
            w.f32s(values);
        }
        Ok(())
    }

    /// The state [`VaeState::save`] wrote, shaped as `zero` (the bundle's zero state): each
    /// tensor must hold exactly as many values as `zero`'s.
    pub(crate) fn load(zero: &VaeState, r: &mut SnapshotReader) -> Result<Self> {
        let read = |tensors: &[TValue], r: &mut SnapshotReader| -> Result<Vec<TValue>> {
            tensors
                .iter()
                .map(|t| {
                    let values = r.f32s_exact("a VAE state tensor", t.len())?;
                    Ok(f32_tensor_owned(t.shape(), values))
                })
                .collect()
        };
        Ok(VaeState {
            encoder: read(&zero.encoder, r)?,
            decoder: read(&zero.decoder, r)?,
        })
    }
}

/// Outputs of the conditioning graph: what stays constant while the condition does.
#[derive(Debug, Clone)]
pub(crate) struct Conditioning {
    /// AdaLN modulation of every context layer, `[1, layers, 6, width]`.
    pub modulation: TValue,
    /// The `<sos>` token, `[width]`.
    pub start_token: Vec<f32>,
    /// The caller's condition it was computed from (the null condition resolved), without the
    /// fed-back floats: what every token's conditioning starts from in a feedback bundle.
    pub condition: Vec<f32>,
}

impl Networks {
    /// Loads every graph `spec` names from `files`.
    pub(crate) fn load(files: &BundleFiles, io: BundleIo, spec: ArmFlowSpec) -> Result<Self> {
        let g = &spec.graphs;
        let mut wanted = vec![
            ("conditioning", &g.conditioning),
            ("velocity", &g.velocity),
            ("vae_encoder", &g.vae_encoder),
            ("vae_decoder", &g.vae_decoder),
        ];
        let steps = match (&g.vae_encoder_step, &g.vae_decoder_step) {
            (Some(e), Some(d)) => Some((e, d)),
            _ => None,
        };
        if let Some((e, d)) = steps {
            wanted.extend([("vae_encoder_step", e), ("vae_decoder_step", d)]);
        }
        let optional = [
            ("context_full", &g.context_full),
            ("text_branch", &g.text_branch),
            ("text_encoder", &g.text_encoder),
        ];
        wanted.extend(
            optional
                .iter()
                .filter_map(|(n, g)| g.as_ref().map(|g| (*n, g))),
        );
        // Graphs not every session runs are checked now and optimised on first use: the window
        // VAE when the bundle has per-token steps (only sessions that ask for windows, and
        // clips, run it), the official clip's context call, and the text tower (only a prompt
        // runs it).
        let mut deferred = vec!["context_full", "text_encoder", "text_branch"];
        if steps.is_some() {
            deferred.extend(["vae_encoder", "vae_decoder"]);
        }
        wanted.extend(
            g.context_layers
                .iter()
                .map(|layer| ("context_layers", layer)),
        );
        let mut graphs = load_graphs(files, &wanted, |role| PlanPolicy {
            deferred: deferred.contains(&role),
            one_row: ONE_ROW_ROLES.contains(&role),
        })?
        .into_iter();
        let mut next = || graphs.next().expect("one graph per wanted entry");
        Ok(Self {
            conditioning: next(),
            velocity: next(),
            vae_encoder: next(),
            vae_decoder: next(),
            vae_steps: steps.map(|_| (next(), next())),
            context_full: g.context_full.as_ref().map(|_| next()),
            text_branch: g.text_branch.as_ref().map(|_| next()),
            text_encoder: g.text_encoder.as_ref().map(|_| next()),
            context: ContextEncoder::new(
                spec.context.clone(),
                g.context_layers.iter().map(|_| next()).collect(),
            ),
            prompts: io
                .tokenizer
                .as_ref()
                .map(|t| Prompts::load(files, t))
                .transpose()?,
            io,
            spec,
        })
    }

    /// Floats per motion frame.
    pub(crate) fn frame_dim(&self) -> usize {
        self.io.frame_dim()
    }

    /// Floats per latent token.
    pub(crate) fn latent_dim(&self) -> usize {
        self.spec.latent.dim
    }

    /// The text branch, when the bundle has one: CLIP features as wide as the condition.
    pub(crate) fn text_branch(&self) -> Option<TextBranch<'_>> {
        self.text_branch.as_ref().map(|graph| TextBranch {
            graph,
            token_dim: self.io.condition.dim,
            condition_dim: self.io.condition.dim,
        })
    }

    /// The prompt encoder, when the bundle takes prompts.
    pub(crate) fn prompt_encoder(&self) -> Option<PromptEncoder<'_>> {
        PromptEncoder::assemble(
            self.prompts.as_ref(),
            self.text_encoder.as_ref(),
            self.text_branch(),
        )
    }

    /// Whether the bundle has per-token VAE steps (O(1) per token, no windows).
    pub(crate) fn has_vae_steps(&self) -> bool {
        self.vae_steps.is_some()
    }

    /// The context `c` the encoder gives after `[<sos>, pairs...]`, computed from scratch in
    /// one causal pass (no cache); see [`crate::Armflow::recompute_context`].
    pub(crate) fn recompute_context(
        &self,
        condition: Option<&[f32]>,
        pairs: &[f32],
    ) -> Result<Vec<f32>> {
        let width = self.spec.context.width;
        if !pairs.len().is_multiple_of(width) {
            return Err(Error::InvalidInput(format!(
                "history holds {} floats, not a multiple of the token width {width}",
                pairs.len()
            )));
        }
        check_input("history", pairs)?;
        if let Some(feedback) = &self.io.condition.feedback {
            return Err(Error::Unsupported(format!(
                "bundle `{}` feeds each token the reactor's placement (condition.feedback `{}`), \
                 which a bare history of pairs does not carry",
                self.io.name, feedback.kind
            )));
        }
        let cond = self.conditioning(condition)?;
        let mut tokens = cond.start_token.clone();
        tokens.extend_from_slice(pairs);
        let positions: Vec<i64> = (0..(tokens.len() / width) as i64).collect();
        let mut cache = KvCache::empty(&self.spec.context, positions.len());
        self.context
            .step(&mut [&mut cache], &tokens, &positions, &[&cond.modulation])
    }

    // ---- typed network calls ------------------------------------------------------------------

    /// Runs the conditioning graph; `None` is the null condition. A feedback bundle's fed-back
    /// floats are zeros: what its first token sees.
    pub(crate) fn conditioning(&self, condition: Option<&[f32]>) -> Result<Conditioning> {
        let dim = self.io.condition.dim;
        let condition = match condition {
            Some(c) => {
                if c.len() != dim {
                    return Err(Error::InvalidInput(format!(
                        "condition has {} floats, the bundle expects {dim}",
                        c.len()
                    )));
                }
                check_input("condition", c)?;
                c.to_vec()
            }
            None => self.io.condition.null_or_zeros(),
        };
        let fed = vec![0f32; self.io.condition.feedback_dim()];
        self.conditioning_fed(condition, &fed)
    }

    /// Runs the conditioning graph on the caller's `condition` (checked) followed by the
    /// fed-back floats `fed` (`condition.feedback.dim` of them).
    pub(crate) fn conditioning_fed(
        &self,
        condition: Vec<f32>,
        fed: &[f32],
    ) -> Result<Conditioning> {
        let a = &self.spec;
        debug_assert_eq!(fed.len(), self.io.condition.feedback_dim());
        let input = [condition.as_slice(), fed].concat();
        let out = self
            .conditioning
            .run(vec![f32_tensor(&[1, input.len()], &input)])?;
        let c = a.context.width;
        read_f32(
            "conditioning",
            "modulation",
            &out[0],
            &[1, a.context.layers, 6, c],
        )?;
        let start_token = read_f32("conditioning", "start_token", &out[1], &[1, 1, c])?.to_vec();
        Ok(Conditioning {
            modulation: out[0].clone(),
            start_token,
            condition,
        })
    }

    /// The average velocity `u(z, r, t | actor, context)` for a batch of rows, each with its own
    /// times `r[i] <= t[i]`.
    pub(crate) fn velocity(
        &self,
        actor: &[f32],
        noisy: &[f32],
        context: &[f32],
        r: &[f32],
        t: &[f32],
    ) -> Result<Vec<f32>> {
        let (lat, c) = (self.spec.latent.dim, self.spec.context.width);
        let b = r.len();
        let out = self.velocity.run(vec![
            f32_tensor(&[b, lat], actor),
            f32_tensor(&[b, lat], noisy),
            f32_tensor(&[b, c], context),
            f32_tensor(&[b], r),
            f32_tensor(&[b], t),
        ])?;
        Ok(read_f32("velocity", "velocity", &out[0], &[b, lat])?.to_vec())
    }

    /// Encodes `frames` (`[T, frame_dim]`, T a multiple of frames_per_token) into the posterior
    /// `(mean, logvar)` of its T / frames_per_token tokens.
    pub(crate) fn encode(&self, frames: &[f32]) -> Result<(Vec<f32>, Vec<f32>)> {
        let a = &self.spec;
        let d = self.frame_dim();
        let t = frames.len() / d;
        let n = t / a.latent.frames_per_token;
        let out = self.vae_encoder.run(vec![f32_tensor(&[1, t, d], frames)])?;
        let shape = [1, n, a.latent.dim];
        Ok((
            read_f32("vae_encoder", "mean", &out[0], &shape)?.to_vec(),
            read_f32("vae_encoder", "logvar", &out[1], &shape)?.to_vec(),
        ))
    }

    /// Decodes unscaled latents (`[N, latent_dim]`) into `[N * frames_per_token, frame_dim]`.
    pub(crate) fn decode(&self, latents: &[f32]) -> Result<Vec<f32>> {
        let a = &self.spec;
        let n = latents.len() / a.latent.dim;
        let out = self
            .vae_decoder
            .run(vec![f32_tensor(&[1, n, a.latent.dim], latents)])?;
        let shape = [1, n * a.latent.frames_per_token, self.frame_dim()];
        Ok(read_f32("vae_decoder", "motion", &out[0], &shape)?.to_vec())
    }

    /// The zero state a stream's VAE steps start from, or `None` without step graphs.
    pub(crate) fn vae_state(&self) -> Option<VaeState> {
        self.vae_steps.as_ref()?;
        let zeros = |graph: &Option<GraphSpec>| -> Vec<TValue> {
            graph
                .iter()
                .flat_map(|g| &g.inputs)
                .filter(|t| t.name.starts_with("state_"))
                .map(|t| {
                    let shape: Vec<usize> = t
                        .shape
                        .iter()
                        .map(|d| match d {
                            Dim::Fixed(n) => *n,
                            // one stream: the batch dim `B` is 1
                            Dim::Symbol(_) => 1,
                        })
                        .collect();
                    f32_tensor(&shape, &vec![0f32; shape.iter().product()])
                })
                .collect()
        };
        let g = &self.spec.graphs;
        Some(VaeState {
            encoder: zeros(&g.vae_encoder_step),
            decoder: zeros(&g.vae_decoder_step),
        })
    }

    /// One token of the encoder for a batch of streams: `frames` (`[B, frames_per_token,
    /// frame_dim]`) to the posteriors `(mean, logvar)` (`[B, latent_dim]` each), advancing each
    /// stream's `states[b]`.
    pub(crate) fn encode_step(
        &self,
        frames: &[f32],
        states: &mut [&mut VaeState],
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let (encoder, _) = self.vae_steps()?;
        let a = &self.spec;
        let (fpt, lat, b) = (a.latent.frames_per_token, a.latent.dim, states.len());
        let mut inputs = vec![f32_tensor(&[b, fpt, self.frame_dim()], frames)];
        inputs.extend(stack_states(states, |s| &s.encoder)?);
        let mut out = encoder.run(inputs)?;
        let mean = read_f32("vae_encoder_step", "mean", &out[0], &[b, 1, lat])?.to_vec();
        let logvar = read_f32("vae_encoder_step", "logvar", &out[1], &[b, 1, lat])?.to_vec();
        unstack_states(states, out.split_off(2), |s| &mut s.encoder)?;
        Ok((mean, logvar))
    }

    /// One token of the decoder for a batch of streams: unscaled latents (`[B, latent_dim]`) to
    /// their frames (`[B, frames_per_token, frame_dim]`), advancing each stream's `states[b]`.
    pub(crate) fn decode_step(
        &self,
        latents: &[f32],
        states: &mut [&mut VaeState],
    ) -> Result<Vec<f32>> {
        let (_, decoder) = self.vae_steps()?;
        let a = &self.spec;
        let (fpt, lat, b) = (a.latent.frames_per_token, a.latent.dim, states.len());
        let mut inputs = vec![f32_tensor(&[b, 1, lat], latents)];
        inputs.extend(stack_states(states, |s| &s.decoder)?);
        let mut out = decoder.run(inputs)?;
        let frames = read_f32(
            "vae_decoder_step",
            "motion",
            &out[0],
            &[b, fpt, self.frame_dim()],
        )?
        .to_vec();
        unstack_states(states, out.split_off(1), |s| &mut s.decoder)?;
        Ok(frames)
    }

    fn vae_steps(&self) -> Result<&(Graph, Graph)> {
        self.vae_steps
            .as_ref()
            .ok_or_else(|| Error::InvalidInput("the bundle has no VAE step graphs".into()))
    }
}

/// Each state input of a VAE step, stacked over the streams of a batch.
fn stack_states(
    states: &[&mut VaeState],
    part: impl Fn(&VaeState) -> &Vec<TValue>,
) -> Result<Vec<TValue>> {
    let count = states.first().map_or(0, |s| part(s).len());
    (0..count)
        .map(|i| {
            let rows: Vec<&TValue> = states.iter().map(|s| &part(s)[i]).collect();
            stack_rows("vae_step", &rows)
        })
        .collect()
}

/// The inverse of [`stack_states`]: gives each stream its row of every `next_state_i`.
fn unstack_states(
    states: &mut [&mut VaeState],
    next: Vec<TValue>,
    part: impl Fn(&mut VaeState) -> &mut Vec<TValue>,
) -> Result<()> {
    let b = states.len();
    for (i, batch) in next.into_iter().enumerate() {
        for (state, row) in states.iter_mut().zip(split_rows("vae_step", batch, b)?) {
            part(state)[i] = row;
        }
    }
    Ok(())
}
