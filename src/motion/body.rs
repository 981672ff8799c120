//! A body as volume, from joint positions alone: one capsule per bone of the t2m-22 skeleton
//! (SMPL-X's first 22 joints are the same), and the signed distance from a point to a body with
//! its analytic gradient. What [`crate::motion::penetration`] builds its loss and metrics on.
//!
//! A capsule is the set of points within `radius` of the segment from a bone's parent joint to
//! its joint. The radii ([`T2M22_RADII`]) are an adult's approximate limb and torso half-depths
//! (`r = circumference / 2π` for limbs, rounded to 5 mm); hands and the head's top are not
//! covered (the skeleton ends at the wrists and the head joint).

use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};
use crate::motion::vec3::{add, dot, norm, scale, sub, Vec3};
use crate::shared::error::{Error, Result};

/// Each t2m-22 bone's capsule radius in metres, by the bone's (child) joint.
pub const T2M22_RADII: [(&str, f64); 21] = [
    ("left_hip", 0.10),   // pelvis to hip: the hips' width
    ("right_hip", 0.10),  //
    ("spine1", 0.11),     // lower torso
    ("left_knee", 0.075), // thigh
    ("right_knee", 0.075),
    ("spine2", 0.11),
    ("left_ankle", 0.05), // shank
    ("right_ankle", 0.05),
    ("spine3", 0.12),    // chest
    ("left_foot", 0.04), // ankle to the ball of the foot
    ("right_foot", 0.04),
    ("neck", 0.06),
    ("left_collar", 0.07),
    ("right_collar", 0.07),
    ("head", 0.09),
    ("left_shoulder", 0.055),
    ("right_shoulder", 0.055),
    ("left_elbow", 0.045), // upper arm
    ("right_elbow", 0.045),
    ("left_wrist", 0.035), // forearm
    ("right_wrist", 0.035),
];

/// One bone's volume: the points within `radius` of the segment between two joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// The parent joint's index.
    pub from: usize,
    /// The joint's index.
    pub to: usize,
    /// Metres.
    pub radius: f64,
}

/// A body made of capsules over a skeleton's joints.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyModel {
    capsules: Vec<Capsule>,
    joints: usize,
}

/// A box around a posed body beyond which points are farther than a margin from it
/// ([`BodyModel::reach`]): the penetration checks skip such points without a distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    low: Vec3,
    high: Vec3,
}

impl Reach {
    /// Whether `point` lies outside the box (and so farther than the margin from the body).
    pub fn beyond(&self, point: Vec3) -> bool {
        (0..3).any(|k| point[k] < self.low[k] || point[k] > self.high[k])
    }
}

/// The signed distance from a point to a body, and its gradient with respect to the point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignedDistance {
    /// Metres; negative inside.
    pub distance: f64,
    /// `∂ distance / ∂ point`: the unit direction from the nearest capsule's axis to the point
    /// (zero for a point exactly on an axis, where no direction is preferred).
    pub gradient: Vec3,
    /// The nearest capsule's index.
    pub capsule: usize,
}

impl BodyModel {
    /// The t2m-22 body: one capsule per bone, radii from [`T2M22_RADII`].
    pub fn t2m22() -> BodyModel {
        let skeleton = Skeleton::t2m22();
        let capsules = T2M22_RADII
            .iter()
            .map(|(name, radius)| {
                let to = skeleton
                    .index_of(name)
                    .expect("the table names t2m-22 joints");
                let from = skeleton.parents()[to].expect("a bone's joint has a parent");
                Capsule {
                    from,
                    to,
                    radius: *radius,
                }
            })
            .collect();
        BodyModel {
            capsules,
            joints: T2M22_JOINTS,
        }
    }

    /// Capsules over `joints` joints; each capsule's joints must exist and its radius be finite
    /// and positive.
    pub fn new(joints: usize, capsules: Vec<Capsule>) -> Result<BodyModel> {
        for (i, c) in capsules.iter().enumerate() {
            if c.from >= joints || c.to >= joints || !(c.radius.is_finite() && c.radius > 0.0) {
                return Err(Error::InvalidInput(format!(
                    "capsule {i} ({} to {}, radius {}) does not fit a body of {joints} joints",
                    c.from, c.to, c.radius
                )));
            }
        }
        Ok(BodyModel { capsules, joints })
    }

    /// The capsules.
    pub fn capsules(&self) -> &[Capsule] {
        &self.capsules
    }

    /// Joints per pose.
    pub fn joints(&self) -> usize {
        self.joints
    }

    /// The signed distance from `point` to the body posed at `pose` (one position per joint):
    /// the smallest over the capsules of the distance to the capsule's axis less its radius.
    ///
    /// # Panics
    /// When `pose` has fewer than [`BodyModel::joints`] positions
    /// ([`crate::motion::penetration`] checks its inputs first).
    pub fn signed_distance(&self, pose: &[Vec3], point: Vec3) -> SignedDistance {
        let mut best = SignedDistance {
            distance: f64::INFINITY,
            gradient: [0.0; 3],
            capsule: 0,
        };
        for (i, c) in self.capsules.iter().enumerate() {
            let (a, b) = (pose[c.from], pose[c.to]);
            let axis = sub(b, a);
            let length2 = dot(axis, axis);
            let t = if length2 > 0.0 {
                (dot(sub(point, a), axis) / length2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let off = sub(point, add(a, scale(axis, t)));
            let d = norm(off);
            if d - c.radius < best.distance {
                best = SignedDistance {
                    distance: d - c.radius,
                    gradient: if d > 0.0 {
                        scale(off, 1.0 / d)
                    } else {
                        [0.0; 3]
                    },
                    capsule: i,
                };
            }
        }
        best
    }

    /// The box around the body posed at `pose` outside which every point is farther than
    /// `margin` from it, so that its signed distance need not be computed.
    ///
    /// # Panics
    /// When `pose` has fewer than [`BodyModel::joints`] positions.
    pub fn reach(&self, pose: &[Vec3], margin: f64) -> Reach {
        let widest = self.capsules.iter().fold(0.0f64, |r, c| r.max(c.radius));
        // A capsule lies inside the box of its two joints grown by its radius, so a point
        // farther than `grow` outside the joints' box along any axis is farther than `margin`
        // from every capsule (the small constant absorbs the distance's rounding).
        let grow = widest + margin + 1e-9;
        let mut reach = Reach {
            low: [f64::INFINITY; 3],
            high: [f64::NEG_INFINITY; 3],
        };
        for c in &self.capsules {
            for p in [pose[c.from], pose[c.to]] {
                for (k, v) in p.iter().enumerate() {
                    reach.low[k] = reach.low[k].min(v - grow);
                    reach.high[k] = reach.high[k].max(v + grow);
                }
            }
        }
        reach
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_bone() -> BodyModel {
        BodyModel::new(
            2,
            vec![Capsule {
                from: 0,
                to: 1,
                radius: 0.1,
            }],
        )
        .unwrap()
    }

    #[test]
    fn points_beyond_the_reach_are_farther_than_the_margin() {
        let body = BodyModel::t2m22();
        let pose = Skeleton::t2m22().rest_positions();
        // A grid of points from inside the body to well outside it, at three margins: a point
        // the box passes is never nearer than the margin, and the box does pass some.
        for margin in [0.0, 0.05, 0.3] {
            let reach = body.reach(&pose, margin);
            let mut passed = 0;
            for i in -12..=12 {
                for j in -4..=20 {
                    for k in -6..=6 {
                        let p = [0.1 * f64::from(i), 0.1 * f64::from(j), 0.1 * f64::from(k)];
                        if reach.beyond(p) {
                            passed += 1;
                            let d = body.signed_distance(&pose, p).distance;
                            assert!(d >= margin, "{p:?}: {d} m");
                        }
                    }
                }
            }
            assert!(passed > 0, "margin {margin}");
            assert!(!reach.beyond(pose[0]));
        }
    }

    #[test]
    fn distances_to_a_capsule() {
        let body = one_bone();
        let pose = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // Beside the middle of the bone, outside and inside.
        let out = body.signed_distance(&pose, [0.3, 0.5, 0.0]);
        assert!((out.distance - 0.2).abs() < 1e-12 && out.gradient == [1.0, 0.0, 0.0]);
        let inside = body.signed_distance(&pose, [0.0, 0.5, -0.04]);
        assert!((inside.distance + 0.06).abs() < 1e-12 && inside.gradient == [0.0, 0.0, -1.0]);
        // Past an end: the distance to the end joint.
        let beyond = body.signed_distance(&pose, [0.0, 1.5, 0.0]);
        assert!((beyond.distance - 0.4).abs() < 1e-12);
        // On the axis: inside by the radius, no preferred direction.
        let axis = body.signed_distance(&pose, [0.0, 0.25, 0.0]);
        assert!((axis.distance + 0.1).abs() < 1e-12 && axis.gradient == [0.0; 3]);
    }

    #[test]
    fn the_gradient_is_the_distances_derivative() {
        let body = BodyModel::t2m22();
        let pose = Skeleton::t2m22().rest_positions();
        let h = 1e-6;
        for point in [[0.05, 1.2, 0.03], [0.3, 0.6, 0.1], [-0.2, 1.5, -0.05]] {
            let sd = body.signed_distance(&pose, point);
            for axis in 0..3 {
                let mut up = point;
                let mut down = point;
                up[axis] += h;
                down[axis] -= h;
                let fd = (body.signed_distance(&pose, up).distance
                    - body.signed_distance(&pose, down).distance)
                    / (2.0 * h);
                assert!(
                    (fd - sd.gradient[axis]).abs() < 1e-6,
                    "{point:?} axis {axis}"
                );
            }
        }
    }

    #[test]
    fn the_rest_body_holds_its_own_joints_and_not_a_metre_away() {
        let body = BodyModel::t2m22();
        let pose = Skeleton::t2m22().rest_positions();
        for (j, p) in pose.iter().enumerate() {
            assert!(body.signed_distance(&pose, *p).distance < 0.0, "joint {j}");
        }
        let far = body.signed_distance(&pose, add(pose[3], [0.0, 0.0, 1.0]));
        assert!(far.distance > 0.8);
    }

    #[test]
    fn capsules_must_fit_the_skeleton() {
        let bad = Capsule {
            from: 0,
            to: 5,
            radius: 0.1,
        };
        assert!(BodyModel::new(2, vec![bad]).is_err());
        let flat = Capsule {
            from: 0,
            to: 1,
            radius: 0.0,
        };
        assert!(BodyModel::new(2, vec![flat]).is_err());
    }
}
