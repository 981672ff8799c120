//! The motion stages a [`Session`](super::session::Session) runs around its family's stream,
//! chosen by the stream's frame layout, never by its family: joint positions in and poses out
//! (`joints.rs`), the root smoothing (`smoothing.rs`) and the penetration guard (`guard.rs`) on
//! the frames sent, and the foot lock on the poses. ARMFlow and ARFlow (`interhuman262`) get all
//! of them; MAGNet (`magnet-smplx145`) all but the foot lock, which needs contact labels.
//!
//! The stages of a step run on a copy that the session keeps only when the step succeeds, and
//! inside the stream's own step (its `finish`), so a failing stage undoes the step as well.

pub(crate) mod guard;
pub(crate) mod joints;
pub(crate) mod layout;
pub(crate) mod smoothing;

use std::sync::Arc;

use guard::GuardState;
pub use guard::PenetrationGuard;
use joints::JointsInput;
use layout::FrameLayout;
pub use smoothing::RootSmoothing;
use smoothing::SmoothingState;

use crate::family::stream::StepOutput;
use crate::motion::features::Pose;
use crate::motion::foot_lock::{FootLock, FootLockOptions};
use crate::motion::placement::Placement;
use crate::motion::world::JointsFormat;
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{bad, SnapshotReader, SnapshotWriter};

/// Frames the joints-in stage adds to the latency of a stream whose frames are `layout` (`dim`
/// floats): one for features, whose velocities and contacts wait for the next frame, none for
/// SMPL-X frames; `None` for a layout the stages do not know (its streams refuse joints).
pub(crate) fn joints_added_latency(layout: &str, dim: usize) -> Option<usize> {
    FrameLayout::of(layout, dim).map(JointsInput::latency_frames)
}

/// A session's motion stages: which are on, with their state.
#[derive(Debug, Clone)]
pub(crate) struct MotionStages {
    /// The stream's layout, when the stages know it (`None`: only frames in and out).
    layout: Option<FrameLayout>,
    /// Shared, so that copying the stages for a step allocates nothing for it.
    layout_name: Arc<str>,
    frame_dim: usize,
    fps: f32,
    guard: Option<(PenetrationGuard, GuardState)>,
    smoothing: Option<(RootSmoothing, SmoothingState)>,
    foot_lock: Option<FootLock>,
    /// The conversion of joint positions, once configured or used.
    joints: Option<JointsInput>,
}

impl MotionStages {
    /// No stage on, for a stream of `frame_dim`-float `layout` frames at `fps`.
    pub(crate) fn new(layout: &str, frame_dim: usize, fps: f32) -> Self {
        MotionStages {
            layout: FrameLayout::of(layout, frame_dim),
            layout_name: Arc::from(layout),
            frame_dim,
            fps,
            guard: None,
            smoothing: None,
            foot_lock: None,
            joints: None,
        }
    }

    /// The layout, or [`Error::Unsupported`] saying that `what` needs one the stages know.
    fn layout(&self, what: &str) -> Result<FrameLayout> {
        match self.layout {
            Some(layout) => Ok(layout),
            None => FrameLayout::required(&self.layout_name, self.frame_dim, what),
        }
    }

    /// Turns the guard on or off for the frames sent from now on; the stream has received
    /// `received` frames (the guard keeps the input's joints from there on).
    pub(crate) fn set_guard(
        &mut self,
        guard: Option<PenetrationGuard>,
        received: u64,
    ) -> Result<()> {
        if let Some(g) = &guard {
            self.layout("the penetration guard")?;
            g.check()?;
        }
        self.guard = guard.map(|g| (g, GuardState::starting_at(received)));
        Ok(())
    }

    /// The guard's settings, when it is on.
    pub(crate) fn guard(&self) -> Option<PenetrationGuard> {
        self.guard.as_ref().map(|(g, _)| *g)
    }

    /// Turns the root smoothing on or off, from the next frame's root.
    pub(crate) fn set_smoothing(&mut self, smoothing: Option<RootSmoothing>) -> Result<()> {
        if let Some(s) = &smoothing {
            self.layout("the root smoothing")?;
            s.check()?;
        }
        self.smoothing = smoothing.map(|s| (s, SmoothingState::default()));
        Ok(())
    }

    /// The root smoothing's setting, when it is on.
    pub(crate) fn smoothing(&self) -> Option<RootSmoothing> {
        self.smoothing.as_ref().map(|(s, _)| *s)
    }

    /// Turns the foot lock of the poses sent on or off, starting with no foot pinned.
    pub(crate) fn set_foot_lock(&mut self, options: Option<FootLockOptions>) -> Result<()> {
        if options.is_some() && self.layout("the foot lock")? != FrameLayout::Features {
            return Err(Error::Unsupported(format!(
                "the foot lock needs foot contact labels, which `{}` frames do not carry",
                self.layout_name
            )));
        }
        self.foot_lock = options.map(FootLock::new).transpose()?;
        Ok(())
    }

    /// The foot lock's settings, when it is on.
    pub(crate) fn foot_lock(&self) -> Option<FootLockOptions> {
        self.foot_lock.as_ref().map(FootLock::options)
    }

    /// Sets how joint positions are measured, forgetting the motion the conversion had.
    pub(crate) fn set_joints_format(&mut self, format: JointsFormat) -> Result<()> {
        let layout = self.layout("joint positions")?;
        self.joints = Some(JointsInput::new(layout, format, self.fps)?);
        Ok(())
    }

    /// The conversion of joint positions: the configured one, or metres, Y up, at the stream's
    /// rate.
    pub(crate) fn joints_input(&self) -> Result<JointsInput> {
        match &self.joints {
            Some(j) => Ok(j.clone()),
            None => self.default_joints_input(),
        }
    }

    /// [`MotionStages::joints_input`], taken out of these stages (put it back with
    /// [`MotionStages::set_joints_input`]).
    pub(crate) fn take_joints_input(&mut self) -> Result<JointsInput> {
        match self.joints.take() {
            Some(j) => Ok(j),
            None => self.default_joints_input(),
        }
    }

    /// Metres, Y up, at the stream's rate.
    fn default_joints_input(&self) -> Result<JointsInput> {
        let layout = self.layout("joint positions")?;
        JointsInput::new(
            layout,
            JointsFormat {
                fps: self.fps,
                ..JointsFormat::default()
            },
            self.fps,
        )
    }

    /// Frames of latency the joint conversion adds.
    pub(crate) fn joints_latency_frames(&self) -> Result<usize> {
        Ok(JointsInput::latency_frames(self.layout("joint positions")?))
    }

    /// Where poses are put (`None` before the first joint frame fixed it).
    pub(crate) fn joints_placement(&self) -> Option<Placement> {
        self.joints.as_ref().and_then(JointsInput::placement)
    }

    /// Puts the conversion a joint step used (and advanced) in place.
    pub(crate) fn set_joints_input(&mut self, input: JointsInput) {
        self.joints = Some(input);
    }

    /// Takes note of the input frames of a step (the guard's view of the input person).
    pub(crate) fn receive(&mut self, frames: &[f32]) {
        if let (Some(layout), Some((_, state))) = (self.layout, &mut self.guard) {
            state.push_actor(layout, frames, self.frame_dim);
        }
    }

    /// Shapes the frames a step sends (the first of them frame `first`): the root smoothing,
    /// then the penetration guard, each when on.
    pub(crate) fn shape(&mut self, first: u64, output: &mut StepOutput) -> Result<()> {
        let Some(layout) = self.layout else {
            return Ok(());
        };
        let fps = f64::from(self.fps);
        if let Some((settings, state)) = &mut self.smoothing {
            state.apply(layout, settings, &mut output.frames, fps);
        }
        if let Some((settings, state)) = &mut self.guard {
            state.apply(layout, settings, &mut output.frames, first, fps)?;
        }
        Ok(())
    }

    /// The poses of shaped output frames, in the caller's world, after the foot lock.
    pub(crate) fn poses(&mut self, frames: &[f32]) -> Result<Vec<Pose>> {
        let layout = self.layout("joint positions")?;
        // Output frames exist only after input frames, which placed the conversion.
        let Some(placement) = self.joints_placement() else {
            return Ok(Vec::new());
        };
        joints::poses(
            layout,
            frames,
            self.frame_dim,
            &placement,
            self.foot_lock.as_mut(),
        )
    }

    /// Back to a fresh session's stages with the current settings.
    pub(crate) fn reset(&mut self) {
        if let Some((_, state)) = &mut self.guard {
            *state = GuardState::starting_at(0);
        }
        if let Some((_, state)) = &mut self.smoothing {
            *state = SmoothingState::default();
        }
        if let Some(lock) = &mut self.foot_lock {
            lock.reset();
        }
        if let Some(joints) = &mut self.joints {
            joints.reset();
        }
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.guard.as_ref().map_or(0, |(_, s)| s.bytes())
    }

    /// Writes the stages' settings and state.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        w.bool(self.guard.is_some());
        if let Some((g, state)) = &self.guard {
            w.f64(g.d_safe).f64(g.max_speed);
            state.save(w);
        }
        w.bool(self.smoothing.is_some());
        if let Some((s, state)) = &self.smoothing {
            w.f64(s.time_constant);
            state.save(w);
        }
        w.bool(self.foot_lock.is_some());
        if let Some(lock) = &self.foot_lock {
            lock.save(w);
        }
        w.bool(self.joints.is_some());
        if let Some(joints) = &self.joints {
            joints.save(w);
        }
    }

    /// Reads back what [`MotionStages::save`] wrote, into these (fresh) stages of a stream that
    /// has received `received` frames; every setting is checked as its setter checks it.
    pub(crate) fn load(&mut self, r: &mut SnapshotReader, received: u64) -> Result<()> {
        let on = |r: &mut SnapshotReader, what: &str| r.bool(what);
        if on(r, "whether the guard is on")? {
            let guard = PenetrationGuard {
                d_safe: r.f64("the guard's margin")?,
                max_speed: r.f64("the guard's speed")?,
            };
            self.set_guard(Some(guard), received)?;
            let state = GuardState::load(r, received)?;
            self.guard = Some((guard, state));
        }
        if on(r, "whether the smoothing is on")? {
            let smoothing = RootSmoothing {
                time_constant: r.f64("the smoothing's time constant")?,
            };
            self.set_smoothing(Some(smoothing))?;
            self.smoothing = Some((smoothing, SmoothingState::load(r)?));
        }
        if on(r, "whether the foot lock is on")? {
            if self.layout != Some(FrameLayout::Features) {
                return Err(bad("a foot lock on frames without contact labels"));
            }
            self.foot_lock = Some(FootLock::load(r)?);
        }
        if on(r, "whether joint positions are read")? {
            let layout = self
                .layout("joint positions")
                .map_err(|_| bad("joint positions on a layout that has none"))?;
            self.joints = Some(JointsInput::load(layout, r)?);
        }
        Ok(())
    }
}
