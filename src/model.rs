//! [`Model`]: a loaded bundle. Immutable once loaded, cheap to clone, shared by any number of
//! sessions on any number of threads.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use tract_onnx::prelude::{TValue, Tensor};

use crate::bundle::BundleFiles;
use crate::error::{Error, Result};
use crate::graph::{f32_tensor, read_f32, split_rows, stack_rows, Graph};
use crate::kv_cache::KvCache;
use crate::manifest::{ArmFlowSpec, Family, GraphSpec, Manifest, UmfSpec};
use crate::session::{Session, SessionOptions};

/// A loaded bundle: manifest plus optimised graphs. An `armflow` model streams reactions
/// through [`Session`]s; a `umf` model generates groups with [`Model::generate_group`].
///
/// `Model` is `Send + Sync`; clones share the same graphs. A [`Session`] keeps its model alive.
#[derive(Debug, Clone)]
pub struct Model {
    inner: Arc<Inner>,
}

#[derive(Debug)]
struct Inner {
    source: PathBuf,
    manifest: Manifest,
    networks: Networks,
}

/// The optimised graphs, by family.
#[derive(Debug)]
enum Networks {
    ArmFlow(Box<ArmFlowNetworks>),
    Umf(Box<UmfNetworks>),
}

#[derive(Debug)]
pub(crate) struct ArmFlowNetworks {
    conditioning: Graph,
    context_step: Graph,
    velocity: Graph,
    vae_encoder: Graph,
    vae_decoder: Graph,
    /// Per-token VAE steps with explicit state, when the bundle has them.
    vae_steps: Option<(Graph, Graph)>,
    /// The official unmasked whole-prefix context call (clip mode), when present.
    pub(crate) context_full: Option<Graph>,
    /// The official text branch (CLIP token features -> condition), when present.
    pub(crate) text_branch: Option<Graph>,
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
}

/// The graphs of a `umf` bundle (used by [`crate::group`]).
#[derive(Debug)]
pub(crate) struct UmfNetworks {
    pub prior: Graph,
    pub reaction: Graph,
    pub context: Graph,
    pub decoder: Graph,
    pub text_branch: Option<Graph>,
}

/// Outputs of the conditioning graph: what stays constant while the condition does.
#[derive(Debug, Clone)]
pub(crate) struct Conditioning {
    /// AdaLN modulation of every context layer, `[1, layers, 6, width]`.
    pub modulation: TValue,
    /// The `<sos>` token, `[width]`.
    pub start_token: Vec<f32>,
}

impl Model {
    /// Loads the bundle at `path`: a directory, or an uncompressed tar archive of one. Reads and
    /// validates `troupe.json`, then loads, checks and optimises every graph it names. Errors
    /// name the file, tensor and shape at fault.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        Self::from_files(BundleFiles::open(path)?, path)
    }

    /// Loads a bundle from an uncompressed tar archive held in memory (the bytes are copied, not
    /// kept). `label` names the archive in error messages.
    pub fn from_archive_bytes(bytes: &[u8], label: &str) -> Result<Self> {
        let label = Path::new(label);
        Self::from_files(BundleFiles::from_archive(bytes, label)?, label)
    }

    fn from_files(files: BundleFiles, source: &Path) -> Result<Self> {
        let manifest = Manifest::load(&files)?;
        let networks = match &manifest.family {
            Family::Armflow(spec) => {
                let g = &spec.graphs;
                let mut wanted = vec![
                    ("conditioning", &g.conditioning),
                    ("context_step", &g.context_step),
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
                ];
                wanted.extend(
                    optional
                        .iter()
                        .filter_map(|(n, g)| g.as_ref().map(|g| (*n, g))),
                );
                let mut graphs = load_graphs(&files, &wanted)?.into_iter();
                let mut next = || graphs.next().expect("one graph per wanted entry");
                Networks::ArmFlow(Box::new(ArmFlowNetworks {
                    conditioning: next(),
                    context_step: next(),
                    velocity: next(),
                    vae_encoder: next(),
                    vae_decoder: next(),
                    vae_steps: steps.map(|_| (next(), next())),
                    context_full: g.context_full.as_ref().map(|_| next()),
                    text_branch: g.text_branch.as_ref().map(|_| next()),
                }))
            }
            Family::Umf(spec) => {
                let g = &spec.graphs;
                let mut wanted = vec![
                    ("prior", &g.prior),
                    ("reaction", &g.reaction),
                    ("context", &g.context),
                    ("decoder", &g.decoder),
                ];
                wanted.extend(g.text_branch.as_ref().map(|t| ("text_branch", t)));
                let mut graphs = load_graphs(&files, &wanted)?.into_iter();
                let mut next = || graphs.next().expect("one graph per wanted entry");
                Networks::Umf(Box::new(UmfNetworks {
                    prior: next(),
                    reaction: next(),
                    context: next(),
                    decoder: next(),
                    text_branch: g.text_branch.as_ref().map(|_| next()),
                }))
            }
        };
        let inner = Inner {
            manifest,
            networks,
            source: source.to_path_buf(),
        };
        Ok(Self {
            inner: Arc::new(inner),
        })
    }

    /// Starts a stream. Options left unset take the bundle's defaults. Fails unless the bundle
    /// is an `armflow` model.
    pub fn session(&self, options: SessionOptions) -> Result<Session> {
        Session::new(self.clone(), options)
    }

    /// The bundle's manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.inner.manifest
    }

    /// The path (or archive label) the bundle was loaded from.
    pub fn source(&self) -> &Path {
        &self.inner.source
    }

    /// Floats per motion frame (262 for `interhuman262`).
    pub fn frame_dim(&self) -> usize {
        self.inner.manifest.motion.frame_dim
    }

    /// Frames per second of the motion.
    pub fn fps(&self) -> u32 {
        self.inner.manifest.motion.fps
    }

    /// Motion frames per latent token (4 for ARMFlow); 0 for a `umf` model, whose tokens are
    /// global queries rather than spans of frames.
    pub fn frames_per_token(&self) -> usize {
        self.armflow_spec().map_or(0, |a| a.latent.frames_per_token)
    }

    /// Floats per latent token of one person.
    pub fn latent_dim(&self) -> usize {
        match &self.inner.manifest.family {
            Family::Armflow(a) => a.latent.dim,
            Family::Umf(u) => u.latent.dim,
        }
    }

    /// Floats in the conditioning vector.
    pub fn condition_dim(&self) -> usize {
        self.inner.manifest.condition.dim
    }

    /// Algorithmic latency in frames: how many actor frames after frame `t` arrive before the
    /// reactor's frame `t` is returned, at worst. For a streaming VAE this is
    /// `frames_per_token - 1`: the first frame of a token waits for the token's last frame.
    /// 0 for a `umf` model, which does not stream.
    pub fn latency_frames(&self) -> usize {
        self.armflow_spec().map_or(0, |a| {
            let fpt = a.latent.frames_per_token;
            fpt - 1 + a.vae.encoder.lookahead_frames + fpt * a.vae.decoder.lookahead_tokens
        })
    }

    /// The most reactor frames one `step` with `n_actor_frames` new frames can return, whatever
    /// the session's state: `ceil(n / frames_per_token) * frames_per_token`. 0 for a `umf`
    /// model.
    pub fn max_output_frames(&self, n_actor_frames: usize) -> usize {
        match self.frames_per_token() {
            0 => 0,
            fpt => n_actor_frames.div_ceil(fpt).saturating_mul(fpt),
        }
    }

    /// The context `c` the encoder gives after `[<sos>, pairs...]`, computed from scratch in one
    /// causal pass (no cache). `pairs` holds `(actor || reactor)` tokens, row-major
    /// `[n, 2 * latent_dim]`; positions are `0..=n`. A session's cached stream gives the same
    /// context while its history fits in the context capacity.
    pub fn recompute_context(&self, condition: Option<&[f32]>, pairs: &[f32]) -> Result<Vec<f32>> {
        let width = self.armflow()?.0.context.width;
        if !pairs.len().is_multiple_of(width) {
            return Err(Error::InvalidInput(format!(
                "history holds {} floats, not a multiple of the token width {width}",
                pairs.len()
            )));
        }
        check_finite("history", pairs)?;
        let cond = self.conditioning(condition)?;
        let mut tokens = cond.start_token.clone();
        tokens.extend_from_slice(pairs);
        let positions: Vec<i64> = (0..(tokens.len() / width) as i64).collect();
        let mut cache = KvCache::empty(&self.armflow()?.0.context);
        self.context_step(&mut [&mut cache], &tokens, &positions, &[&cond.modulation])
    }

    /// Whether `other` is this model or a clone of it (the same loaded graphs).
    pub(crate) fn same_as(&self, other: &Model) -> bool {
        Arc::ptr_eq(&self.inner, &other.inner)
    }

    /// The `armflow` manifest fields, if this is an ARMFlow model.
    pub fn armflow_spec(&self) -> Option<&ArmFlowSpec> {
        match &self.inner.manifest.family {
            Family::Armflow(spec) => Some(spec),
            Family::Umf(_) => None,
        }
    }

    /// The `umf` manifest fields, if this is a UMF model.
    pub fn umf_spec(&self) -> Option<&UmfSpec> {
        match &self.inner.manifest.family {
            Family::Umf(spec) => Some(spec),
            Family::Armflow(_) => None,
        }
    }

    /// The error for using this bundle where another family is needed: `what` needs `needed`.
    pub(crate) fn wrong_family(&self, needed: &str, what: &str) -> Error {
        // As read aloud: "an armflow", "a umf".
        let article = if needed == "armflow" { "an" } else { "a" };
        Error::InvalidInput(format!(
            "bundle `{}` is a `{}` model; {what} needs {article} `{needed}` bundle",
            self.inner.manifest.name,
            self.inner.manifest.family_name()
        ))
    }

    /// The ARMFlow spec and graphs, or an error naming the family this bundle is.
    /// The bundle's text branch and the width of the CLIP token features it reads; an error
    /// naming the bundle when it has none.
    pub(crate) fn text_branch(&self) -> Result<(&Graph, usize)> {
        let found = match (&self.inner.manifest.family, &self.inner.networks) {
            (Family::Armflow(_), Networks::ArmFlow(n)) => {
                n.text_branch.as_ref().map(|g| (g, self.condition_dim()))
            }
            (Family::Umf(spec), Networks::Umf(n)) => {
                n.text_branch.as_ref().map(|g| (g, spec.text.prior_dim))
            }
            _ => None,
        };
        found.ok_or_else(|| {
            Error::InvalidInput(format!(
                "bundle `{}` has no text_branch graph",
                self.manifest().name
            ))
        })
    }

    pub(crate) fn armflow(&self) -> Result<(&ArmFlowSpec, &ArmFlowNetworks)> {
        match (&self.inner.manifest.family, &self.inner.networks) {
            (Family::Armflow(spec), Networks::ArmFlow(nets)) => Ok((spec, nets)),
            _ => Err(self.wrong_family("armflow", "streaming")),
        }
    }

    /// The UMF spec and graphs, or an error naming the family this bundle is.
    pub(crate) fn umf(&self) -> Result<(&UmfSpec, &UmfNetworks)> {
        match (&self.inner.manifest.family, &self.inner.networks) {
            (Family::Umf(spec), Networks::Umf(nets)) => Ok((spec, nets)),
            _ => Err(self.wrong_family("umf", "group generation")),
        }
    }

    // ---- typed network calls, used by sessions ------------------------------------------------

    /// Runs the conditioning graph; `None` is the null condition (all zeros).
    pub(crate) fn conditioning(&self, condition: Option<&[f32]>) -> Result<Conditioning> {
        let (a, nets) = self.armflow()?;
        let dim = self.inner.manifest.condition.dim;
        let zeros;
        let condition = match condition {
            Some(c) => {
                if c.len() != dim {
                    return Err(Error::InvalidInput(format!(
                        "condition has {} floats, the bundle expects {dim}",
                        c.len()
                    )));
                }
                check_finite("condition", c)?;
                c
            }
            None => {
                zeros = self.null_condition();
                &zeros
            }
        };
        let out = nets
            .conditioning
            .run(vec![f32_tensor(&[1, dim], condition)])?;
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
        })
    }

    /// One context-encoder call for a batch of streams. Row `b` appends its tokens (`S` tokens
    /// of `width` floats at `positions[b * S..]`) to `caches[b]`, under `modulations[b]`
    /// (`[1, layers, 6, width]`). More than one stream needs `S = 1`. Returns the contexts at
    /// the last position, `[B, width]` row-major.
    pub(crate) fn context_step(
        &self,
        caches: &mut [&mut KvCache],
        tokens: &[f32],
        positions: &[i64],
        modulations: &[&TValue],
    ) -> Result<Vec<f32>> {
        let (a, nets) = self.armflow()?;
        let (c, b) = (a.context.width, caches.len());
        let s = positions.len() / b.max(1);
        let views: Vec<&KvCache> = caches.iter().map(|k| &**k).collect();
        let (past, key_mask) = KvCache::batch_inputs(&views)?;
        let padded = key_mask.shape()[1];
        let mut inputs = vec![
            f32_tensor(&[b, s, c], tokens),
            Tensor::from_shape(&[b, s], positions)
                .expect("shape matches data")
                .into(),
            stack_rows("context_step", modulations)?,
            key_mask,
        ];
        inputs.extend(past);
        let mut out = nets.context_step.run(inputs)?;
        let context = read_f32("context_step", "context", &out[0], &[b, c])?.to_vec();
        let present = out.split_off(1);
        if let [cache] = caches {
            cache.replace(present, s)?;
        } else {
            for (row, cache) in caches.iter_mut().enumerate() {
                cache.take_row(&present, row, padded)?;
            }
        }
        Ok(context)
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
        let (a, nets) = self.armflow()?;
        let (lat, c) = (a.latent.dim, a.context.width);
        let b = r.len();
        let out = nets.velocity.run(vec![
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
        let (a, nets) = self.armflow()?;
        let d = self.frame_dim();
        let t = frames.len() / d;
        let n = t / a.latent.frames_per_token;
        let out = nets.vae_encoder.run(vec![f32_tensor(&[1, t, d], frames)])?;
        let shape = [1, n, a.latent.dim];
        Ok((
            read_f32("vae_encoder", "mean", &out[0], &shape)?.to_vec(),
            read_f32("vae_encoder", "logvar", &out[1], &shape)?.to_vec(),
        ))
    }

    /// Decodes unscaled latents (`[N, latent_dim]`) into `[N * frames_per_token, frame_dim]`.
    pub(crate) fn decode(&self, latents: &[f32]) -> Result<Vec<f32>> {
        let (a, nets) = self.armflow()?;
        let n = latents.len() / a.latent.dim;
        let out = nets
            .vae_decoder
            .run(vec![f32_tensor(&[1, n, a.latent.dim], latents)])?;
        let shape = [1, n * a.latent.frames_per_token, self.frame_dim()];
        Ok(read_f32("vae_decoder", "motion", &out[0], &shape)?.to_vec())
    }
}

impl Model {
    /// The condition that stands for "none": the bundle's `condition.null`, or zeros.
    pub fn null_condition(&self) -> Vec<f32> {
        let c = &self.inner.manifest.condition;
        c.null.clone().unwrap_or_else(|| vec![0f32; c.dim])
    }
}

impl Model {
    /// Whether the bundle has per-token VAE steps (O(1) per token, no windows).
    pub fn has_vae_steps(&self) -> bool {
        self.armflow()
            .is_ok_and(|(_, nets)| nets.vae_steps.is_some())
    }

    /// The zero state a stream's VAE steps start from, or `None` without step graphs.
    pub(crate) fn vae_state(&self) -> Result<Option<VaeState>> {
        let (spec, nets) = self.armflow()?;
        if nets.vae_steps.is_none() {
            return Ok(None);
        }
        let zeros = |graph: &Option<crate::manifest::GraphSpec>| -> Vec<TValue> {
            graph
                .iter()
                .flat_map(|g| &g.inputs)
                .filter(|t| t.name.starts_with("state_"))
                .map(|t| {
                    let shape: Vec<usize> = t
                        .shape
                        .iter()
                        .map(|d| match d {
                            crate::manifest::Dim::Fixed(n) => *n,
                            // one stream: the batch dim `B` is 1
                            crate::manifest::Dim::Symbol(_) => 1,
                        })
                        .collect();
                    f32_tensor(&shape, &vec![0f32; shape.iter().product()])
                })
                .collect()
        };
        let g = &spec.graphs;
        Ok(Some(VaeState {
            encoder: zeros(&g.vae_encoder_step),
            decoder: zeros(&g.vae_decoder_step),
        }))
    }

    /// One token of the encoder for a batch of streams: `frames` (`[B, frames_per_token,
    /// frame_dim]`) to the posteriors `(mean, logvar)` (`[B, latent_dim]` each), advancing each
    /// stream's `states[b]`.
    pub(crate) fn encode_step(
        &self,
        frames: &[f32],
        states: &mut [&mut VaeState],
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let (a, nets) = self.armflow()?;
        let (encoder, _) = vae_steps(nets)?;
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
        let (a, nets) = self.armflow()?;
        let (_, decoder) = vae_steps(nets)?;
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
}

/// Loads and optimises `wanted` graphs on all cores (optimisation dominates load time and each
/// graph is independent); returns them in order, or the first error in that order.
fn load_graphs(files: &BundleFiles, wanted: &[(&'static str, &GraphSpec)]) -> Result<Vec<Graph>> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(wanted.len());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut slots: Vec<Option<Result<Graph>>> = (0..wanted.len()).map(|_| None).collect();
    let done = std::sync::Mutex::new(&mut slots);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&(role, spec)) = wanted.get(i) else {
                    break;
                };
                let graph = Graph::load(role, files, spec);
                done.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(graph);
            });
        }
    });
    slots
        .into_iter()
        .map(|slot| slot.expect("every graph was attempted"))
        .collect()
}

fn vae_steps(nets: &ArmFlowNetworks) -> Result<&(Graph, Graph)> {
    nets.vae_steps
        .as_ref()
        .ok_or_else(|| Error::InvalidInput("the bundle has no VAE step graphs".into()))
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

/// Rejects NaN and infinities, naming the first offending index.
pub(crate) fn check_finite(what: &str, values: &[f32]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::InvalidInput(format!(
            "{what} holds a non-finite value ({}) at index {i}",
            values[i]
        ))),
    }
}
