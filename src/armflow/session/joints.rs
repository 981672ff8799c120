//! Joint positions in, poses out: a session for callers that never touch the feature vector.
//!
//! The actor's positions go through a [`FeatureStream`] (one frame of extra latency: velocities
//! and contacts need the next frame), and the reactor's features come back as [`Pose`]s in the
//! caller's world, placed by the actor's first frame, after the foot lock (when on) has kept
//! their feet still in the stream's canonical frame.

use ndarray::ArrayView3;

use super::{step_reactors_bounded, Reactor};
use crate::motion::{
    decode_canonical, joints_layout, FeatureStream, JointsFormat, Placement, Pose,
    STREAM_LATENCY_FRAMES, T2M22_JOINTS,
};
use crate::shared::error::{Error, Result};

impl Reactor {
    /// Sets how [`Reactor::step_joints`] reads actor positions (units, up axis, handedness,
    /// frame rate; resampled to the bundle's rate) and forgets the actor frames and placement
    /// the joint stream had. Without it, positions are metres, Y up, at the bundle's rate.
    pub fn set_joints_format(&mut self, format: JointsFormat) -> Result<()> {
        joints_layout(&self.nets.io.motion)?;
        self.joints = Some(FeatureStream::new(
            format,
            self.nets.io.motion.fps as f32,
            None,
        )?);
        Ok(())
    }

    /// The joint stream's placement: where the reactor's poses are put, fixed by the first actor
    /// frame given to [`Reactor::step_joints`] (`None` before it).
    pub fn joints_placement(&self) -> Option<&Placement> {
        self.joints.as_ref().and_then(|j| j.placement())
    }

    /// Frames of latency from an actor joint frame to the reactor pose it completes: the
    /// session's own ([`crate::Model::latency_frames`]) plus the one frame features need.
    pub fn joints_latency_frames(&self) -> usize {
        self.latency_frames() + STREAM_LATENCY_FRAMES
    }

    /// Feeds actor joint positions (`[n, 22, 3]`, n may be 0, measured as
    /// [`Reactor::set_joints_format`] said) and returns the reactor poses that became ready, in
    /// the caller's world. On error the session, joint stream included, is unchanged.
    pub fn step_joints(&mut self, actor: ArrayView3<f32>) -> Result<Vec<Pose>> {
        let mut out = step_reactors_joints(&mut [self], &[actor])?;
        Ok(out.pop().expect("one session, one result"))
    }

    /// How many reactor poses [`Reactor::step_joints`] returns for the next `n` actor joint
    /// frames (what a caller's buffer must hold).
    pub fn joints_ready_after(&self, n: usize) -> Result<usize> {
        Ok(self.frames_ready_after(self.joint_stream()?.rows_after(n)))
    }

    fn joint_stream(&self) -> Result<FeatureStream> {
        joints_layout(&self.nets.io.motion)?;
        match &self.joints {
            Some(s) => Ok(s.clone()),
            None => {
                let fps = self.nets.io.motion.fps as f32;
                let format = JointsFormat {
                    fps,
                    ..JointsFormat::default()
                };
                FeatureStream::new(format, fps, None)
            }
        }
    }
}

/// [`Reactor::step_joints`] for many sessions of one model at once, like
/// [`super::step_reactors`]: each session's actor positions (`[n_i, 22, 3]`) in, each
/// session's reactor poses out. On error no session changes.
pub fn step_reactors_joints(
    sessions: &mut [&mut Reactor],
    actor: &[ArrayView3<f32>],
) -> Result<Vec<Vec<Pose>>> {
    if actor.len() != sessions.len() {
        return Err(Error::InvalidInput(format!(
            "{} sessions but {} chunks of actor joints",
            sessions.len(),
            actor.len()
        )));
    }
    // Convert on copies of the joint streams, committed only when every step succeeds.
    let mut streams = Vec::with_capacity(sessions.len());
    let mut features: Vec<Vec<f32>> = Vec::with_capacity(sessions.len());
    for (i, (session, chunk)) in sessions.iter().zip(actor).enumerate() {
        let context = |e: Error| match e {
            Error::InvalidInput(m) if sessions.len() > 1 => {
                Error::InvalidInput(format!("session {i}: {m}"))
            }
            other => other,
        };
        if chunk.shape()[1..] != [T2M22_JOINTS, 3] {
            return Err(context(Error::InvalidInput(format!(
                "actor joints must be [frames, 22, 3], got {:?}",
                chunk.shape()
            ))));
        }
        let mut stream = session.joint_stream().map_err(context)?;
        let mut flat = Vec::new();
        for (t, frame) in chunk.outer_iter().enumerate() {
            let rows = stream.push(frame).map_err(|e| match e {
                Error::InvalidInput(m) => context(Error::InvalidInput(format!("frame {t}: {m}"))),
                other => other,
            })?;
            flat.extend(rows.iter().flatten());
        }
        streams.push(stream);
        features.push(flat);
    }
    let chunks: Vec<&[f32]> = features.iter().map(Vec::as_slice).collect();
    let outputs = step_reactors_bounded(sessions, &chunks, &[])?;
    let mut poses = Vec::with_capacity(sessions.len());
    for ((session, stream), output) in sessions.iter_mut().zip(streams).zip(outputs) {
        // Reactor frames exist only after actor frames, which placed the stream. The session's
        // output is finite (it refuses non-finite steps), so decoding cannot fail.
        let frames = match stream.placement() {
            Some(placement) => output
                .frames
                .outer_iter()
                .map(|row| {
                    let mut pose = decode_canonical(row)?;
                    if let Some(lock) = &mut session.foot_lock {
                        lock.apply(&mut pose);
                    }
                    Ok(pose.placed(placement))
                })
                .collect::<Result<Vec<_>>>()?,
            None => Vec::new(),
        };
        session.joints = Some(stream);
        poses.push(frames);
    }
    Ok(poses)
}
