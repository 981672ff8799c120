//! The penetration guard of a stream: the frames a step sends are pulled out of the input
//! person's body (`crate::motion::penetration`), in the stream's own frames (any layout whose
//! joints [`FrameLayout`] knows), by a rule that keeps the frames consistent and cannot make the
//! motion jump.
//!
//! The rule, per output frame `t` (in the stream's one world, y up):
//! 1. The reactor keeps an offset `o` in the floor plane (x, z), carried from frame to frame.
//! 2. If the reactor's joints at `o` moved toward 0 by one step are clear of the actor's body
//!    (no joint nearer than `d_safe`), that is the target: the reactor returns to its own motion.
//!    Otherwise the target is found from `o` by steps of a quarter step against the penetration
//!    loss's gradient summed over the joints, projected on the floor, until the joints are clear
//!    (at most 16 steps).
//! 3. The offset moves toward the target by at most one step, `max_speed / fps`: the guard
//!    never moves the reactor faster than that, so it cannot make the motion jump.
//! 4. Every joint position moves by the offset (a rigid shift: rotations and the body's shape are
//!    unchanged), and in `interhuman262` every joint velocity (`p[t+1] − p[t]`) by the offset's
//!    own change from the previous frame; contacts are left as decoded.
//!
//! The network's own history is not changed: the guard shapes what is sent. Output frame `t` is
//! checked against input frame `t` (the two people share one timeline in every family).

use std::collections::VecDeque;

use ndarray::Array2;

use super::layout::FrameLayout;
use crate::motion::body::{BodyModel, Reach};
#[cfg(doc)]
use crate::motion::penetration::PenetrationLoss;
use crate::motion::skeleton::T2M22_JOINTS;
use crate::motion::vec3::Vec3;
use crate::motion::world::MAX_WORLD_METRES;
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{self, SnapshotReader, SnapshotWriter};

const JOINTS: usize = T2M22_JOINTS;
const SEARCH_STEPS: usize = 16;

/// The guard's settings (off unless a session sets one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenetrationGuard {
    /// Joints nearer the actor's body than this, metres, are pushed out (in [0, 0.5]).
    pub d_safe: f64,
    /// The fastest the guard moves the reactor, metres per second (in (0, 10]).
    pub max_speed: f64,
}

impl Default for PenetrationGuard {
    fn default() -> Self {
        // Measured on the demo model (docs/ARFLOW.md): a 5 cm margin and 2 m/s remove most of
        // the depth without a push faster than a brisk walk.
        PenetrationGuard {
            d_safe: 0.05,
            max_speed: 2.0,
        }
    }
}

impl PenetrationGuard {
    /// Checks the settings' ranges.
    pub fn check(&self) -> Result<()> {
        if !(self.d_safe.is_finite() && (0.0..=0.5).contains(&self.d_safe)) {
            return Err(Error::InvalidOption(format!(
                "penetration guard: d_safe {} m is not in [0, 0.5] m",
                self.d_safe
            )));
        }
        if !(self.max_speed.is_finite() && self.max_speed > 0.0 && self.max_speed <= 10.0) {
            return Err(Error::InvalidOption(format!(
                "penetration guard: max_speed {} m/s is not in (0, 10] m/s",
                self.max_speed
            )));
        }
        Ok(())
    }
}

/// What the guard carries between steps: its offset and the input person's joints for the
/// frames not yet sent.
#[derive(Debug, Clone, Default)]
pub(crate) struct GuardState {
    offset: [f64; 2],
    /// The actor's joint positions (66 floats) from frame `base` on.
    actor: VecDeque<Vec<f32>>,
    base: u64,
}

/// The linear penetration loss of `pose` moved by `o` on the floor against the actor's body,
/// and its gradient with respect to `o` (the joints' gradients summed, x and z): what
/// [`PenetrationLoss::evaluate`] gives with the linear hinge, to the bit, without building a
/// gradient per joint. `reach` is the actor's [`BodyModel::reach`] at `d_safe`.
fn floor_push(
    body: &BodyModel,
    reach: &Reach,
    actor: &[Vec3],
    pose: &[Vec3],
    o: [f64; 2],
    d_safe: f64,
) -> (f64, [f64; 2]) {
    let (mut loss, mut g) = (0.0, [0.0, 0.0]);
    for p in pose {
        let p = [p[0] + o[0], p[1], p[2] + o[1]];
        if reach.beyond(p) {
            continue;
        }
        let sd = body.signed_distance(actor, p);
        let x = d_safe - sd.distance;
        if x > 0.0 {
            loss += x;
            g = [g[0] - sd.gradient[0], g[1] - sd.gradient[2]];
        }
    }
    (loss, g)
}

/// `to` moved toward `from` so that it is at most `limit` away from it.
fn clamp_move(from: [f64; 2], to: [f64; 2], limit: f64) -> [f64; 2] {
    let d = [to[0] - from[0], to[1] - from[1]];
    let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
    if n <= limit {
        to
    } else {
        [from[0] + d[0] * limit / n, from[1] + d[1] * limit / n]
    }
}

impl GuardState {
    /// No offset, the actor's joints kept from frame `frame` on.
    pub(crate) fn starting_at(frame: u64) -> Self {
        GuardState {
            base: frame,
            ..Default::default()
        }
    }

    /// Keeps the joint positions of the input person's new frames (`frame_dim` floats each).
    pub(crate) fn push_actor(&mut self, layout: FrameLayout, frames: &[f32], frame_dim: usize) {
        for f in frames.chunks_exact(frame_dim) {
            let joints = layout.joints(f);
            self.actor
                .push_back(joints.iter().flat_map(|p| p.map(|v| v as f32)).collect());
        }
    }

    /// Guards `frames` (the output's, `[n, frame_dim]`, the first of them frame `first`), then
    /// forgets the input's frames before the next one to send.
    pub(crate) fn apply(
        &mut self,
        layout: FrameLayout,
        guard: &PenetrationGuard,
        frames: &mut Array2<f32>,
        first: u64,
        fps: f64,
    ) -> Result<()> {
        let body = BodyModel::t2m22();
        let step = guard.max_speed / fps;
        for (i, mut frame) in frames.outer_iter_mut().enumerate() {
            let index = first + i as u64;
            let Some(actor) = index
                .checked_sub(self.base)
                .and_then(|k| self.actor.get(k as usize))
            else {
                continue; // no actor frame for it (cannot happen in a stream): sent as decoded
            };
            let actor: Vec<Vec3> = actor
                .chunks_exact(3)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
                .collect();
            let pose = layout.joints(frame.as_slice().expect("rows of a standard-layout array"));
            if !actor.iter().chain(&pose).flatten().all(|v| v.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "penetration guard: frame {index} holds a non-finite joint position"
                )));
            }
            let previous = self.offset;
            let released = clamp_move(previous, [0.0, 0.0], step);
            let reach = body.reach(&actor, guard.d_safe);
            // Clear means a zero loss: every joint at least `d_safe` from the actor's body (the
            // first joint too near answers).
            let clear = |o: [f64; 2]| {
                pose.iter().all(|p| {
                    let p = [p[0] + o[0], p[1], p[2] + o[1]];
                    reach.beyond(p) || body.signed_distance(&actor, p).distance >= guard.d_safe
                })
            };
            let target = if clear(released) {
                released
            } else {
                let mut o = previous;
                for _ in 0..SEARCH_STEPS {
                    let (loss, g) = floor_push(&body, &reach, &actor, &pose, o, guard.d_safe);
                    if loss == 0.0 {
                        break;
                    }
                    let n = (g[0] * g[0] + g[1] * g[1]).sqrt();
                    if n == 0.0 {
                        break;
                    }
                    o = [o[0] - 0.25 * step * g[0] / n, o[1] - 0.25 * step * g[1] / n];
                }
                o
            };
            let o = clamp_move(previous, target, step);
            layout.shift_on_floor(
                frame
                    .as_slice_mut()
                    .expect("rows of a standard-layout array"),
                o,
                previous,
            );
            self.offset = o;
        }
        let next = first + frames.nrows() as u64;
        while self.base < next && !self.actor.is_empty() {
            self.actor.pop_front();
            self.base += 1;
        }
        Ok(())
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.actor.iter().map(Vec::capacity).sum::<usize>() * std::mem::size_of::<f32>()
    }

    /// Writes the offset and the actor's kept joints.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        w.f64(self.offset[0]).f64(self.offset[1]).u64(self.base);
        w.u64(self.actor.len() as u64);
        for joints in &self.actor {
            w.f32s(joints);
        }
    }

    /// The state [`GuardState::save`] wrote, of a stream that has received `received` frames
    /// (the kept joints are of frames it received: at most `received - base` of them).
    pub(crate) fn load(r: &mut SnapshotReader, received: u64) -> Result<Self> {
        let offset = [
            r.metres("the guard's offset", MAX_WORLD_METRES)?,
            r.metres("the guard's offset", MAX_WORLD_METRES)?,
        ];
        let base = r.u64("the guard's first frame")?;
        let kept = received.checked_sub(base).ok_or_else(|| {
            snapshot::bad(format!(
                "the guard keeps frames from {base} on, the stream received {received}"
            ))
        })?;
        let n = r.count("the guard's frames", kept.min(usize::MAX as u64) as usize)?;
        let actor = (0..n)
            .map(|_| r.f32s_exact("the guard's actor joints", 3 * JOINTS))
            .collect::<Result<_>>()?;
        Ok(GuardState {
            offset,
            actor,
            base,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::penetration::{Hinge, PenetrationLoss};
    use crate::motion::skeleton::Skeleton;

    fn shifted(pose: &[Vec3], o: [f64; 2]) -> Vec<Vec3> {
        pose.iter()
            .map(|p| [p[0] + o[0], p[1], p[2] + o[1]])
            .collect()
    }

    #[test]
    fn the_floor_push_is_the_linear_losses_summed_gradient() {
        let body = BodyModel::t2m22();
        let actor = Skeleton::t2m22().rest_positions();
        let loss = PenetrationLoss {
            d_safe: 0.25,
            hinge: Hinge::Linear,
        };
        let reach = body.reach(&actor, loss.d_safe);
        let mut inside = 0;
        for step in 0..30 {
            let o = [0.08 * f64::from(step) - 0.3, 0.01 * f64::from(step % 5)];
            let pose = shifted(&actor, [0.05, 0.02]);
            let want = loss
                .evaluate(&body, std::slice::from_ref(&actor), &[shifted(&pose, o)])
                .unwrap();
            let summed = want.gradient[0]
                .iter()
                .fold([0.0, 0.0], |s, g| [s[0] + g[0], s[1] + g[2]]);
            let (got, g) = floor_push(&body, &reach, &actor, &pose, o, loss.d_safe);
            assert_eq!(got, want.loss, "offset {o:?}");
            assert_eq!(g, summed, "offset {o:?}");
            inside += usize::from(got > 0.0);
        }
        // Offsets from overlapping to clear: both cases were compared.
        assert!(inside > 0 && inside < 30, "{inside} of 30 offsets overlap");
    }
}
