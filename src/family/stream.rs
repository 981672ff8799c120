//! [`Stream`]: what a family's stream gives the [`Session`](super::session::Session) that boxes
//! it. Frames in, the other person's frames out, and the settings a family may or may not
//! offer, reported as [`Capability`]s rather than known by the family's name.

use std::any::Any;
use std::fmt::{self, Debug};

use ndarray::Array2;

use crate::shared::bundle_io::BundleIo;
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{cannot_snapshot, SnapshotWriter};

/// What a stream computed for one token.
#[derive(Debug, Clone, PartialEq)]
pub struct TokenTrace {
    /// Token index in the stream (0-based).
    pub index: u64,
    /// The input person's latent token (ARMFlow: the actor's `a_j`, scaled; MAGNet: the user's
    /// token at the same place).
    pub actor_latent: Vec<f32>,
    /// The generated latent token (ARMFlow: the reactor's `b_j`, scaled; MAGNet: the partner's).
    pub reactor_latent: Vec<f32>,
    /// The context `c_j` ARMFlow's velocity network was conditioned on (empty for others).
    pub context: Vec<f32>,
}

/// Result of a step: the frames that became ready and the tokens computed for them.
#[derive(Debug, Clone)]
pub struct StepOutput {
    /// Output frames that became ready, `[n, frame_dim]`.
    pub frames: Array2<f32>,
    /// Every token generated during the step, in order (none for ARFlow, which has no latent).
    pub tokens: Vec<TokenTrace>,
}

impl StepOutput {
    /// Frames without tokens (ARFlow's steps).
    pub(crate) fn frames_only(frames: Array2<f32>) -> Self {
        Self {
            frames,
            tokens: Vec::new(),
        }
    }
}

/// A setting or input a stream may take beyond frames, seed and steps (which every stream
/// takes). A call for a capability the stream lacks fails with [`Error::Unsupported`] naming it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Capability {
    /// A conditioning vector (`Session::set_condition`).
    Condition,
    /// A text prompt turned into the condition by the bundle's text encoder.
    Prompt,
    /// Classifier-free guidance with a caller-set scale (`Session::set_cfg_scale`).
    CfgScale,
    /// Standard normals queued in the order the sampler draws them (`Session::queue_normals`).
    QueuedNormals,
}

impl Capability {
    /// Every capability, in a fixed order (its bit is its index).
    pub const ALL: [Capability; 4] = [
        Capability::Condition,
        Capability::Prompt,
        Capability::CfgScale,
        Capability::QueuedNormals,
    ];

    /// The capability's bit in a [`Capabilities`] set (and in the C ABI's mask).
    pub const fn bit(self) -> u32 {
        1 << self as u32
    }

    /// What the capability is called in messages and docs.
    pub const fn name(self) -> &'static str {
        match self {
            Capability::Condition => "a condition",
            Capability::Prompt => "a text prompt",
            Capability::CfgScale => "a CFG scale",
            Capability::QueuedNormals => "queued normals",
        }
    }
}

impl fmt::Display for Capability {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A set of [`Capability`]s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Capabilities(u32);

impl Capabilities {
    /// The set of `caps`.
    pub const fn of(caps: &[Capability]) -> Self {
        let mut bits = 0;
        let mut i = 0;
        while i < caps.len() {
            bits |= caps[i].bit();
            i += 1;
        }
        Capabilities(bits)
    }

    /// Whether `cap` is in the set.
    pub const fn has(self, cap: Capability) -> bool {
        self.0 & cap.bit() != 0
    }

    /// The set as a bit mask ([`Capability::bit`]).
    pub const fn bits(self) -> u32 {
        self.0
    }

    /// The capabilities in the set, in [`Capability::ALL`]'s order.
    pub fn iter(self) -> impl Iterator<Item = Capability> {
        Capability::ALL.into_iter().filter(move |c| self.has(*c))
    }
}

/// The error for `cap` asked of a `family` stream that lacks it.
pub(crate) fn unsupported(family: &str, cap: Capability) -> Error {
    Error::Unsupported(format!(
        "{cap}: this `{family}` stream does not take it (see Session::capabilities)"
    ))
}

/// What a session does to a step's output before the stream commits the step: called with the
/// stream's index in the batch (0 alone) and its output; an error undoes the whole step.
pub(crate) type Finish<'a> = &'a mut dyn FnMut(usize, &mut StepOutput) -> Result<()>;

/// Steps many streams of one family and model at once; entry `i` of the result is what
/// stepping `streams[i]` alone with `frames[i]` would give. Every stream is of the family whose
/// [`Stream::step_together`] gave this.
pub(crate) type StepTogether =
    fn(&mut [&mut dyn Stream], &[&[f32]], Finish<'_>) -> Result<Vec<StepOutput>>;

/// What the neutral layer needs of a family's stream. A step either completes or leaves the
/// stream exactly as it was; the session checked the frames' shape and values and the room for
/// the output before it is called.
pub(crate) trait Stream: Send + Debug + Any {
    /// The family's manifest name (`"armflow"`).
    fn family(&self) -> &'static str;
    /// The bundle facts the stream's model was loaded with.
    fn io(&self) -> &BundleIo;
    /// The frames' layout (`motion.layout` of the manifest: `"interhuman262"`, ...).
    fn frame_layout(&self) -> &str {
        &self.io().motion.layout
    }
    /// Frames per second, in and out.
    fn fps(&self) -> f32 {
        self.io().motion.fps as f32
    }
    /// Floats per frame, in and out.
    fn frame_dim(&self) -> usize;
    /// Floats per latent token (a frame for a family without latents).
    fn latent_dim(&self) -> usize;
    /// Floats in the conditioning vector the stream takes (0: none).
    fn condition_dim(&self) -> usize {
        0
    }
    /// What the stream takes beyond frames, seed and steps.
    fn capabilities(&self) -> Capabilities {
        Capabilities::default()
    }
    /// One step on row-major frames; `finish` runs on the output before the step is committed.
    fn step(&mut self, frames: &[f32], finish: Finish<'_>) -> Result<StepOutput>;
    /// The family's batched step, for [`super::session::step_sessions`], which has checked the
    /// streams are of this family and model and that there are as many chunks as streams.
    fn step_together(&self) -> StepTogether;
    /// Whether `other` runs on the same loaded model (streams stepped together must).
    fn same_model(&self, other: &dyn Stream) -> bool;
    /// Back to a fresh stream with the current settings.
    fn reset(&mut self);
    /// Algorithmic latency in frames.
    fn latency_frames(&self) -> usize;
    /// The noise seed for what is generated from now on.
    fn set_seed(&mut self, seed: u64);
    /// The sampler's steps for what is generated from now on.
    fn set_steps(&mut self, steps: u32) -> Result<()>;
    /// [`Capability::CfgScale`].
    fn set_cfg_scale(&mut self, _scale: f32) -> Result<()> {
        Err(unsupported(self.family(), Capability::CfgScale))
    }
    /// [`Capability::Condition`]; `None`: the null condition.
    fn set_condition(&mut self, _condition: Option<&[f32]>) -> Result<()> {
        Err(unsupported(self.family(), Capability::Condition))
    }
    /// [`Capability::Prompt`].
    fn set_prompt(&mut self, _prompt: &str) -> Result<()> {
        Err(unsupported(self.family(), Capability::Prompt))
    }
    /// [`Capability::QueuedNormals`]: standard normals taken, in the order the sampler draws,
    /// before the seeded generator (see `Session::queue_normals`).
    fn queue_normals(&mut self, _normals: &[f32]) -> Result<()> {
        Err(unsupported(self.family(), Capability::QueuedNormals))
    }
    /// Exactly how many frames a step with `n` new frames returns.
    fn frames_ready_after(&self, n: usize) -> usize;
    /// Input frames received since the start or the last reset.
    fn frames_received(&self) -> u64;
    /// Output frames returned since the start or the last reset.
    fn frames_emitted(&self) -> u64;
    /// Tokens generated since the start or the last reset (0 without latents).
    fn tokens_generated(&self) -> u64 {
        0
    }
    /// Bytes the stream holds (shared weights not counted).
    fn memory_bytes(&self) -> usize;
    /// Context held for the next step (tokens, or frames for a frame-wise stream).
    fn context_len(&self) -> usize;
    /// The model's identity, which the stream's snapshots carry.
    fn model_identity(&self) -> [u8; 32] {
        self.io().identity()
    }
    /// Writes the stream's snapshot payload (`Session::snapshot` frames it and adds the
    /// session's own part after it).
    fn save(&self, _w: &mut SnapshotWriter) -> Result<()> {
        Err(cannot_snapshot(self.family()))
    }
    /// For [`super::session::Session::family_ref`].
    fn as_any(&self) -> &dyn Any;
    /// For `Session::family_mut` and the families' batched steps.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// The streams of a batch as the family's concrete type `S`; the caller checked the family.
pub(crate) fn downcast_all<'a, S: 'static>(streams: &'a mut [&mut dyn Stream]) -> Vec<&'a mut S> {
    streams
        .iter_mut()
        .map(|s| {
            s.as_any_mut()
                .downcast_mut::<S>()
                .expect("streams stepped together are of one family")
        })
        .collect()
}
