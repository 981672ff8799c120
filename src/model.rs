//! [`Model`]: a loaded bundle, above the families. It reads the manifest, loads the family's
//! networks, answers the questions every caller asks whatever the family (frame size, latency,
//! dimensions), and hands each family-specific call to the family it belongs to, or says which
//! family the bundle is when it does not. Immutable once loaded, cheap to clone, shared by any
//! number of sessions on any number of threads.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use ndarray::ArrayView2;

use crate::arflow::stream::ArflowStream;
use crate::arflow::{self, ArflowOptions};
use crate::armflow::{self, Clip, ClipOptions};
use crate::magnet::live::LiveSession;
use crate::magnet::{self, MagnetOptions, MagnetOutput};
use crate::manifest::{
    ArmFlowSpec, ClipSpec, ConditionLabel, Family, MagnetSpec, Manifest, UmfSpec,
};
use crate::session::{Session, SessionOptions};
use crate::shared::bundle::BundleFiles;
use crate::shared::error::{Error, Result};
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::{no_prompts, PromptEncoder};
use crate::umf::{self, Group, GroupNoise, GroupNoiseShape, GroupOptions};

/// A loaded bundle: manifest plus optimised graphs. An `armflow` model streams reactions
/// through [`Session`]s; a `umf` model generates groups with [`Model::generate_group`].
///
/// `Model` is `Send + Sync`; clones share the same graphs. A [`Session`] keeps the graphs alive.
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

/// The loaded networks of the bundle's family. Each is shared (`Arc`) with what runs it: an
/// ARMFlow session holds its model's networks, not the model.
#[derive(Debug)]
enum Networks {
    ArmFlow(Arc<armflow::Networks>),
    Umf(Arc<umf::Networks>),
    Magnet(Arc<magnet::Networks>),
    Arflow(Arc<arflow::Networks>),
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
        let io = manifest.bundle_io();
        let networks = match &manifest.family {
            Family::Armflow(spec) => Networks::ArmFlow(Arc::new(armflow::Networks::load(
                &files,
                io,
                (**spec).clone(),
            )?)),
            Family::Umf(spec) => {
                Networks::Umf(Arc::new(umf::Networks::load(&files, io, (**spec).clone())?))
            }
            Family::Magnet(spec) => Networks::Magnet(Arc::new(magnet::Networks::load(
                &files,
                io,
                (**spec).clone(),
            )?)),
            Family::Arflow(spec) => Networks::Arflow(Arc::new(arflow::Networks::load(
                &files,
                io,
                (**spec).clone(),
            )?)),
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

    // ---- what every bundle answers --------------------------------------------------------------

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

    /// Motion frames per latent token (4 for ARMFlow and MAGNet); 0 for a `umf` model, whose
    /// tokens are global queries rather than spans of frames, and an `arflow` model, which has
    /// no latent tokens.
    pub fn frames_per_token(&self) -> usize {
        match &self.inner.manifest.family {
            Family::Armflow(a) => a.latent.frames_per_token,
            Family::Umf(_) | Family::Arflow(_) => 0,
            Family::Magnet(_) => crate::magnet::layout::FRAMES_PER_TOKEN,
        }
    }

    /// Floats per latent token of one person.
    pub fn latent_dim(&self) -> usize {
        match &self.inner.manifest.family {
            Family::Armflow(a) => a.latent.dim,
            Family::Umf(u) => u.latent.dim,
            Family::Magnet(m) => m.model.token_dim,
            Family::Arflow(a) => a.model.dim,
        }
    }

    /// Floats in the conditioning vector.
    pub fn condition_dim(&self) -> usize {
        self.inner.manifest.condition.dim
    }

    /// The condition that stands for "none": the bundle's `condition.null`, or zeros.
    pub fn null_condition(&self) -> Vec<f32> {
        self.inner.manifest.condition.null_or_zeros()
    }

    /// The named conditions the bundle was trained on (empty for most bundles): the demo
    /// model's partner rules `mirror`, `follow`, `keep-away`.
    pub fn condition_labels(&self) -> &[ConditionLabel] {
        &self.inner.manifest.condition.labels
    }

    /// The conditioning vector of the label `name`; an [`Error::InvalidInput`] naming the labels
    /// the bundle has when it has no such label.
    pub fn condition_for(&self, name: &str) -> Result<Vec<f32>> {
        let condition = &self.inner.manifest.condition;
        condition
            .labelled(name)
            .map(<[f32]>::to_vec)
            .ok_or_else(|| {
                let known: Vec<&str> = condition.labels.iter().map(|l| l.name.as_str()).collect();
                Error::InvalidInput(if known.is_empty() {
                    format!(
                        "no condition `{name}`: bundle `{}` has no named conditions",
                        self.inner.manifest.name
                    )
                } else {
                    format!(
                        "no condition `{name}`; bundle `{}` has: {}",
                        self.inner.manifest.name,
                        known.join(", ")
                    )
                })
            })
    }

    /// Algorithmic latency in frames: how many actor frames after frame `t` arrive before the
    /// reactor's frame `t` is returned, at worst. For a streaming VAE this is
    /// `frames_per_token - 1`: the first frame of a token waits for the token's last frame.
    /// For a `magnet` model, the live partner's with the default (final) emission: a window of
    /// user frames, `4 Tm - 1` (a session's own [`Session::latency_frames`] follows its
    /// options). 0 for a `umf` model, which does not stream.
    ///
    /// Actor *joint positions* add [`crate::motion::STREAM_LATENCY_FRAMES`] (one frame, for the
    /// velocities): see [`Model::joints_latency_frames`].
    pub fn latency_frames(&self) -> usize {
        match &self.inner.manifest.family {
            Family::Armflow(a) => a.latency_frames(),
            Family::Umf(_) | Family::Arflow(_) => 0,
            Family::Magnet(m) => m.model.window * crate::magnet::layout::FRAMES_PER_TOKEN - 1,
        }
    }

    /// Latency in frames when the actor streams joint positions ([`Session::step_joints`]):
    /// [`Model::latency_frames`] plus the frame that velocities and contacts wait for. 0 for a
    /// `umf` model.
    pub fn joints_latency_frames(&self) -> usize {
        self.armflow_spec().map_or(0, |a| {
            a.latency_frames() + crate::motion::STREAM_LATENCY_FRAMES
        })
    }

    /// The most frames one `step` with `n_actor_frames` new frames can return, whatever the
    /// session's state: `ceil(n / frames_per_token) * frames_per_token` for ARMFlow; for a
    /// MAGNet live partner `n` plus the frames a stream may hold back, under one window
    /// (`4 Tm`); `n` for an ARFlow stream (a frame out for each frame in). 0 for a `umf` model.
    pub fn max_output_frames(&self, n_actor_frames: usize) -> usize {
        match &self.inner.manifest.family {
            Family::Magnet(m) => n_actor_frames
                .saturating_add(m.model.window * crate::magnet::layout::FRAMES_PER_TOKEN),
            Family::Arflow(_) => n_actor_frames,
            _ => match self.frames_per_token() {
                0 => 0,
                fpt => n_actor_frames.div_ceil(fpt).saturating_mul(fpt),
            },
        }
    }

    /// Frames of motion per clip: per person of [`Model::generate_group`] for a `umf` bundle,
    /// of [`Model::generate_clip`] for an `armflow` bundle with a `clip` section; 0 otherwise.
    pub fn clip_frames(&self) -> usize {
        match (self.umf_spec(), self.clip_spec()) {
            (Some(u), _) => u.clip_frames,
            (None, Some(c)) => c.frames,
            (None, None) => 0,
        }
    }

    /// The `armflow` manifest fields, if this is an ARMFlow model.
    pub fn armflow_spec(&self) -> Option<&ArmFlowSpec> {
        match &self.inner.manifest.family {
            Family::Armflow(spec) => Some(spec),
            Family::Umf(_) | Family::Magnet(_) | Family::Arflow(_) => None,
        }
    }

    /// The `umf` manifest fields, if this is a UMF model.
    pub fn umf_spec(&self) -> Option<&UmfSpec> {
        match &self.inner.manifest.family {
            Family::Umf(spec) => Some(spec),
            Family::Armflow(_) | Family::Magnet(_) | Family::Arflow(_) => None,
        }
    }

    /// The `magnet` manifest fields, if this is a MAGNet model.
    pub fn magnet_spec(&self) -> Option<&MagnetSpec> {
        match &self.inner.manifest.family {
            Family::Magnet(spec) => Some(spec),
            Family::Armflow(_) | Family::Umf(_) | Family::Arflow(_) => None,
        }
    }

    /// The `arflow` manifest fields, if this is an ARFlow model.
    pub fn arflow_spec(&self) -> Option<&crate::manifest::ArflowSpec> {
        match &self.inner.manifest.family {
            Family::Arflow(spec) => Some(spec),
            _ => None,
        }
    }

    /// ARFlow's offline generation: the reactor's `interhuman262` features `[T, 262]` for the
    /// actor's `actor` `[T, 262]` (1 to `model.max_frames` frames, one world frame for both),
    /// with the bundle's sampler settings changed by `options` (guidance strength λ, weight w,
    /// η, d_safe, ...; `docs/ARFLOW.md`). With the online variant's causal network, frame `n` of
    /// the result depends only on the actor's frames up to `n`.
    pub fn arflow_generate(
        &self,
        actor: ndarray::ArrayView2<f32>,
        options: &ArflowOptions,
    ) -> Result<ndarray::Array2<f32>> {
        let nets = match &self.inner.networks {
            Networks::Arflow(nets) => nets,
            _ => return Err(self.wrong_family("arflow", "ARFlow generation")),
        };
        let sampling = options.apply(&nets.spec.sampler)?;
        arflow::sampler::generate(nets, actor, &sampling, options.seed)
    }

    /// The sampling configuration a default live partner session of this `magnet` model runs.
    pub fn magnet_live_configuration(&self) -> Result<crate::magnet::spec::SamplingSpec> {
        let nets = self.magnet("a live partner session")?;
        Ok(crate::session::partner_settings(nets, &SessionOptions::default())?.sampling)
    }

    /// Runs the MAGNet sampling configuration `config` (one of the bundle's released ones, by
    /// the official YAML's name: `dd100`, `dd100_partner_prediction`, ..., see
    /// [`MagnetSpec::sampling`]; or a whole configuration as JSON, the fields of those entries)
    /// on a clip of `frames` `[F, P, 145]` (per person and frame:
    /// betas, the 21 body joints' 6-D rotations, the root's pose in the world, y up;
    /// `onnx/README.md`, "Family `magnet`"), every person present unless `mask` `[F, P]` says
    /// otherwise. What the frames are depends on the task: the context (its first
    /// `context_len` frames) for joint generation, turn-taking and sync; person 0's whole
    /// motion (and the others' first `context_len` frames) for partner prediction, the live
    /// partner, inpainting and pp2joint; the key frames for in-betweening. Returns the sampled
    /// tokens and the frames they decode to, every person's root in the input's world frame.
    pub fn magnet_generate(
        &self,
        config: &str,
        frames: ndarray::ArrayView3<f32>,
        mask: Option<ndarray::ArrayView2<bool>>,
        options: &MagnetOptions,
    ) -> Result<MagnetOutput> {
        let nets = self.magnet("MAGNet generation")?;
        let cfg = magnet::configuration(nets, config, options)?;
        magnet::generate(nets, cfg, frames, mask, options.draws.clone())
    }

    /// The shape `[S, F, P, 145]` of the frames [`Model::magnet_generate`] returns for
    /// `input_frames` frames of input, without running it (the same checks of the
    /// configuration and the input's length).
    pub fn magnet_output_shape(
        &self,
        config: &str,
        input_frames: usize,
        options: &MagnetOptions,
    ) -> Result<[usize; 4]> {
        let nets = self.magnet("MAGNet generation")?;
        let cfg = magnet::configuration(nets, config, options)?;
        magnet::output_shape(nets, &cfg, input_frames)
    }

    /// [`Model::magnet_generate`] with a configuration of the caller's (checked as the
    /// manifest's are: the task fits the model, lengths fit the window) and, optionally, every
    /// draw of the run.
    pub fn magnet_generate_with(
        &self,
        sampling: &crate::magnet::spec::SamplingSpec,
        frames: ndarray::ArrayView3<f32>,
        mask: Option<ndarray::ArrayView2<bool>>,
        draws: Option<Vec<Vec<f32>>>,
    ) -> Result<MagnetOutput> {
        let nets = self.magnet("MAGNet generation")?;
        magnet::generate(nets, sampling.clone(), frames, mask, draws)
    }

    /// Runs the official text branch: CLIP's token features `[tokens, text_token_dim]` (the
    /// output of CLIP's final LayerNorm for one prompt) and the index of its end-of-text token
    /// (the argmax of CLIP's token ids) give the condition vector `[condition_dim]`. Needs a
    /// bundle with a `text_branch` graph ([`Model::text_token_dim`] is then `Some`): ARMFlow's
    /// official bundles, and UMF's, whose condition is `[P-Flow text ; S-Flow text]`.
    pub fn encode_text(&self, clip_tokens: ArrayView2<f32>, eot_index: usize) -> Result<Vec<f32>> {
        self.text_branch()?.encode(clip_tokens, eot_index)
    }

    /// The width of the CLIP token features [`Model::encode_text`] reads, or `None` when the
    /// bundle has no text branch.
    pub fn text_token_dim(&self) -> Option<usize> {
        self.text_branch().ok().map(|branch| branch.token_dim)
    }

    /// The condition for a text prompt, as the official code computes it: the prompt tokenized
    /// as CLIP tokenizes it (lower-cased, cleaned, byte-pair encoded, truncated to 77 tokens),
    /// CLIP's text tower, then the family's text branch at the end-of-text token. `""` gives
    /// the official "no text" (for such bundles, the manifest's null condition). The last 64
    /// prompts are cached. Needs a bundle with a text encoder ([`Model::takes_prompts`]).
    pub fn encode_prompt(&self, prompt: &str) -> Result<Vec<f32>> {
        self.prompt_encoder()?.encode(prompt)
    }

    /// Whether the bundle turns text prompts into conditions ([`Model::encode_prompt`]): it
    /// carries CLIP's text tower, its tokenizer and a text branch.
    pub fn takes_prompts(&self) -> bool {
        self.prompt_encoder().is_ok()
    }

    /// The token ids the bundle's text tower reads for `prompt` (CLIP's `tokenize` with
    /// truncation: `<|startoftext|>`, the byte-pair ids, `<|endoftext|>`, zeros to 77).
    pub fn prompt_token_ids(&self, prompt: &str) -> Result<Vec<i64>> {
        self.prompt_encoder()?.prompts.token_ids(prompt)
    }

    fn prompt_encoder(&self) -> Result<PromptEncoder<'_>> {
        let found = match &self.inner.networks {
            Networks::ArmFlow(n) => n.prompt_encoder(),
            Networks::Umf(n) => n.prompt_encoder(),
            Networks::Magnet(_) | Networks::Arflow(_) => None,
        };
        found.ok_or_else(|| no_prompts(&self.manifest().name))
    }

    /// The bundle's text branch; an error naming the bundle when it has none.
    pub(crate) fn text_branch(&self) -> Result<TextBranch<'_>> {
        let found = match &self.inner.networks {
            Networks::ArmFlow(n) => n.text_branch(),
            Networks::Umf(n) => n.text_branch(),
            Networks::Magnet(_) | Networks::Arflow(_) => None,
        };
        found.ok_or_else(|| {
            Error::InvalidInput(format!(
                "bundle `{}` has no text_branch graph",
                self.manifest().name
            ))
        })
    }

    // ---- armflow ------------------------------------------------------------------------------

    /// Starts a stream. Options left unset take the bundle's defaults. An `armflow` model
    /// streams the reactor to an actor; a `magnet` model the live partner to a user (its
    /// `motion_control_live` configuration). Fails for other families.
    pub fn session(&self, options: SessionOptions) -> Result<Session> {
        match &self.inner.networks {
            Networks::ArmFlow(nets) => Ok(Session::reaction(armflow::Session::new(
                Arc::clone(nets),
                options.for_reaction()?,
            )?)),
            Networks::Magnet(nets) => {
                let settings = crate::session::partner_settings(nets, &options)?;
                Ok(Session::partner(LiveSession::new(
                    Arc::clone(nets),
                    settings,
                )?))
            }
            Networks::Arflow(nets) => {
                let sampling = options.for_flow(&nets.spec.sampler)?;
                Ok(Session::flow(ArflowStream::new(
                    Arc::clone(nets),
                    sampling,
                    options.seed,
                )?))
            }
            Networks::Umf(_) => Err(Error::Unsupported(format!(
                "bundle `{}` is a `umf` model; a streaming session needs an `armflow`, a `magnet` \
                 or an online `arflow` bundle",
                self.inner.manifest.name
            ))),
        }
    }

    /// The context `c` the encoder gives after `[<sos>, pairs...]`, computed from scratch in one
    /// causal pass (no cache). `pairs` holds `(actor || reactor)` tokens, row-major
    /// `[n, 2 * latent_dim]`; positions are `0..=n`. A session's cached stream gives the same
    /// context while its history fits in the context capacity.
    pub fn recompute_context(&self, condition: Option<&[f32]>, pairs: &[f32]) -> Result<Vec<f32>> {
        self.armflow("streaming")?
            .recompute_context(condition, pairs)
    }

    /// Whether the bundle has per-token VAE steps (O(1) per token, no windows).
    pub fn has_vae_steps(&self) -> bool {
        self.armflow("streaming")
            .is_ok_and(|nets| nets.has_vae_steps())
    }

    /// The official clip of an `armflow` bundle with a `clip` section, or `None`.
    pub fn clip_spec(&self) -> Option<&ClipSpec> {
        self.armflow_spec().and_then(|a| a.clip.as_ref())
    }

    /// The draws [`Model::generate_clip`] makes for `seed` when none are given.
    pub fn clip_noise(&self, seed: u64) -> Result<armflow::ClipNoise> {
        self.armflow("clip generation")?.clip_noise(seed)
    }

    /// Runs the official ARMFlow sampler on one actor clip (see `armflow/clip.rs`): `actor` is
    /// `[frames, frame_dim]` with 1 to `clip.frames` frames (zero-padded to `clip.frames`);
    /// `condition` the text condition (`None`: the null condition). Needs an `armflow` bundle
    /// with a `clip` section, exported from the official layout (`onnx/cli.py armflow export
    /// --preset interhuman | interx`).
    ///
    /// ```no_run
    /// use ndarray::Array2;
    /// use troupe::{ClipOptions, Model};
    /// let model = Model::load("onnx/bundles/armflow-tiny-interhuman")?;
    /// let actor = Array2::<f32>::zeros((120, model.frame_dim()));
    /// let clip = model.generate_clip(actor.view(), None, &ClipOptions { seed: 1, ..Default::default() })?;
    /// assert_eq!(clip.frames.nrows(), 300);
    /// # Ok::<(), troupe::Error>(())
    /// ```
    pub fn generate_clip(
        &self,
        actor: ArrayView2<f32>,
        condition: Option<&[f32]>,
        options: &ClipOptions,
    ) -> Result<Clip> {
        self.armflow("clip generation")?
            .generate_clip(actor, condition, options)
    }

    /// [`Model::generate_clip`] conditioned on a text prompt ([`Model::encode_prompt`]).
    pub fn generate_clip_for_prompt(
        &self,
        actor: ArrayView2<f32>,
        prompt: &str,
        options: &ClipOptions,
    ) -> Result<Clip> {
        let condition = self.encode_prompt(prompt)?;
        self.generate_clip(actor, Some(&condition), options)
    }

    // ---- umf ----------------------------------------------------------------------------------

    /// Generates `people` persons' motion for `condition` (`[prior text ; reaction text]`,
    /// `condition_dim` floats; `None` is the bundle's null condition). Needs a `umf` bundle.
    ///
    /// ```no_run
    /// use troupe::{GroupOptions, Model};
    /// let model = Model::load("onnx/bundles/umf-tiny")?;
    /// let group = model.generate_group(None, 3, &GroupOptions { seed: 1, ..Default::default() })?;
    /// assert_eq!(group.motion.shape()[0], 3);
    /// # Ok::<(), troupe::Error>(())
    /// ```
    pub fn generate_group(
        &self,
        condition: Option<&[f32]>,
        people: usize,
        options: &GroupOptions,
    ) -> Result<Group> {
        self.umf()?.generate_group(condition, people, options)
    }

    /// [`Model::generate_group`] conditioned on a text prompt ([`Model::encode_prompt`]: for a
    /// UMF bundle, `[prior text ; reaction text]` of the prompt).
    pub fn generate_group_for_prompt(
        &self,
        prompt: &str,
        people: usize,
        options: &GroupOptions,
    ) -> Result<Group> {
        let condition = self.encode_prompt(prompt)?;
        self.generate_group(Some(&condition), people, options)
    }

    /// The noise `generate_group` draws for `seed` and `people` when none is given: Philox
    /// normals (see [`crate::noise`]) on streams [`crate::STREAM_PRIOR_NOISE`],
    /// [`crate::STREAM_JUMP_NOISE`] (turned into block noise by each jump's covariance factor)
    /// and [`crate::STREAM_REACTION_NOISE`].
    pub fn group_noise(&self, seed: u64, people: usize) -> Result<GroupNoise> {
        self.umf()?.group_noise(seed, people)
    }

    /// The shape of the [`GroupNoise`] of `people` people (1 to [`crate::MAX_PEOPLE`]).
    pub fn group_noise_shape(&self, people: usize) -> Result<GroupNoiseShape> {
        self.umf()?.group_noise_shape(people)
    }

    // ---- dispatch -----------------------------------------------------------------------------

    /// The ARMFlow networks, or an error saying that `what` needs an `armflow` bundle.
    fn armflow(&self, what: &str) -> Result<&Arc<armflow::Networks>> {
        match &self.inner.networks {
            Networks::ArmFlow(nets) => Ok(nets),
            _ => Err(self.wrong_family("armflow", what)),
        }
    }

    /// The UMF networks, or an error saying that group generation needs a `umf` bundle.
    fn umf(&self) -> Result<&umf::Networks> {
        match &self.inner.networks {
            Networks::Umf(nets) => Ok(nets),
            _ => Err(self.wrong_family("umf", "group generation")),
        }
    }

    /// The MAGNet networks, or an error saying that `what` needs a `magnet` bundle.
    fn magnet(&self, what: &str) -> Result<&magnet::Networks> {
        match &self.inner.networks {
            Networks::Magnet(nets) => Ok(nets),
            _ => Err(self.wrong_family("magnet", what)),
        }
    }

    /// The error for using this bundle where another family is needed: `what` needs `needed`.
    pub(crate) fn wrong_family(&self, needed: &str, what: &str) -> Error {
        // As read aloud: "an armflow", "an arflow", "a umf", "a magnet".
        let article = |family: &str| if family.starts_with('a') { "an" } else { "a" };
        let family = self.inner.manifest.family_name();
        Error::Unsupported(format!(
            "bundle `{}` is {} `{family}` model; {what} needs {} `{needed}` bundle",
            self.inner.manifest.name,
            article(family),
            article(needed),
        ))
    }
}
