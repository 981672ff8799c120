//! Foot locking: a causal clean-up of a generated stream that keeps a foot still while the
//! motion says it is on the ground.
//!
//! Generated feet slide: a network predicts each frame's ankle to a few centimetres, and a few
//! centimetres a frame is a visible skate. The motion's own contact labels (the `interhuman262`
//! layout carries four, ankle and toe of each foot) say when a foot should not move, so:
//!
//! - when a foot's ankle contact label rises above the threshold, the ankle is pinned where it
//!   is in that frame (not while a release is under way);
//! - while the label stays on, the leg is solved by two-bone IK (hip fixed, knee bent in the
//!   leg's own plane) so the ankle stays on the pin, the foot keeping its orientation;
//! - when the label drops, or the motion's ankle has walked farther than `max_stretch` from the
//!   pin (a contact the motion itself abandoned), the ankle returns to the motion over
//!   `release_frames` frames, linearly, so nothing jumps.
//!
//! It works frame by frame on what the stream already produced: no frame is held back, no
//! latency added. Positions and rotations stay consistent (the leg's local rotations are turned
//! with its bones).

use crate::motion::features::CanonicalPose;
use crate::motion::ik::{two_bone_turns, TwoBoneTurns};
use crate::motion::rotation::Quat;
use crate::motion::vec3::{add, cross, load_points, norm, save_points, scale, sub, Vec3};
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};

/// t2m-22 legs: hip, knee, ankle, toe (left, right), and the index of the ankle's contact label.
const LEGS: [([usize; 4], usize); 2] = [([1, 4, 7, 10], 0), ([2, 5, 8, 11], 2)];

/// The foot lock's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootLockOptions {
    /// A foot is in contact while its ankle's contact label is at least this (in (0, 1]).
    pub contact_threshold: f32,
    /// Frames over which a released foot returns to the motion (1 to 60).
    pub release_frames: u32,
    /// A pinned ankle is let go when the motion's ankle is farther than this from the pin,
    /// metres (in (0, 1]).
    pub max_stretch: f64,
}

impl Default for FootLockOptions {
    fn default() -> Self {
        // Tuned on the demo model's held-out streams (docs/DEMO.md): 0.5 is the labels'
        // midpoint; 4 frames (0.13 s at 30 fps) hide the release; 0.25 m lets a pinned foot
        // follow a body that turns or leans without the knee locking straight.
        FootLockOptions {
            contact_threshold: 0.5,
            release_frames: 4,
            max_stretch: 0.25,
        }
    }
}

impl FootLockOptions {
    /// Checks the settings' ranges.
    pub fn check(&self) -> Result<()> {
        if !(self.contact_threshold > 0.0 && self.contact_threshold <= 1.0) {
            return Err(Error::InvalidOption(format!(
                "foot lock: contact_threshold {} is not in (0, 1]",
                self.contact_threshold
            )));
        }
        if !(1..=60).contains(&self.release_frames) {
            return Err(Error::InvalidOption(format!(
                "foot lock: release_frames {} is not in 1 to 60",
                self.release_frames
            )));
        }
        if !(self.max_stretch.is_finite() && self.max_stretch > 0.0 && self.max_stretch <= 1.0) {
            return Err(Error::InvalidOption(format!(
                "foot lock: max_stretch {} m is not in (0, 1] m",
                self.max_stretch
            )));
        }
        Ok(())
    }
}

/// One foot's state.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Foot {
    /// Where the ankle is pinned while in contact.
    pin: Option<Vec3>,
    /// A release in progress: where it started and the frames done.
    release: Option<(Vec3, u32)>,
}

/// The foot lock of one stream (its state is the two feet's pins), so one per stream.
#[derive(Debug, Clone, PartialEq)]
pub struct FootLock {
    options: FootLockOptions,
    feet: [Foot; 2],
}

impl FootLock {
    /// A foot lock with `options`, refused when a setting is out of range.
    pub fn new(options: FootLockOptions) -> Result<Self> {
        options.check()?;
        Ok(FootLock {
            options,
            feet: [Foot::default(); 2],
        })
    }

    /// Its settings.
    pub fn options(&self) -> FootLockOptions {
        self.options
    }

    /// Writes the settings and the two feet's pins to a snapshot.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        let o = self.options;
        w.f32(o.contact_threshold)
            .u32(o.release_frames)
            .f64(o.max_stretch);
        for foot in &self.feet {
            save_points(w, foot.pin.as_ref().map(std::slice::from_ref));
            save_points(
                w,
                foot.release.as_ref().map(|(p, _)| std::slice::from_ref(p)),
            );
            w.u32(foot.release.map_or(0, |(_, done)| done));
        }
    }

    /// The foot lock [`FootLock::save`] wrote (its settings checked as [`FootLock::new`] does).
    pub(crate) fn load(r: &mut SnapshotReader) -> Result<Self> {
        let options = FootLockOptions {
            contact_threshold: r.f32("the foot lock's threshold")?,
            release_frames: r.u32("the foot lock's release")?,
            max_stretch: r.f64("the foot lock's stretch")?,
        };
        let mut lock = FootLock::new(options)?;
        for foot in &mut lock.feet {
            let one = |r: &mut SnapshotReader, what| -> Result<Option<Vec3>> {
                Ok(load_points(r, what, 1)?.map(|p| p[0]))
            };
            foot.pin = one(r, "a foot's pin")?;
            let release = one(r, "a foot's release")?;
            let done = r.u32("a foot's release frames")?;
            foot.release = release.map(|p| (p, done));
        }
        Ok(lock)
    }

    /// Forgets the pins (a new stream).
    pub fn reset(&mut self) {
        self.feet = [Foot::default(); 2];
    }

    /// Cleans up the next frame of the stream in place.
    pub fn apply(&mut self, pose: &mut CanonicalPose) {
        for (k, ([hip, knee, ankle, toe], label)) in LEGS.into_iter().enumerate() {
            let contact = pose.contacts[label] >= self.options.contact_threshold;
            let free = pose.positions[ankle];
            let target = self.target(k, free, contact);
            if norm(sub(target, free)) < 1e-9 {
                continue;
            }
            let p = &pose.positions;
            let hint = cross(sub(p[ankle], p[knee]), sub(p[hip], p[knee]));
            let Some(TwoBoneTurns { swing, bend }) =
                two_bone_turns([p[hip], p[knee], p[ankle]], target, hint)
            else {
                continue;
            };
            turn_leg(pose, [hip, knee, ankle, toe], swing, bend);
        }
    }

    /// Where foot `k`'s ankle goes this frame: the motion's, pinned while in contact and
    /// released smoothly.
    fn target(&mut self, k: usize, free: Vec3, contact: bool) -> Vec3 {
        let foot = &mut self.feet[k];
        let target = match foot.pin {
            Some(pin) if contact && norm(sub(pin, free)) <= self.options.max_stretch => pin,
            Some(pin) => {
                foot.pin = None;
                foot.release = Some((pin, 0));
                free
            }
            // A new contact pins the foot where it is now; not while a release is under way
            // (a contact the motion walked away from is not taken up again at once).
            None if contact && foot.release.is_none() => {
                foot.pin = Some(free);
                free
            }
            None => free,
        };
        match (foot.pin, foot.release) {
            (None, Some((from, done))) => {
                let total = self.options.release_frames;
                let done = done + 1;
                foot.release = (done < total).then_some((from, done));
                let t = f64::from(done) / f64::from(total);
                add(scale(from, 1.0 - t), scale(free, t))
            }
            _ => target,
        }
    }
}

/// Turns a leg by the IK's world turns: the thigh by `swing`, the shin by `swing * bend`, the
/// foot keeping its world orientation; positions and local rotations both.
fn turn_leg(
    pose: &mut CanonicalPose,
    [hip, knee, ankle, toe]: [usize; 4],
    swing: Quat,
    bend: Quat,
) {
    // World rotations of the pelvis and the leg's joints (each turns its children's offsets).
    let pelvis = pose.rotations[0];
    let w_hip = pelvis * pose.rotations[hip];
    let w_knee = w_hip * pose.rotations[knee];
    let w_ankle = w_knee * pose.rotations[ankle];
    let new_hip = swing * w_hip;
    let new_knee = swing * bend * w_knee;
    pose.rotations[hip] = (pelvis.conj() * new_hip).normalized();
    pose.rotations[knee] = (new_hip.conj() * new_knee).normalized();
    pose.rotations[ankle] = (new_knee.conj() * w_ankle).normalized();

    let p = &mut pose.positions;
    let (h, kn, a, t) = (p[hip], p[knee], p[ankle], p[toe]);
    let new_kn = add(h, swing.rotate(sub(kn, h)));
    let new_a = add(new_kn, (swing * bend).rotate(sub(a, kn)));
    p[knee] = new_kn;
    p[ankle] = new_a;
    p[toe] = add(new_a, sub(t, a));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::ik::forward_kinematics;
    use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};

    /// The neutral body at `root` with its knees bent (so a pinned foot can be reached), its
    /// legs' contacts as given.
    fn standing(root: Vec3, contacts: [f32; 4]) -> CanonicalPose {
        let skeleton = Skeleton::t2m22();
        let mut local = [Quat::IDENTITY; T2M22_JOINTS];
        for (hip, knee, ankle) in [(1, 4, 7), (2, 5, 8)] {
            local[hip] = Quat::from_axis_angle([1.0, 0.0, 0.0], -0.4);
            local[knee] = Quat::from_axis_angle([1.0, 0.0, 0.0], 0.8);
            local[ankle] = Quat::from_axis_angle([1.0, 0.0, 0.0], -0.4);
        }
        let positions = forward_kinematics(&skeleton, root, &local);
        CanonicalPose {
            positions: positions.try_into().unwrap(),
            rotations: local,
            contacts,
        }
    }

    #[test]
    fn a_foot_in_contact_stays_put_and_is_released_over_the_frames_asked() {
        let options = FootLockOptions::default();
        let mut lock = FootLock::new(options).unwrap();
        let mut ankles = Vec::new();
        // The body drifts 1 cm a frame in x; the left foot is in contact for 10 frames.
        for t in 0..20 {
            let on = if t < 10 { 1.0 } else { 0.0 };
            let mut pose = standing([0.01 * t as f64, 0.9, 0.0], [on, on, 0.0, 0.0]);
            let free_left = pose.positions[7];
            let free_right = pose.positions[8];
            lock.apply(&mut pose);
            assert_eq!(pose.positions[8], free_right, "the right foot is free");
            ankles.push((pose.positions[7], free_left));
        }
        for (pinned, _) in &ankles[..10] {
            assert!(norm(sub(*pinned, ankles[0].0)) < 1e-6, "{pinned:?}");
        }
        // Released over 4 frames: each a quarter of the way back, then free.
        for (i, (got, free)) in ankles[10..14].iter().enumerate() {
            let t = (i + 1) as f64 / 4.0;
            let want = add(scale(ankles[0].0, 1.0 - t), scale(*free, t));
            assert!(
                norm(sub(*got, want)) < 1e-6,
                "frame {}: {got:?} {want:?}",
                10 + i
            );
        }
        for (got, free) in &ankles[14..] {
            assert!(norm(sub(*got, *free)) < 1e-9);
        }
    }

    #[test]
    fn a_locked_leg_keeps_its_bones_and_its_rotations_reproduce_its_positions() {
        let mut lock = FootLock::new(FootLockOptions::default()).unwrap();
        let skeleton = Skeleton::t2m22();
        let mut first = standing([0.0, 0.9, 0.0], [1.0; 4]);
        lock.apply(&mut first);
        // The body moves 10 cm forward and 3 cm down: both ankles must stay, the knees bend.
        let mut pose = standing([0.0, 0.87, 0.1], [1.0; 4]);
        let before = pose.clone();
        lock.apply(&mut pose);
        for (hip, knee, ankle) in [(1, 4, 7), (2, 5, 8)] {
            assert!(norm(sub(pose.positions[ankle], first.positions[ankle])) < 1e-6);
            let bone = |p: &[Vec3; 22], a: usize, b: usize| norm(sub(p[a], p[b]));
            assert!(
                (bone(&pose.positions, hip, knee) - bone(&before.positions, hip, knee)).abs()
                    < 1e-9
            );
            assert!(
                (bone(&pose.positions, knee, ankle) - bone(&before.positions, knee, ankle)).abs()
                    < 1e-9
            );
        }
        // Forward kinematics of the new rotations lands on the new positions.
        let fk = forward_kinematics(&skeleton, pose.positions[0], &pose.rotations);
        for (j, (got, want)) in fk.iter().zip(&pose.positions).enumerate() {
            assert!(norm(sub(*got, *want)) < 1e-9, "joint {j}");
        }
    }

    #[test]
    fn a_foot_the_motion_walks_away_from_is_let_go() {
        let mut lock = FootLock::new(FootLockOptions::default()).unwrap();
        let mut pose = standing([0.0, 0.9, 0.0], [1.0, 1.0, 0.0, 0.0]);
        lock.apply(&mut pose);
        let pinned = pose.positions[7];
        // 40 cm away in one frame, label still on: farther than max_stretch, so released.
        let mut far = standing([0.4, 0.9, 0.0], [1.0, 1.0, 0.0, 0.0]);
        let free = far.positions[7];
        lock.apply(&mut far);
        let t = 1.0 / 4.0;
        let want = add(scale(pinned, 1.0 - t), scale(free, t));
        assert!(
            norm(sub(far.positions[7], want)) < 1e-3,
            "{:?}",
            far.positions[7]
        );
    }

    #[test]
    fn settings_out_of_range_are_refused() {
        for bad in [
            FootLockOptions {
                contact_threshold: 0.0,
                ..FootLockOptions::default()
            },
            FootLockOptions {
                contact_threshold: f32::NAN,
                ..FootLockOptions::default()
            },
            FootLockOptions {
                release_frames: 0,
                ..FootLockOptions::default()
            },
            FootLockOptions {
                max_stretch: f64::INFINITY,
                ..FootLockOptions::default()
            },
            FootLockOptions {
                max_stretch: -1.0,
                ..FootLockOptions::default()
            },
        ] {
            assert!(FootLock::new(bad).is_err(), "{bad:?}");
        }
    }
}
