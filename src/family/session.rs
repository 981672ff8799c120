//! [`Session`]: one stream, whatever the family. Frames or joint positions in, the other
//! person's frames or poses out.
//!
//! A family that streams implements [`Stream`] for its stream type (ARMFlow's reactor, MAGNet's
//! live partner, ARFlow's online stream); a `Session` boxes one with the motion stages its frame
//! layout allows (`motion/`), so that code which does not care about the family — a game loop,
//! a crowd, the C ABI — drives every stream one way: `step` / `step_joints` / `reset` / the
//! settings, and [`step_sessions`] for crowds (one batched pass per round). A setting only some
//! streams take is a [`Capability`] the session reports; what only one family offers is reached
//! through the family's own type ([`Session::family_mut`]). Either is refused with
//! [`Error::Unsupported`] where the stream lacks it.

use ndarray::{Array2, ArrayView2, ArrayView3};

use super::motion::{MotionStages, PenetrationGuard, RootSmoothing};
use super::stream::{unsupported, Capabilities, Capability, StepOutput, Stream};
use crate::motion::features::Pose;
use crate::motion::foot_lock::FootLockOptions;
use crate::motion::placement::Placement;
use crate::motion::skeleton::T2M22_JOINTS;
use crate::motion::world::JointsFormat;
use crate::shared::checks::{check_frame_count, check_input};
use crate::shared::error::{a_or_an, Error, Result};
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};

/// One stream over a shared [`crate::Model`] (made by [`crate::Model::session`]), whatever
/// its family. `Send`, not `Sync`: use it from one thread at a time.
#[derive(Debug)]
pub struct Session {
    stream: Box<dyn Stream>,
    motion: MotionStages,
}

impl Session {
    /// Boxes a family's stream, with no motion stage on.
    pub(crate) fn new(stream: impl Stream) -> Self {
        let motion = MotionStages::new(stream.frame_layout(), stream.frame_dim(), stream.fps());
        Self {
            stream: Box::new(stream),
            motion,
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

    /// The frames' layout: `"interhuman262"` (ARMFlow, ARFlow), `"magnet-smplx145"` (MAGNet).
    pub fn frame_layout(&self) -> &str {
        self.stream.frame_layout()
    }

    /// Floats per motion frame, in and out.
    pub fn frame_dim(&self) -> usize {
        self.stream.frame_dim()
    }

    /// Frames per second, in and out.
    pub fn fps(&self) -> f32 {
        self.stream.fps()
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

    /// What the stream takes beyond frames, seed and steps (a condition, a prompt, a CFG
    /// scale, queued normals); the calls for the others fail with [`Error::Unsupported`].
    pub fn capabilities(&self) -> Capabilities {
        self.stream.capabilities()
    }

    /// Feeds any number of frames (`[n, frame_dim]`, n may be 0) and returns the other person's
    /// frames that became ready, after the motion stages that are on. On error the session is
    /// unchanged.
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
        self.step_bounded(frames, usize::MAX)
    }

    /// [`Session::step_flat`] that fails, leaving the session unchanged, when more than
    /// `max_frames` frames would come out (the C ABI's caller-sized buffer).
    pub(crate) fn step_bounded(&mut self, frames: &[f32], max_frames: usize) -> Result<StepOutput> {
        let out = advance(&mut [self], &[frames], &[max_frames], false)?;
        Ok(out.into_iter().next().expect("one session, one output").0)
    }

    /// Feeds the input person's joint positions (`[n, 22, 3]`, t2m-22 joints, n may be 0,
    /// measured as [`Session::set_joints_format`] said) and returns the other person's poses
    /// that became ready, in the caller's world, after the motion stages that are on. Works on
    /// every stream whose frames the motion stages know (`docs/MOTION.md`); on error the session
    /// is unchanged.
    pub fn step_joints(&mut self, positions: ArrayView3<f32>) -> Result<Vec<Pose>> {
        self.step_joints_bounded(positions, usize::MAX)
    }

    /// [`Session::step_joints`] that fails, leaving the session unchanged, when more than
    /// `max_poses` poses would come out (the C ABI's caller-sized buffers).
    pub(crate) fn step_joints_bounded(
        &mut self,
        positions: ArrayView3<f32>,
        max_poses: usize,
    ) -> Result<Vec<Pose>> {
        let out = joints_bounded(&mut [self], &[positions], &[max_poses])?;
        Ok(out.into_iter().next().expect("one session, one output"))
    }

    /// Sets how [`Session::step_joints`] reads positions (units, up axis, handedness, frame
    /// rate; resampled to the stream's rate) and forgets the joint frames and placement it had.
    /// Without it, positions are metres, Y up, at the stream's rate.
    pub fn set_joints_format(&mut self, format: JointsFormat) -> Result<()> {
        self.motion.set_joints_format(format)
    }

    /// How many poses [`Session::step_joints`] returns for the next `n` joint frames.
    pub fn joints_ready_after(&self, n: usize) -> Result<usize> {
        let rows = self.motion.joints_input()?.rows_after(n);
        Ok(self.stream.frames_ready_after(rows))
    }

    /// Where the poses are put: fixed by the first joint frame for `interhuman262` streams
    /// (`None` before it), the caller's world for `magnet-smplx145` ones.
    pub fn joints_placement(&self) -> Option<Placement> {
        self.motion.joints_placement()
    }

    /// Frames of latency from a joint frame to the pose it completes: the stream's own plus
    /// what the conversion needs (one frame for features' velocities).
    pub fn joints_latency_frames(&self) -> Result<usize> {
        Ok(self.latency_frames() + self.motion.joints_latency_frames()?)
    }

    /// Turns the penetration guard on (with its settings) or off (`None`) for the frames sent
    /// from now on (`docs/MOTION.md`). Turning it on starts with no offset.
    pub fn set_penetration_guard(&mut self, guard: Option<PenetrationGuard>) -> Result<()> {
        let received = self.stream.frames_received();
        self.motion.set_guard(guard, received)
    }

    /// The penetration guard's settings, when it is on.
    pub fn penetration_guard(&self) -> Option<PenetrationGuard> {
        self.motion.guard()
    }

    /// Turns the root smoothing on (with its time constant) or off (`None`) for the frames sent
    /// from now on; turning it on starts from the next frame's root.
    pub fn set_root_smoothing(&mut self, smoothing: Option<RootSmoothing>) -> Result<()> {
        self.motion.set_smoothing(smoothing)
    }

    /// The root smoothing's setting, when it is on.
    pub fn root_smoothing(&self) -> Option<RootSmoothing> {
        self.motion.smoothing()
    }

    /// Turns the foot lock of the poses [`Session::step_joints`] returns on (with its settings)
    /// or off (`None`), from the next pose on, starting with no foot pinned. Needs frames with
    /// contact labels (`interhuman262`).
    pub fn set_foot_lock(&mut self, options: Option<FootLockOptions>) -> Result<()> {
        self.motion.set_foot_lock(options)
    }

    /// The foot lock's settings, when it is on.
    pub fn foot_lock(&self) -> Option<FootLockOptions> {
        self.motion.foot_lock()
    }

    /// Everything the stream needs to go on, as bytes: [`crate::Model::restore`] on the same
    /// model (in this process or another) gives a session whose steps are, bit for bit, this
    /// one's. Taken between steps, so it never holds half a step; the session is unchanged. A
    /// versioned, checksummed format (`docs/SNAPSHOTS.md`); [`Error::Unsupported`] for a family
    /// whose streams cannot be saved yet.
    pub fn snapshot(&self) -> Result<Vec<u8>> {
        let mut w = SnapshotWriter::new(
            self.family(),
            &self.stream.model_identity(),
            self.memory_bytes(),
        );
        self.stream.save(&mut w)?;
        self.motion.save(&mut w);
        Ok(w.finish())
    }

    /// [`Session::snapshot`] sealed under `key` (at least 16 bytes, which the caller keeps
    /// secret): [`crate::Model::restore_sealed`] with the same key restores it; another key, or
    /// any changed byte, is refused. For snapshot stores that others can write.
    pub fn snapshot_sealed(&self, key: &[u8]) -> Result<Vec<u8>> {
        crate::shared::sealed::seal(&self.snapshot()?, key)
    }

    /// Reads the motion stages a snapshot holds after the stream's part.
    pub(crate) fn load_motion(&mut self, r: &mut SnapshotReader) -> Result<()> {
        let received = self.stream.frames_received();
        self.motion.load(r, received)
    }

    /// Returns the session to the state of a fresh session with the current settings.
    pub fn reset(&mut self) {
        self.stream.reset();
        self.motion.reset();
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

    /// Sets the sampler's steps (>= 1): MeanFlow steps per token, DDIM steps per chunk, flow
    /// steps per frame.
    pub fn set_steps(&mut self, steps: u32) -> Result<()> {
        self.stream.set_steps(steps)
    }

    /// Sets the classifier-free guidance scale ([`Capability::CfgScale`]; finite), applied as
    /// the family's official sampler applies it (ARMFlow: guided only above 1). A stream without
    /// guidance accepts 1, the scale it runs at, and refuses any other.
    pub fn set_cfg_scale(&mut self, scale: f32) -> Result<()> {
        if scale == 1.0 && !self.capabilities().has(Capability::CfgScale) {
            return Ok(());
        }
        self.require(Capability::CfgScale)?;
        self.stream.set_cfg_scale(scale)
    }

    /// Sets the conditioning vector ([`Capability::Condition`]; `None`: the null condition),
    /// for what is generated from now on. A stream without conditioning accepts `None`, the
    /// condition it runs on, and refuses any other.
    pub fn set_condition(&mut self, condition: Option<&[f32]>) -> Result<()> {
        if condition.is_none() && !self.capabilities().has(Capability::Condition) {
            return Ok(());
        }
        self.require(Capability::Condition)?;
        self.stream.set_condition(condition)
    }

    /// Conditions what is generated from now on on a text prompt ([`Capability::Prompt`]:
    /// bundles with a text encoder).
    pub fn set_prompt(&mut self, prompt: &str) -> Result<()> {
        self.require(Capability::Prompt)?;
        self.stream.set_prompt(prompt)
    }

    /// Queues standard normals for the draws to come ([`Capability::QueuedNormals`]), to
    /// replay another implementation's stream exactly: each draw the sampler makes takes the
    /// next ones it needs while any are queued, then the seeded generator goes on (draw `i` its
    /// token `i`, as if the queued draws were its). The order per family: ARMFlow per token the
    /// actor's posterior then the reactor's start noise (`latent_dim` each, whole tokens only);
    /// MAGNet's live partner as its offline run (`docs/MAGNET.md`); ARFlow online per frame the
    /// start noise when σ > 0, then one ε per step when η > 0, 262 each. A draw that needs more
    /// than are left fails, the stream as it was. [`Session::reset`] drops them.
    pub fn queue_normals(&mut self, normals: &[f32]) -> Result<()> {
        self.require(Capability::QueuedNormals)?;
        check_input("queued normals", normals)?;
        self.stream.queue_normals(normals)
    }

    /// [`Error::Unsupported`] naming `cap` unless the stream takes it.
    fn require(&self, cap: Capability) -> Result<()> {
        if self.capabilities().has(cap) {
            Ok(())
        } else {
            Err(unsupported(self.family(), cap))
        }
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

    /// Bytes this session holds, bounded however long it runs (the model's weights, shared by
    /// all sessions, not counted).
    pub fn memory_bytes(&self) -> usize {
        self.stream.memory_bytes() + self.motion.bytes()
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

/// [`Session::step_joints`] for many sessions of one model at once, like [`step_sessions`]:
/// each session's joint positions (`[n_i, 22, 3]`) in, each session's poses out. On error no
/// session changes.
pub fn step_sessions_joints(
    sessions: &mut [&mut Session],
    positions: &[ArrayView3<f32>],
) -> Result<Vec<Vec<Pose>>> {
    joints_bounded(sessions, positions, &[])
}

/// [`step_sessions_joints`] that fails, changing no session, when session `i` would return
/// more than `max_poses[i]` poses (empty: unbounded).
fn joints_bounded(
    sessions: &mut [&mut Session],
    positions: &[ArrayView3<f32>],
    max_poses: &[usize],
) -> Result<Vec<Vec<Pose>>> {
    if positions.len() != sessions.len() {
        return Err(Error::InvalidInput(format!(
            "{} sessions but {} chunks of joint positions",
            sessions.len(),
            positions.len()
        )));
    }
    let indexed = sessions.len() > 1;
    let whose = |i: usize, e: Error| match e {
        Error::InvalidInput(m) if indexed => Error::InvalidInput(format!("session {i}: {m}")),
        other => other,
    };
    // Convert on copies of the stages' joint conversions, kept only when every step succeeds.
    let mut stages: Vec<MotionStages> = sessions.iter().map(|s| s.motion.clone()).collect();
    let mut frames: Vec<Vec<f32>> = Vec::with_capacity(sessions.len());
    for (i, (stage, chunk)) in stages.iter_mut().zip(positions).enumerate() {
        if chunk.shape()[1..] != [T2M22_JOINTS, 3] {
            return Err(whose(
                i,
                Error::InvalidInput(format!(
                    "joint positions must be [frames, 22, 3], got {:?}",
                    chunk.shape()
                )),
            ));
        }
        let mut input = stage.take_joints_input().map_err(|e| whose(i, e))?;
        let mut flat = Vec::new();
        for (t, frame) in chunk.outer_iter().enumerate() {
            input.push(frame, &mut flat).map_err(|e| match e {
                Error::InvalidInput(m) => whose(i, Error::InvalidInput(format!("frame {t}: {m}"))),
                other => other,
            })?;
        }
        stage.set_joints_input(input);
        frames.push(flat);
    }
    let chunks: Vec<&[f32]> = frames.iter().map(Vec::as_slice).collect();
    let out = advance_with(sessions, &chunks, max_poses, stages, true, indexed)?;
    Ok(out.into_iter().map(|(_, poses)| poses).collect())
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
    Ok(advance(sessions, frames, max_frames, true)?
        .into_iter()
        .map(|(out, _)| out)
        .collect())
}

/// Steps `sessions` on frames, their motion stages on copies.
fn advance(
    sessions: &mut [&mut Session],
    frames: &[&[f32]],
    max_frames: &[usize],
    indexed: bool,
) -> Result<Vec<(StepOutput, Vec<Pose>)>> {
    let stages = sessions.iter().map(|s| s.motion.clone()).collect();
    advance_with(sessions, frames, max_frames, stages, false, indexed)
}

/// The one step of every session and of many at once: checks each chunk of frames and the room
/// for its output (the only place that does), runs the stream's step (the family's batched step
/// for several) with `stages` shaping each output, and with `poses` decoding it, inside the
/// step; keeps the stages only when every session's step succeeded. With `indexed`, messages
/// name the session by its index.
fn advance_with(
    sessions: &mut [&mut Session],
    frames: &[&[f32]],
    max_frames: &[usize],
    mut stages: Vec<MotionStages>,
    poses: bool,
    indexed: bool,
) -> Result<Vec<(StepOutput, Vec<Pose>)>> {
    let Some(first) = sessions.first() else {
        return Ok(Vec::new());
    };
    let whose = |i: usize, e: Error| match e {
        Error::InvalidInput(m) if indexed => Error::InvalidInput(format!("session {i}: {m}")),
        Error::OutputTooSmall(m) if indexed => Error::OutputTooSmall(format!("session {i}: {m}")),
        other => other,
    };
    if let Some(i) = (1..sessions.len()).find(|&i| {
        sessions[i].family() != first.family() || !sessions[i].stream.same_model(&*first.stream)
    }) {
        return Err(Error::InvalidInput(format!(
            "session {i} runs another model: sessions stepped together must share one"
        )));
    }
    let mut starts = Vec::with_capacity(sessions.len());
    for (i, (session, chunk)) in sessions.iter().zip(frames).enumerate() {
        // The count is needed here; the values are checked by the family's step, which reads them.
        let dim = session.frame_dim();
        check_frame_count("input frames", chunk, dim).map_err(|e| whose(i, e))?;
        let out = session.stream.frames_ready_after(chunk.len() / dim);
        let max = max_frames.get(i).copied().unwrap_or(usize::MAX);
        if out > max {
            return Err(whose(
                i,
                Error::OutputTooSmall(format!(
                    "this call returns {out} frames, the output holds {max}"
                )),
            ));
        }
        stages[i].receive(chunk);
        starts.push(session.stream.frames_emitted());
    }
    let mut decoded: Vec<Vec<Pose>> = vec![Vec::new(); sessions.len()];
    let mut finish = |i: usize, out: &mut StepOutput| -> Result<()> {
        stages[i].shape(starts[i], out)?;
        if poses {
            let flat = out.frames.as_standard_layout();
            decoded[i] = stages[i].poses(flat.as_slice().expect("standard layout"))?;
        }
        Ok(())
    };
    let outputs = if sessions.len() == 1 && !indexed {
        vec![sessions[0].stream.step(frames[0], &mut finish)?]
    } else {
        let together = first.stream.step_together();
        let mut streams: Vec<&mut dyn Stream> =
            sessions.iter_mut().map(|s| &mut *s.stream).collect();
        together(&mut streams, frames, &mut finish)?
    };
    for (session, stages) in sessions.iter_mut().zip(stages) {
        session.motion = stages;
    }
    Ok(outputs.into_iter().zip(decoded).collect())
}
