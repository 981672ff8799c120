//! A skeleton as data: joint names, parents and rest offsets, and the one troupe's motion
//! features are defined on, the 22-joint SMPL / HumanML3D "t2m" body.
//!
//! Axes are troupe's canonical ones (InterGen's): metres, +Y up, the body facing +Z in its rest
//! pose, so +X is the body's *left* (the SMPL convention). Rest offsets describe a T-pose.
//!
//! A skeleton is a JSON document (`skeletons/t2m22.json` beside this file is the built-in one,
//! which the Python tooling reads too): joints in order, each with its name, its parent's name
//! (`null` for the root) and its rest offset from the parent (the root's: its rest position),
//! and a `branch_frames` entry for every joint with several children.

use std::sync::OnceLock;

use serde::Deserialize;

use crate::motion::rotation::Quat;
use crate::motion::vec3::{normalize, sub, Vec3};
use crate::shared::error::{Error, Result};

/// The built-in t2m-22 skeleton document.
pub const T2M22_JSON: &str = include_str!("skeletons/t2m22.json");

/// The most joints a skeleton may have.
pub const MAX_JOINTS: usize = 256;

/// The name troupe and bundle manifests use for the t2m-22 skeleton.
pub const T2M22: &str = "t2m22";

/// Joints of the t2m-22 skeleton.
pub const T2M22_JOINTS: usize = 22;

/// Joints InterGen uses to find the facing direction: `[right_hip, left_hip, right_shoulder,
/// left_shoulder]` (its `face_joint_indx`; only the hips enter its canonicalisation).
pub const FACE_JOINTS: [usize; 4] = [2, 1, 17, 16];

/// Foot joints whose contacts the features carry: left ankle and foot, then right ankle and
/// foot (InterGen's `fid_l`, `fid_r`).
pub const FOOT_JOINTS: [usize; 4] = [7, 10, 8, 11];

/// How a joint with several children is oriented: from the direction between two of its
/// children (`across`, pointing to the body's left) and the direction to a third (`up`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BranchFrame {
    /// `(left child, right child)`: the frame's x axis points from right to left.
    pub across: (usize, usize),
    /// The child the frame's y axis points toward (made perpendicular to x).
    pub up: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SkeletonDoc {
    name: String,
    #[serde(default)]
    #[allow(dead_code)]
    about: String,
    #[serde(default)]
    #[allow(dead_code)]
    axes: String,
    #[serde(default)]
    #[allow(dead_code)]
    rotations: String,
    joints: Vec<JointDoc>,
    #[serde(default)]
    branch_frames: Vec<BranchDoc>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JointDoc {
    name: String,
    parent: Option<String>,
    offset: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BranchDoc {
    joint: String,
    across: [String; 2],
    up: String,
}

/// A joint hierarchy with rest offsets.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    name: String,
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    offsets: Vec<Vec3>,
    branch_frames: Vec<Option<BranchFrame>>,
}

impl Skeleton {
    /// The t2m-22 skeleton with the neutral body's rest offsets.
    pub fn t2m22() -> Skeleton {
        static T2M22: OnceLock<Skeleton> = OnceLock::new();
        T2M22
            .get_or_init(|| {
                Skeleton::from_json(T2M22_JSON).expect("the built-in skeleton is valid (tested)")
            })
            .clone()
    }

    /// A skeleton from its JSON document (see the module documentation), checked: unique
    /// names, each parent named before its child, finite offsets, at most [`MAX_JOINTS`] joints,
    /// one root, and a branch frame for exactly the joints with several children, built from
    /// their own children.
    pub fn from_json(text: &str) -> Result<Skeleton> {
        let bad = |message: String| Error::InvalidInput(format!("skeleton: {message}"));
        let doc: SkeletonDoc =
            serde_json::from_str(text).map_err(|e| bad(format!("not a skeleton document: {e}")))?;
        let n = doc.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(bad(format!(
                "{n} joints; between 1 and {MAX_JOINTS} are allowed"
            )));
        }
        let mut names: Vec<String> = Vec::with_capacity(n);
        let mut parents = Vec::with_capacity(n);
        let mut offsets = Vec::with_capacity(n);
        for (j, joint) in doc.joints.iter().enumerate() {
            if names.contains(&joint.name) {
                return Err(bad(format!(
                    "joint {j}: the name {:?} is used twice",
                    joint.name
                )));
            }
            let parent = match &joint.parent {
                None if j == 0 => None,
                None => {
                    return Err(bad(format!(
                        "joint {j} ({}): only joint 0 is a root",
                        joint.name
                    )))
                }
                Some(p) => Some(names.iter().position(|n| n == p).ok_or_else(|| {
                    bad(format!(
                        "joint {j} ({}): parent {p:?} is not a joint before it",
                        joint.name
                    ))
                })?),
            };
            if joint.offset.iter().any(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "joint {j} ({}): offset is not finite",
                    joint.name
                )));
            }
            names.push(joint.name.clone());
            parents.push(parent);
            offsets.push(joint.offset);
        }
        if parents[0].is_some() {
            return Err(bad("joint 0 must be the root (parent null)".into()));
        }
        let index = |name: &str, what: &str| {
            names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| bad(format!("{what}: no joint is called {name:?}")))
        };
        let mut branch_frames = vec![None; n];
        for b in &doc.branch_frames {
            let j = index(&b.joint, "branch frame")?;
            let frame = BranchFrame {
                across: (
                    index(&b.across[0], &b.joint)?,
                    index(&b.across[1], &b.joint)?,
                ),
                up: index(&b.up, &b.joint)?,
            };
            for c in [frame.across.0, frame.across.1, frame.up] {
                if parents[c] != Some(j) {
                    return Err(bad(format!(
                        "branch frame of {}: {} is not its child",
                        b.joint, names[c]
                    )));
                }
            }
            branch_frames[j] = Some(frame);
        }
        for j in 0..n {
            let children = parents.iter().filter(|&&p| p == Some(j)).count();
            if children > 1 && branch_frames[j].is_none() {
                return Err(bad(format!(
                    "{} has {children} children and needs a branch frame",
                    names[j]
                )));
            }
        }
        Ok(Skeleton {
            name: doc.name,
            names,
            parents,
            offsets,
            branch_frames,
        })
    }

    /// The skeleton's name (`t2m22` for the built-in one).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of joints.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the skeleton has no joints (never true for one troupe builds).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Joint names, in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The index of the joint called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Each joint's parent (`None` for the root). Parents come before their children.
    pub fn parents(&self) -> &[Option<usize>] {
        &self.parents
    }

    /// Rest offsets from each joint's parent, metres (the root's: its rest position).
    pub fn offsets(&self) -> &[Vec3] {
        &self.offsets
    }

    /// How joints with several children are oriented (`None` for the others).
    pub fn branch_frames(&self) -> &[Option<BranchFrame>] {
        &self.branch_frames
    }

    /// This skeleton with other rest offsets (one per joint, the root's first).
    ///
    /// # Panics
    /// If `offsets` does not have one entry per joint.
    pub fn with_offsets(mut self, offsets: Vec<Vec3>) -> Skeleton {
        assert_eq!(offsets.len(), self.len(), "one offset per joint");
        self.offsets = offsets;
        self
    }

    /// The children of `joint`, in index order.
    pub fn children(&self, joint: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(move |&c| self.parents[c] == Some(joint))
    }

    /// Rest positions of every joint (a T-pose standing on the floor).
    pub fn rest_positions(&self) -> Vec<Vec3> {
        let mut out: Vec<Vec3> = Vec::with_capacity(self.len());
        for (j, off) in self.offsets.iter().enumerate() {
            out.push(match self.parents[j] {
                Some(p) => crate::motion::vec3::add(out[p], *off),
                None => *off,
            });
        }
        out
    }

    /// The rest-pose rotation of a branch joint's frame: the frame its children span in the
    /// rest pose, so that posed frame × rest frame⁻¹ is the joint's world rotation.
    pub(crate) fn rest_frame(&self, frame: BranchFrame) -> Quat {
        let across = sub(self.offsets[frame.across.0], self.offsets[frame.across.1]);
        branch_rotation(across, self.offsets[frame.up]).unwrap_or(Quat::IDENTITY)
    }

    /// The world rotation of branch joint `joint` in a pose (canonical positions indexed like
    /// the joints): the frame its children span in the pose times the inverse of the one they
    /// span at rest. `None` when `joint` has no branch frame or its children span none (they
    /// coincide or are collinear).
    pub(crate) fn branch_world_rotation(&self, joint: usize, pose: &[Vec3]) -> Option<Quat> {
        let frame = self.branch_frames[joint]?;
        let across = sub(pose[frame.across.0], pose[frame.across.1]);
        let posed = branch_rotation(across, sub(pose[frame.up], pose[joint]))?;
        Some(posed * self.rest_frame(frame).conj())
    }

    /// This skeleton with its bone lengths and branch shapes measured from a clip of canonical
    /// joint positions (`[T][joints]`): single-child bones keep their rest direction and take
    /// the clip's mean length; children of a branch joint take their mean position in the
    /// branch's frame. Forward kinematics with the result reproduces the clip exactly wherever
    /// its bones are rigid. Frames where a branch has no frame are skipped.
    pub fn fitted_to(&self, clip: &[Vec<Vec3>]) -> Skeleton {
        let mut fitted = self.clone();
        for j in 0..self.len() {
            let Some(parent) = self.parents[j] else {
                continue;
            };
            match self.branch_frames[parent] {
                Some(_) => {
                    let mut sum = [0.0; 3];
                    let mut n = 0.0;
                    for pose in clip {
                        if let Some(world) = self.branch_world_rotation(parent, pose) {
                            let local = world.conj().rotate(sub(pose[j], pose[parent]));
                            sum = crate::motion::vec3::add(sum, local);
                            n += 1.0;
                        }
                    }
                    if n > 0.0 {
                        fitted.offsets[j] = crate::motion::vec3::scale(sum, 1.0 / n);
                    }
                }
                None => {
                    let lengths: Vec<f64> = clip
                        .iter()
                        .map(|pose| crate::motion::vec3::norm(sub(pose[j], pose[parent])))
                        .collect();
                    if let (Some(dir), false) = (normalize(self.offsets[j]), lengths.is_empty()) {
                        let mean = lengths.iter().sum::<f64>() / lengths.len() as f64;
                        fitted.offsets[j] = crate::motion::vec3::scale(dir, mean);
                    }
                }
            }
        }
        fitted
    }
}

/// The rotation whose x axis is `across` and whose y axis is `up` made perpendicular to it.
/// `None` when either is degenerate or they are parallel.
pub(crate) fn branch_rotation(across: Vec3, up: Vec3) -> Option<Quat> {
    Quat::from_columns(across, up)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_neutral_body_stands_on_the_floor_facing_z_with_left_at_plus_x() {
        let s = Skeleton::t2m22();
        let rest = s.rest_positions();
        let lowest = rest.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
        assert!((lowest - 0.02).abs() < 1e-9, "lowest joint at {lowest}");
        assert!(rest[1][0] > 0.0 && rest[2][0] < 0.0, "left hip at +x");
        assert!(rest[10][2] > rest[7][2], "feet point forward (+z)");
        let head = rest[15][1];
        assert!((1.5..1.7).contains(&head), "head joint at {head} m");
        for (j, p) in s.parents().iter().enumerate() {
            assert!(p.is_none_or(|p| p < j), "parents come first");
        }
        assert_eq!(s.name(), T2M22);
        assert_eq!(s.len(), T2M22_JOINTS);
        for (l, r) in [
            (1, 2),
            (4, 5),
            (7, 8),
            (10, 11),
            (13, 14),
            (16, 17),
            (18, 19),
            (20, 21),
        ] {
            let (a, b) = (s.offsets()[l], s.offsets()[r]);
            assert_eq!([a[0], a[1], a[2]], [-b[0], b[1], b[2]], "{l}/{r} symmetric");
            assert!(s.names()[l].starts_with("left_") && s.names()[r].starts_with("right_"));
        }
    }

    #[test]
    fn bad_skeleton_documents_are_refused_with_the_reason() {
        let cases = [
            ("{}", "not a skeleton"),
            (r#"{"name":"a","joints":[]}"#, "0 joints"),
            (
                r#"{"name":"a","joints":[{"name":"r","parent":null,"offset":[0,0,0]},
                   {"name":"r","parent":"r","offset":[0,1,0]}]}"#,
                "used twice",
            ),
            (
                r#"{"name":"a","joints":[{"name":"r","parent":null,"offset":[0,0,0]},
                   {"name":"b","parent":"c","offset":[0,1,0]}]}"#,
                "not a joint before",
            ),
            (
                r#"{"name":"a","joints":[{"name":"r","parent":null,"offset":[0,0,0]},
                   {"name":"b","parent":"r","offset":[0,1,0]},
                   {"name":"c","parent":"r","offset":[0,1,0]}]}"#,
                "needs a branch frame",
            ),
        ];
        for (text, reason) in cases {
            let err = Skeleton::from_json(text).unwrap_err().to_string();
            assert!(err.contains(reason), "{text}: {err}");
        }
    }

    #[test]
    fn the_rest_frames_of_the_branches_are_nearly_the_identity() {
        let s = Skeleton::t2m22();
        for f in s.branch_frames().iter().flatten() {
            let q = s.rest_frame(*f);
            assert!(q.w.abs() > 0.99, "{q:?}");
        }
    }
}
