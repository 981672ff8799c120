//! Joint rotations from joint positions (inverse kinematics) and back (forward kinematics).
//!
//! Rotations are local, in the convention of SMPL, BVH and game engines: joint `j`'s rotation
//! turns the offsets of `j`'s children, and a joint's world rotation is its parent's world
//! rotation times its local one. The root's local rotation is its world rotation.
//!
//! What positions can recover, and what they cannot:
//! - a joint with one child gets the *shortest-arc* rotation taking the rest direction of its
//!   bone onto the posed one (HumanML3D's method): the swing is exact, the twist about the bone
//!   is unknowable from positions and comes out as none;
//! - a joint with several children (the pelvis, `spine3`) is oriented by its branch frame: the
//!   direction between its left and right child and the direction to its up child. The root's
//!   orientation so follows the hips and the spine, and its heading matches the facing InterGen
//!   and HumanML3D take from the hips;
//! - joints without children (head, feet, wrists) carry no information and get no rotation;
//! - a bone of zero length, or a branch whose children are collinear, gives no rotation either.
//!
//! Forward kinematics with a skeleton [fitted](crate::motion::Skeleton::fitted_to) to the clip
//! reproduces the input exactly where the clip's bones are rigid: always for single-child
//! bones, and for a branch when its children move rigidly together (true of rigs whose hips and
//! spine hang off one bone, as in LAFAN1 and Mixamo BVH files).

use crate::motion::rotation::Quat;
use crate::motion::skeleton::Skeleton;
use crate::motion::vec3::{add, cross, dot, norm, normalize, reject, sub, Vec3};

/// Local rotations of every joint of one pose. Positions are canonical (y up, metres), indexed
/// like the skeleton's joints.
pub fn inverse_kinematics(skeleton: &Skeleton, positions: &[Vec3]) -> Vec<Quat> {
    let n = skeleton.len();
    let mut world = vec![Quat::IDENTITY; n];
    let mut local = vec![Quat::IDENTITY; n];
    for j in 0..n {
        let parent_world = skeleton.parents()[j].map_or(Quat::IDENTITY, |p| world[p]);
        let w = if skeleton.branch_frames()[j].is_some() {
            skeleton
                .branch_world_rotation(j, positions)
                .unwrap_or(parent_world)
        } else {
            let mut children = skeleton.children(j);
            match (children.next(), children.next()) {
                (Some(c), None) => {
                    let target = parent_world.conj().rotate(sub(positions[c], positions[j]));
                    Quat::between(skeleton.offsets()[c], target)
                        .map_or(parent_world, |q| parent_world * q)
                }
                _ => parent_world,
            }
        };
        world[j] = w;
        local[j] = (parent_world.conj() * w).normalized();
    }
    local
}

/// Joint positions of a pose from its root position and local rotations.
pub fn forward_kinematics(skeleton: &Skeleton, root: Vec3, local: &[Quat]) -> Vec<Vec3> {
    let n = skeleton.len();
    let mut world = vec![Quat::IDENTITY; n];
    let mut positions = vec![[0.0; 3]; n];
    for j in 0..n {
        match skeleton.parents()[j] {
            Some(p) => {
                positions[j] = add(positions[p], world[p].rotate(skeleton.offsets()[j]));
                world[j] = world[p] * local[j];
            }
            None => {
                positions[j] = root;
                world[j] = local[j];
            }
        }
    }
    positions
}

/// The two world-space turns that bring a limb's end onto `target`, for a limb of three joints
/// at `upper`, `middle` and `end` (a leg: hip, knee, ankle): `bend` turns the middle joint
/// (about the limb's bend axis) so that the limb is as long as `target` is far (clamped to what
/// the bones reach), then `swing` turns the whole limb about the upper joint to point at it.
/// The middle joint's world rotation becomes `swing * bend * old`, the upper joint's
/// `swing * old`. `bend_hint` is the bend axis to use when the limb is straight (the sense of
/// `cross(end - middle, upper - middle)`). `None` for a degenerate limb (a bone of zero length).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoBoneTurns {
    /// The turn of the whole limb about the upper joint.
    pub swing: Quat,
    /// The turn of the lower bone about the middle joint (before `swing`).
    pub bend: Quat,
}

/// [`TwoBoneTurns`] for the limb `[upper, middle, end]` reaching for `target`.
pub fn two_bone_turns([a, b, c]: [Vec3; 3], target: Vec3, bend_hint: Vec3) -> Option<TwoBoneTurns> {
    let (l1, l2) = (norm(sub(b, a)), norm(sub(c, b)));
    if l1 < 1e-9 || l2 < 1e-9 {
        return None;
    }
    let reach = norm(sub(target, a)).clamp((l1 - l2).abs() + 1e-6, l1 + l2 - 1e-6);
    let (ba, bc) = (sub(a, b), sub(c, b));
    let angle = |x: Vec3, y: Vec3| {
        (dot(x, y) / (norm(x) * norm(y)).max(1e-12))
            .clamp(-1.0, 1.0)
            .acos()
    };
    let now = angle(ba, bc);
    let want = ((l1 * l1 + l2 * l2 - reach * reach) / (2.0 * l1 * l2))
        .clamp(-1.0, 1.0)
        .acos();
    // The axis turning `bc` towards `ba`; when the limb is straight, the hint's.
    let axis = normalize(cross(bc, ba)).or_else(|| {
        let dir = normalize(sub(c, a))?;
        normalize(reject(bend_hint, dir))
    })?;
    let bend = Quat::from_axis_angle(axis, now - want);
    let c_bent = add(b, bend.rotate(bc));
    let swing = Quat::between(sub(c_bent, a), sub(target, a))?;
    Some(TwoBoneTurns { swing, bend })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::vec3::{norm, normalize};

    /// A pose from the neutral body with every joint turned a little, and the body moved.
    fn posed(skeleton: &Skeleton, t: f64) -> (Vec<Quat>, Vec<Vec3>) {
        let local: Vec<Quat> = (0..skeleton.len())
            .map(|j| {
                let a = t + j as f64;
                let axis = normalize([a.sin(), a.cos(), 0.5 * (2.0 * a).sin()]).unwrap();
                Quat::from_axis_angle(axis, 0.6 * (1.3 * a).sin())
            })
            .collect();
        let positions = forward_kinematics(skeleton, [0.3, 0.9, -1.1], &local);
        (local, positions)
    }

    #[test]
    fn ik_then_fk_reproduces_positions_of_a_rigid_skeleton() {
        let skeleton = Skeleton::t2m22();
        for k in 0..20 {
            let (_, positions) = posed(&skeleton, f64::from(k) * 0.31);
            let rotations = inverse_kinematics(&skeleton, &positions);
            let again = forward_kinematics(&skeleton, positions[0], &rotations);
            for (a, b) in positions.iter().zip(&again) {
                assert!(norm(sub(*a, *b)) < 1e-9, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn ik_recovers_swing_but_not_twist() {
        // Where the posing rotation had no twist about the bone, IK gets it back exactly: the
        // world direction of every bone is reproduced, and the rest pose gives identities.
        let skeleton = Skeleton::t2m22();
        let rest = skeleton.rest_positions();
        for q in inverse_kinematics(&skeleton, &rest) {
            assert!((q.w.abs() - 1.0).abs() < 1e-12, "{q:?}");
        }
    }

    #[test]
    fn a_fitted_skeleton_reproduces_a_body_of_other_proportions() {
        let neutral = Skeleton::t2m22();
        let mut other = neutral.clone();
        // A taller person with wider hips and a differently shaped shoulder girdle.
        let mut offsets = other.offsets().to_vec();
        for (j, o) in offsets.iter_mut().enumerate() {
            let s = 1.0 + 0.02 * (j as f64 % 5.0);
            *o = [o[0] * s, o[1] * s * 1.1, o[2] * s + 0.01];
        }
        other = other.with_offsets(offsets);
        let clip: Vec<Vec<Vec3>> = (0..10).map(|k| posed(&other, f64::from(k)).1).collect();
        let fitted = neutral.fitted_to(&clip);
        for pose in &clip {
            let rotations = inverse_kinematics(&neutral, pose);
            let again = forward_kinematics(&fitted, pose[0], &rotations);
            for (a, b) in pose.iter().zip(&again) {
                assert!(norm(sub(*a, *b)) < 1e-9, "{a:?} vs {b:?}");
            }
        }
    }
}
