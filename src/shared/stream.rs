//! [`Session`]: one stream, whatever the family. Frames in, the other person's frames out.
//!
//! A family that streams implements [`Stream`] for its stream type (ARMFlow's reactor, MAGNet's
//! live partner, ARFlow's online stream); a `Session` boxes one, so that code which does not
//! care about the family — a game loop, a crowd, the C ABI — drives every stream one way:
//! `step` / `reset` / the common settings, and [`step_sessions`] for crowds (one batched pass
//! per round). What only one family offers is reached through the family's own type
//! ([`Session::family_mut`]), or refused with [`Error::Unsupported`].

use std::any::Any;
use std::fmt::Debug;

use ndarray::{Array2, ArrayView2};

use crate::shared::error::{a_or_an, Error, Result};
use crate::shared::snapshot::cannot_snapshot;

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

/// Steps many streams of one family and model at once; entry `i` of the result is what
/// stepping `streams[i]` alone with `frames[i]` would give, bounded by `max_frames[i]` (empty:
/// unbounded). Every stream is of the family whose [`Stream::step_together`] gave this.
pub(crate) type StepTogether =
    fn(&mut [&mut dyn Stream], &[&[f32]], &[usize]) -> Result<Vec<StepOutput>>;

/// What the neutral layer needs of a family's stream. A step either completes or leaves the
/// stream exactly as it was.
pub(crate) trait Stream: Send + Debug + Any {
    /// The family's manifest name (`"armflow"`).
    fn family(&self) -> &'static str;
    /// Floats per frame, in and out.
    fn frame_dim(&self) -> usize;
    /// Floats per latent token (a frame for a family without latents).
    fn latent_dim(&self) -> usize;
    /// Floats in the conditioning vector the stream takes (0: none).
    fn condition_dim(&self) -> usize {
        0
    }
    /// One step on row-major frames, failing without change when more than `max_frames` would
    /// come out.
    fn step_bounded(&mut self, frames: &[f32], max_frames: usize) -> Result<StepOutput>;
    /// The family's batched step, for [`step_sessions`], which has checked the streams are of
    /// this family and model and that there are as many chunks of frames as streams.
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
    /// Queues standard normals taken, in the order the sampler draws, before the seeded
    /// generator (see [`Session::queue_normals`]).
    fn queue_normals(&mut self, _normals: &[f32]) -> Result<()> {
        Err(Error::Unsupported(format!(
            "queued normals: {} streams take their noise per token (queue_noise)",
            self.family()
        )))
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
    /// The stream's snapshot ([`Session::snapshot`]).
    fn snapshot(&self) -> Result<Vec<u8>> {
        Err(cannot_snapshot(self.family()))
    }
    /// For [`Session::family_ref`].
    fn as_any(&self) -> &dyn Any;
    /// For [`Session::family_mut`] and the families' batched steps.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// One stream over a shared [`crate::Model`] (made by [`crate::Model::session`]), whatever
/// its family. `Send`, not `Sync`: use it from one thread at a time.
#[derive(Debug)]
pub struct Session {
    stream: Box<dyn Stream>,
}

impl Session {
    /// Boxes a family's stream.
    pub(crate) fn new(stream: impl Stream) -> Self {
        Self {
            stream: Box::new(stream),
        }
    }

    /// The family this session streams: `"armflow"`, `"magnet"` or `"arflow"`.
    pub fn family(&self) -> &'static str {
        self.stream.family()
    }

    /// The family's own stream type (`armflow::Reactor`, `magnet::LivePartner`,
    /// `arflow::OnlineStream`), for what only that family offers; [`Error::Unsupported`] naming
    /// both when this session runs another family.
    pub fn family_ref<S: 'static>(&self) -> Result<&S> {
        let family = self.family();
        self.stream
            .as_any()
            .downcast_ref::<S>()
            .ok_or_else(|| wrong_stream::<S>(family))
    }

    /// [`Session::family_ref`], mutable.
    pub fn family_mut<S: 'static>(&mut self) -> Result<&mut S> {
        let family = self.family();
        self.stream
            .as_any_mut()
            .downcast_mut::<S>()
            .ok_or_else(|| wrong_stream::<S>(family))
    }

    /// Floats per motion frame, in and out.
    pub fn frame_dim(&self) -> usize {
        self.stream.frame_dim()
    }

    /// Floats per latent token (ARMFlow: each noise vector; MAGNet: a motion token; ARFlow,
    /// which has no latent: a frame).
    pub fn latent_dim(&self) -> usize {
        self.stream.latent_dim()
    }

    /// Floats in the conditioning vector the stream takes (0: none).
    pub fn condition_dim(&self) -> usize {
        self.stream.condition_dim()
    }

    /// Feeds any number of frames (`[n, frame_dim]`, n may be 0) and returns the other person's
    /// frames that became ready. On error the session is unchanged.
    pub fn step(&mut self, frames: ArrayView2<f32>) -> Result<Array2<f32>> {
        Ok(self.step_detailed(frames)?.frames)
    }

    /// [`Session::step`], also returning the latent tokens it computed.
    pub fn step_detailed(&mut self, frames: ArrayView2<f32>) -> Result<StepOutput> {
        let dim = self.frame_dim();
        if frames.ncols() != dim {
            return Err(Error::InvalidInput(format!(
                "frames have {} features, this {} stream takes {dim}",
                frames.ncols(),
                self.family()
            )));
        }
        let owned = frames.as_standard_layout();
        self.step_flat(owned.as_slice().expect("standard layout"))
    }

    /// [`Session::step_detailed`] on row-major frames (`n * frame_dim` floats).
    pub fn step_flat(&mut self, frames: &[f32]) -> Result<StepOutput> {
        self.stream.step_bounded(frames, usize::MAX)
    }

    /// [`Session::step_flat`] that fails, leaving the session unchanged, when more than
    /// `max_frames` frames would come out (the C ABI's caller-sized buffer).
    pub(crate) fn step_bounded(&mut self, frames: &[f32], max_frames: usize) -> Result<StepOutput> {
        self.stream.step_bounded(frames, max_frames)
    }

    /// Everything the stream needs to go on, as bytes: [`crate::Model::restore`] on the same
    /// model (in this process or another) gives a session whose steps are, bit for bit, this
    /// one's. Taken between steps, so it never holds half a step; the session is unchanged. A
    /// versioned, checksummed format (`docs/SNAPSHOTS.md`); [`Error::Unsupported`] for a family
    /// whose streams cannot be saved yet.
    pub fn snapshot(&self) -> Result<Vec<u8>> {
        self.stream.snapshot()
    }

    /// Returns the session to the state of a fresh session with the current settings.
    pub fn reset(&mut self) {
        self.stream.reset()
    }

    /// Algorithmic latency in frames: how many input frames after frame `t` arrive before the
    /// output frame `t` is out (at worst, compute time not counted).
    pub fn latency_frames(&self) -> usize {
        self.stream.latency_frames()
    }

    /// Sets the noise seed; applies to what is generated from now on.
    pub fn set_seed(&mut self, seed: u64) {
        self.stream.set_seed(seed)
    }

    /// Queues standard normals for the draws to come, to replay another implementation's
    /// stream exactly: each draw the sampler makes (MAGNet's live partner: as its offline run,
    /// `docs/MAGNET.md`; ARFlow online: per frame the start noise when σ > 0, then one ε per
    /// step when η > 0, 262 each) takes the next ones it needs while any are queued, then the
    /// seeded generator goes on (draw `i` its token `i`, as if the queued draws were its). A
    /// draw that needs more than are left fails, the stream as it was. [`Session::reset`] drops
    /// them. ARMFlow streams take their noise per token (`Reactor::queue_noise`) and refuse
    /// this with [`Error::Unsupported`].
    pub fn queue_normals(&mut self, normals: &[f32]) -> Result<()> {
        crate::shared::checks::check_input("queued normals", normals)?;
        self.stream.queue_normals(normals)
    }

    /// Sets the sampler's steps (>= 1): MeanFlow steps per token, DDIM steps per chunk, flow
    /// steps per frame.
    pub fn set_steps(&mut self, steps: u32) -> Result<()> {
        self.stream.set_steps(steps)
    }

    /// Exactly how many frames a `step` with `n` new input frames will return.
    pub fn frames_ready_after(&self, n: usize) -> usize {
        self.stream.frames_ready_after(n)
    }

    /// Input frames received since the start (or the last reset).
    pub fn frames_received(&self) -> u64 {
        self.stream.frames_received()
    }

    /// Output frames returned since the start (or the last reset).
    pub fn frames_emitted(&self) -> u64 {
        self.stream.frames_emitted()
    }

    /// Tokens generated (ARMFlow) or sent (MAGNet) since the start (or the last reset).
    pub fn tokens_generated(&self) -> u64 {
        self.stream.tokens_generated()
    }

    /// Bytes this stream holds, bounded however long it runs (the model's weights, shared by
    /// all sessions, not counted).
    pub fn memory_bytes(&self) -> usize {
        self.stream.memory_bytes()
    }

    /// Context held: ARMFlow's cache entries (`<sos>` included), MAGNet's context tokens for
    /// its next window, ARFlow's frames.
    pub fn context_len(&self) -> usize {
        self.stream.context_len()
    }
}

/// The error for a family's own stream type asked of another family's session.
fn wrong_stream<S>(family: &str) -> Error {
    let wanted = std::any::type_name::<S>().trim_start_matches("troupe::");
    Error::Unsupported(format!(
        "this session runs {} `{family}` model, not a `{wanted}`",
        a_or_an(family)
    ))
}

/// Advances many sessions of one model in one call: `frames[i]` (row-major, any number) goes to
/// `sessions[i]`, and the result's entry `i` is what [`Session::step_flat`] would have returned
/// for it. Each round runs the networks once for all the sessions that have work (a token, a
/// chunk, a frame), so the weights are read once per round rather than once per session; each
/// session's output equals stepping it alone up to float rounding (<= 1e-5 in the tests). On
/// error every session is unchanged.
pub fn step_sessions(sessions: &mut [&mut Session], frames: &[&[f32]]) -> Result<Vec<StepOutput>> {
    step_sessions_bounded(sessions, frames, &[])
}

/// [`step_sessions`] that fails, changing no session, when session `i` would return more than
/// `max_frames[i]` frames (the C ABI's caller-sized buffers; empty: unbounded).
pub(crate) fn step_sessions_bounded(
    sessions: &mut [&mut Session],
    frames: &[&[f32]],
    max_frames: &[usize],
) -> Result<Vec<StepOutput>> {
    if frames.len() != sessions.len() {
        return Err(Error::InvalidInput(format!(
            "{} sessions but {} chunks of frames",
            sessions.len(),
            frames.len()
        )));
    }
    let Some(first) = sessions.first() else {
        return Ok(Vec::new());
    };
    let together = first.stream.step_together();
    if let Some(i) = (1..sessions.len()).find(|&i| {
        sessions[i].family() != sessions[0].family()
            || !sessions[i].stream.same_model(&*sessions[0].stream)
    }) {
        return Err(Error::InvalidInput(format!(
            "session {i} runs another model: sessions stepped together must share one"
        )));
    }
    let mut streams: Vec<&mut dyn Stream> = sessions.iter_mut().map(|s| &mut *s.stream).collect();
    together(&mut streams, frames, max_frames)
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
