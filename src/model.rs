//! [`Model`]: a loaded bundle, above the families. It reads the manifest, loads the family's
//! model through its manifest section (`manifest.rs`'s registration table), answers the
//! questions every caller asks whatever the family (frame size, latency, dimensions, text
//! prompts, a default stream), and gives the family's own type for everything else:
//! `model.armflow()?`, `model.umf()?`, `model.magnet()?`, `model.arflow()?`. Immutable once
//! loaded, cheap to clone, shared by any number of sessions on any number of threads.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use ndarray::ArrayView2;

use crate::arflow::Arflow;
use crate::armflow::Armflow;
use crate::family::motion::joints_added_latency;
use crate::family::session::Session;
use crate::family::{wrong_family, Family, StreamOptions};
use crate::magnet::Magnet;
use crate::manifest::{ConditionLabel, Manifest};
use crate::shared::bundle::BundleFiles;
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::SnapshotReader;
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::{no_prompts, PromptEncoder};
use crate::umf::Umf;

/// A loaded bundle: manifest plus optimised graphs, of one family. What every family answers
/// is here; the rest is the family's own type (`model.armflow()?.generate_clip(..)`).
///
/// `Model` is `Send + Sync`; clones share the same graphs. A [`Session`] keeps the graphs alive.
#[derive(Debug, Clone)]
pub struct Model {
    inner: Arc<Inner>,
}

#[derive(Debug)]
struct Inner {
    source: PathBuf,
    /// SHA-256 of the bundle's files as the load read them.
    identity: [u8; 32],
    manifest: Manifest,
    family: Box<dyn Family>,
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
        let family = manifest.family.section().load(&files, io.clone())?;
        let identity = files.identity();
        io.identity.get_or_init(|| identity);
        let inner = Inner {
            identity,
            manifest,
            family,
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

    /// The bundle's family: `"armflow"`, `"umf"`, `"magnet"` or `"arflow"`.
    pub fn family(&self) -> &'static str {
        self.inner.family.name()
    }

    /// Motion frames per latent token (4 for ARMFlow and MAGNet); 0 for a `umf` model, whose
    /// tokens are global queries rather than spans of frames, and an `arflow` model, which has
    /// no latent tokens.
    pub fn frames_per_token(&self) -> usize {
        self.inner.family.frames_per_token()
    }

    /// Floats per latent token of one person.
    pub fn latent_dim(&self) -> usize {
        self.inner.family.latent_dim()
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
        self.inner.family.latency_frames()
    }

    /// Latency in frames when the actor streams joint positions ([`crate::Session::step_joints`]):
    /// [`Model::latency_frames`] plus what the joints stage of the stream's frame layout adds
    /// (one frame for features, whose velocities and contacts wait for the next; none for a
    /// MAGNet partner's SMPL-X frames). 0 for a model whose streams take no joint positions (a
    /// `umf` model, an InterX ARMFlow bundle).
    pub fn joints_latency_frames(&self) -> usize {
        let motion = &self.inner.manifest.motion;
        match joints_added_latency(&motion.layout, motion.frame_dim) {
            Some(added) if self.inner.family.session_defaults().is_ok() => {
                self.latency_frames() + added
            }
            _ => 0,
        }
    }

    /// The most frames one `step` with `n_actor_frames` new frames can return, whatever the
    /// session's state: `ceil(n / frames_per_token) * frames_per_token` for ARMFlow; for a
    /// MAGNet live partner `n` plus the frames a stream may hold back, under one window
    /// (`4 Tm`); `n` for an ARFlow stream (a frame out for each frame in). 0 for a `umf` model.
    pub fn max_output_frames(&self, n_actor_frames: usize) -> usize {
        self.inner.family.max_output_frames(n_actor_frames)
    }

    /// Frames of motion per clip: per person of `Umf::generate_group` for a `umf` bundle,
    /// of `Armflow::generate_clip` for an `armflow` bundle with a `clip` section; 0 otherwise.
    pub fn clip_frames(&self) -> usize {
        self.inner.family.clip_frames()
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
        self.inner
            .family
            .prompt_encoder()
            .ok_or_else(|| no_prompts(&self.manifest().name))
    }

    /// The bundle's text branch; an error naming the bundle when it has none.
    pub(crate) fn text_branch(&self) -> Result<TextBranch<'_>> {
        self.inner.family.text_branch().ok_or_else(|| {
            Error::InvalidInput(format!(
                "bundle `{}` has no text_branch graph",
                self.manifest().name
            ))
        })
    }

    // ---- streams -----------------------------------------------------------------------------

    /// Starts a stream. [`crate::SessionOptions`] opens the family's default stream (an
    /// `armflow` reactor, a `magnet` live partner, an online `arflow` stream) with the bundle's
    /// defaults; a family's own options ([`crate::armflow::ReactorOptions`],
    /// [`crate::magnet::PartnerOptions`], [`crate::arflow::ArflowOptions`]) open that family's
    /// stream with everything it offers, and are refused by another family's bundle
    /// ([`Error::Unsupported`], as is any session of a `umf` bundle, which does not stream).
    ///
    /// ```no_run
    /// use troupe::{armflow::ReactorOptions, Model, SessionOptions};
    /// let model = Model::load("onnx/bundles/armflow-tiny")?;
    /// let any = model.session(SessionOptions { seed: 7, ..Default::default() })?;
    /// let mirror = model.session(ReactorOptions { cfg_scale: Some(2.0), ..Default::default() })?;
    /// # Ok::<(), troupe::Error>(())
    /// ```
    pub fn session(&self, options: impl StreamOptions) -> Result<Session> {
        options.open(&*self.inner.family)
    }

    /// A session that goes on exactly where the session [`Session::snapshot`] saved in `snapshot`
    /// stopped: its next step gives, bit for bit, what the saved session's next step would have
    /// given. The snapshot may come from another process or machine, but only from this model
    /// (the same bundle files, [`Model::identity`]); a snapshot that is truncated, altered, of
    /// another model, family or format version is refused with [`Error::InvalidInput`] before
    /// anything it claims is allocated. The format: `docs/SNAPSHOTS.md`.
    pub fn restore(&self, snapshot: &[u8]) -> Result<Session> {
        self.restore_checked(snapshot)
    }

    /// [`Model::restore`] of a snapshot sealed with [`Session::snapshot_sealed`] under `key`:
    /// its seal is checked first (in constant time), so a snapshot that another key sealed, or
    /// whose bytes changed, is refused before any of it is read (`docs/SNAPSHOTS.md`). An
    /// unsealed snapshot is refused too: a store that needs seals takes no other.
    pub fn restore_sealed(&self, sealed: &[u8], key: &[u8]) -> Result<Session> {
        self.restore_checked(crate::shared::sealed::open(sealed, key)?)
    }

    fn restore_checked(&self, snapshot: &[u8]) -> Result<Session> {
        let family = &*self.inner.family;
        let mut payload = SnapshotReader::open(snapshot, family.name(), &self.inner.identity)?;
        let mut session = family.restore(&mut payload)?;
        session.load_motion(&mut payload)?;
        payload.finish()?;
        Ok(session)
    }

    /// The model's identity: the SHA-256 of its bundle's files as the load read them (in name
    /// order, each with its name), the same for a directory and a tar of it. Snapshots carry it.
    pub fn identity(&self) -> [u8; 32] {
        self.inner.identity
    }

    /// The common options the default stream starts with: the bundle's steps and context, seed
    /// 0 ([`Error::Unsupported`] for a family that does not stream).
    pub fn session_defaults(&self) -> Result<crate::SessionOptions> {
        self.inner.family.session_defaults()
    }

    // ---- the family's own API -----------------------------------------------------------------

    /// The ARMFlow model: reactors, the official clip; [`Error::Unsupported`] for another
    /// family's bundle.
    pub fn armflow(&self) -> Result<&Armflow> {
        self.family_as("armflow")
    }

    /// The UMF model: groups; [`Error::Unsupported`] for another family's bundle.
    pub fn umf(&self) -> Result<&Umf> {
        self.family_as("umf")
    }

    /// The MAGNet model: its tasks and live partners; [`Error::Unsupported`] for another
    /// family's bundle.
    pub fn magnet(&self) -> Result<&Magnet> {
        self.family_as("magnet")
    }

    /// The ARFlow model: whole clips and online streams; [`Error::Unsupported`] for another
    /// family's bundle.
    pub fn arflow(&self) -> Result<&Arflow> {
        self.family_as("arflow")
    }

    fn family_as<F: 'static>(&self, needed: &str) -> Result<&F> {
        self.inner
            .family
            .as_any()
            .downcast_ref::<F>()
            .ok_or_else(|| self.wrong_family(needed, "this call"))
    }

    /// The error for using this bundle where another family is needed: `what` needs `needed`.
    pub(crate) fn wrong_family(&self, needed: &str, what: &str) -> Error {
        wrong_family(Some(&self.inner.manifest.name), self.family(), needed, what)
    }
}
