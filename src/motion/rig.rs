//! A caller's character rig: the skeleton motion is retargeted onto and written out for.
//!
//! Unlike [`Skeleton`] (troupe's own t2m-22 body, in canonical axes), a
//! rig is whatever a game engine or a DCC tool has: any joint names, extra joints (a root bone,
//! twist bones, fingers), any rest pose (T-pose, A-pose), rest rotations on its joints (glTF and
//! FBX rigs have them; BVH rigs do not), and its own units and axes. It comes from a BVH
//! hierarchy ([`Bvh::rig`](crate::motion::bvh::Bvh::rig)) or a rig JSON document
//! ([`Rig::from_json`]):
//!
//! ```json
//! {"name": "my_rig", "units": "centimeters", "up": "z", "handedness": "right",
//!  "joints": [{"name": "Hips", "parent": null, "offset": [0, 0, 95]},
//!             {"name": "Spine", "parent": "Hips", "offset": [0, 0, 10],
//!              "rotation": [1, 0, 0, 0], "end_site": [0, 0, 12]}]}
//! ```
//!
//! `offset` is the joint's rest translation from its parent (the root's: its rest position),
//! `rotation` its rest rotation relative to its parent as `[w, x, y, z]` (identity when left
//! out), `end_site` where its bone ends if it has no child (optional). World = parent world ×
//! translation × rotation, as in glTF and BVH.

use serde::Deserialize;

use crate::motion::rotation::Quat;
use crate::motion::skeleton::Skeleton;
use crate::motion::vec3::{add, Vec3};
use crate::motion::world::{Handedness, JointsFormat, Units, UpAxis};
use crate::shared::error::{excerpt, Error, Result};

/// The most joints a rig may have.
pub const MAX_RIG_JOINTS: usize = 1024;
/// The longest joint name, in bytes.
pub const MAX_RIG_NAME_BYTES: usize = 256;
/// The largest rest offset, in metres (10 km): finite arithmetic on every pose.
pub const MAX_RIG_OFFSET_METRES: f64 = 1e4;

/// A character rig: joints, their rest pose, and the units and axes it is measured in.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    name: String,
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    offsets: Vec<Vec3>,
    rotations: Vec<Quat>,
    end_sites: Vec<Option<Vec3>>,
    format: JointsFormat,
}

/// One pose of a rig: what an engine animates.
#[derive(Debug, Clone, PartialEq)]
pub struct RigPose {
    /// Every joint's local rotation (relative to its parent), in the rig's axes; joints the map
    /// does not name keep their rest rotation.
    pub rotations: Vec<Quat>,
    /// The joint whose translation moves (the one mapped to the pelvis).
    pub root: usize,
    /// Its local translation (relative to its parent, or the world for the rig's root joint), in
    /// the rig's units and axes.
    pub root_translation: Vec3,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RigDoc {
    name: String,
    #[serde(default)]
    #[allow(dead_code)]
    about: String,
    #[serde(default)]
    units: Option<String>,
    #[serde(default)]
    up: Option<String>,
    #[serde(default)]
    handedness: Option<String>,
    joints: Vec<RigJointDoc>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RigJointDoc {
    name: String,
    parent: Option<String>,
    offset: [f64; 3],
    #[serde(default)]
    rotation: Option<[f64; 4]>,
    #[serde(default)]
    end_site: Option<[f64; 3]>,
}

/// One joint of a rig as [`Rig::new`] takes it.
#[derive(Debug, Clone, PartialEq)]
pub struct RigJoint {
    /// The joint's name (unique within the rig).
    pub name: String,
    /// The index of its parent, which comes before it (`None` for the root, joint 0 only).
    pub parent: Option<usize>,
    /// Rest translation from the parent (the root's: its rest position), in the rig's units.
    pub offset: Vec3,
    /// Rest rotation relative to the parent.
    pub rotation: Quat,
    /// Where the joint's bone ends when it has no child, relative to the joint.
    pub end_site: Option<Vec3>,
}

fn parse_units(s: &str) -> Option<Units> {
    Some(match s.to_ascii_lowercase().as_str() {
        "m" | "meters" | "metres" => Units::Meters,
        "cm" | "centimeters" | "centimetres" => Units::Centimeters,
        "mm" | "millimeters" | "millimetres" => Units::Millimeters,
        "in" | "inches" => Units::Inches,
        _ => return None,
    })
}

impl Rig {
    /// A rig from its joints (parents before children, joint 0 the only root), checked: unique
    /// names of at most [`MAX_RIG_NAME_BYTES`] bytes without control characters, at most
    /// [`MAX_RIG_JOINTS`] joints, finite offsets within [`MAX_RIG_OFFSET_METRES`], unit rest
    /// rotations.
    pub fn new(name: &str, joints: Vec<RigJoint>, format: JointsFormat) -> Result<Rig> {
        let bad = |m: String| Error::InvalidInput(format!("rig {}: {m}", excerpt(name)));
        let n = joints.len();
        if n == 0 || n > MAX_RIG_JOINTS {
            return Err(bad(format!(
                "{n} joints; between 1 and {MAX_RIG_JOINTS} are allowed"
            )));
        }
        let limit = MAX_RIG_OFFSET_METRES / format.units.meters();
        let mut names: Vec<String> = Vec::with_capacity(n);
        for (j, joint) in joints.iter().enumerate() {
            let what = format!("joint {j} ({})", excerpt(&joint.name));
            if joint.name.is_empty()
                || joint.name.len() > MAX_RIG_NAME_BYTES
                || joint.name.chars().any(char::is_control)
            {
                return Err(bad(format!(
                    "{what}: names are 1 to {MAX_RIG_NAME_BYTES} bytes without control characters"
                )));
            }
            if names.contains(&joint.name) {
                return Err(bad(format!("{what}: the name is used twice")));
            }
            match joint.parent {
                None if j == 0 => {}
                None => return Err(bad(format!("{what}: only joint 0 is a root"))),
                Some(p) if p >= j => {
                    return Err(bad(format!("{what}: its parent must come before it")))
                }
                Some(_) if j == 0 => return Err(bad("joint 0 must be the root".into())),
                Some(_) => {}
            }
            let far = |v: &Vec3| v.iter().any(|x| !x.is_finite() || x.abs() > limit);
            if far(&joint.offset) || joint.end_site.as_ref().is_some_and(far) {
                return Err(bad(format!(
                    "{what}: offsets must be finite and within {MAX_RIG_OFFSET_METRES} m"
                )));
            }
            let q = joint.rotation;
            let len = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
            if !len.is_finite() || (len - 1.0).abs() > 1e-3 {
                return Err(bad(format!(
                    "{what}: the rest rotation is not a unit quaternion (length {len})"
                )));
            }
            names.push(joint.name.clone());
        }
        Ok(Rig {
            name: name.to_string(),
            names,
            parents: joints.iter().map(|j| j.parent).collect(),
            offsets: joints.iter().map(|j| j.offset).collect(),
            rotations: joints.iter().map(|j| j.rotation.normalized()).collect(),
            end_sites: joints.iter().map(|j| j.end_site).collect(),
            format: JointsFormat {
                fps: 30.0,
                ..format
            },
        })
    }

    /// A rig from its JSON document (see the module documentation). `units` defaults to metres,
    /// `up` to `"y"`, `handedness` to `"right"`.
    pub fn from_json(text: &str) -> Result<Rig> {
        let bad = |m: String| Error::InvalidInput(format!("rig: {m}"));
        let doc: RigDoc =
            serde_json::from_str(text).map_err(|e| bad(format!("not a rig document: {e}")))?;
        let units = match doc.units.as_deref() {
            None => Units::Meters,
            Some(u) => parse_units(u).ok_or_else(|| {
                bad(format!(
                    "units {:?}: one of meters, centimeters, millimeters, inches",
                    excerpt(u)
                ))
            })?,
        };
        let up = match doc.up.as_deref().map(str::to_ascii_lowercase).as_deref() {
            None | Some("y") => UpAxis::Y,
            Some("z") => UpAxis::Z,
            Some(other) => return Err(bad(format!("up {:?}: \"y\" or \"z\"", excerpt(other)))),
        };
        let handedness = match doc
            .handedness
            .as_deref()
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            None | Some("right") => Handedness::Right,
            Some("left") => Handedness::Left,
            Some(other) => {
                return Err(bad(format!(
                    "handedness {:?}: \"right\" or \"left\"",
                    excerpt(other)
                )))
            }
        };
        if doc.joints.len() > MAX_RIG_JOINTS {
            return Err(bad(format!(
                "{} joints; at most {MAX_RIG_JOINTS} are allowed",
                doc.joints.len()
            )));
        }
        let mut joints: Vec<RigJoint> = Vec::with_capacity(doc.joints.len());
        for (j, joint) in doc.joints.into_iter().enumerate() {
            let parent = match &joint.parent {
                None => None,
                Some(p) => Some(joints.iter().position(|k| &k.name == p).ok_or_else(|| {
                    bad(format!(
                        "joint {j} ({}): parent {:?} is not a joint before it",
                        excerpt(&joint.name),
                        excerpt(p)
                    ))
                })?),
            };
            joints.push(RigJoint {
                name: joint.name,
                parent,
                offset: joint.offset,
                rotation: joint.rotation.map_or(Quat::IDENTITY, Quat::from_wxyz),
                end_site: joint.end_site,
            });
        }
        Rig::new(
            &doc.name,
            joints,
            JointsFormat {
                units,
                up,
                handedness,
                ..JointsFormat::default()
            },
        )
    }

    /// troupe's own t2m-22 body as a rig (metres, Y up): retargeting onto it reproduces the
    /// motion, which is what the tests check first.
    pub fn t2m22() -> Rig {
        Rig::from_skeleton(&Skeleton::t2m22())
    }

    /// A skeleton (canonical axes) as a rig.
    pub fn from_skeleton(skeleton: &Skeleton) -> Rig {
        let joints = (0..skeleton.len())
            .map(|j| RigJoint {
                name: skeleton.names()[j].clone(),
                parent: skeleton.parents()[j],
                offset: skeleton.offsets()[j],
                rotation: Quat::IDENTITY,
                end_site: None,
            })
            .collect();
        Rig::new(skeleton.name(), joints, JointsFormat::default())
            .expect("a checked skeleton is a valid rig")
    }

    /// The rig's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of joints.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the rig has no joints (never true of a constructed rig).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Joint names.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Each joint's parent.
    pub fn parents(&self) -> &[Option<usize>] {
        &self.parents
    }

    /// Rest translations from the parents, in the rig's units and axes.
    pub fn offsets(&self) -> &[Vec3] {
        &self.offsets
    }

    /// Rest rotations relative to the parents, in the rig's axes.
    pub fn rest_rotations(&self) -> &[Quat] {
        &self.rotations
    }

    /// End sites of joints without children, relative to the joint.
    pub fn end_sites(&self) -> &[Option<Vec3>] {
        &self.end_sites
    }

    /// The units and axes the rig is measured in (its `fps` is meaningless).
    pub fn format(&self) -> JointsFormat {
        self.format
    }

    /// This rig measured in other units and axes (the same body).
    pub fn with_format(&self, format: JointsFormat) -> Rig {
        // In f64 throughout (`JointsFormat`'s conversions take f32 caller positions).
        let convert = |v: Vec3| format.point_from_canonical(self.format.point_to_canonical(v));
        Rig {
            name: self.name.clone(),
            names: self.names.clone(),
            parents: self.parents.clone(),
            offsets: self.offsets.iter().map(|&v| convert(v)).collect(),
            rotations: self
                .rotations
                .iter()
                .map(|&q| {
                    format.rotation_from_canonical_axes(self.format.rotation_to_canonical_axes(q))
                })
                .collect(),
            end_sites: self.end_sites.iter().map(|e| e.map(convert)).collect(),
            format: JointsFormat {
                fps: 30.0,
                ..format
            },
        }
    }

    /// The children of `joint`, in index order.
    pub fn children(&self, joint: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(move |&c| self.parents[c] == Some(joint))
    }

    /// World transforms of every joint given local rotations (rig axes) and a translation for
    /// one joint (`moved`: its local translation replaces its rest offset): positions in the
    /// rig's units and axes, and world rotations.
    pub fn forward_kinematics(
        &self,
        local: &[Quat],
        moved: Option<(usize, Vec3)>,
    ) -> (Vec<Vec3>, Vec<Quat>) {
        let n = self.len();
        let mut pos = vec![[0.0; 3]; n];
        let mut rot = vec![Quat::IDENTITY; n];
        for j in 0..n {
            let offset = match moved {
                Some((m, t)) if m == j => t,
                _ => self.offsets[j],
            };
            match self.parents[j] {
                Some(p) => {
                    pos[j] = add(pos[p], rot[p].rotate(offset));
                    rot[j] = rot[p] * local[j];
                }
                None => {
                    pos[j] = offset;
                    rot[j] = local[j];
                }
            }
        }
        (pos, rot)
    }

    /// What a file writer needs of `poses` (at least one, `fps` within [1, 1000], each with one
    /// finite rotation per joint, a finite root translation and the same moving joint), checked
    /// with errors that begin "`format` out on rig NAME"; returns the moving joint.
    pub(crate) fn check_poses(&self, poses: &[RigPose], fps: f32, format: &str) -> Result<usize> {
        let bad = |m: String| {
            Error::InvalidInput(format!("{format} out on rig {}: {m}", excerpt(&self.name)))
        };
        let first = poses
            .first()
            .ok_or_else(|| bad("a clip of 0 frames".into()))?;
        if !crate::motion::world::FPS_RANGE.contains(&fps) {
            return Err(bad(format!("{fps} fps is outside [1, 1000]")));
        }
        let moving = first.root;
        for (t, pose) in poses.iter().enumerate() {
            let finite = pose
                .rotations
                .iter()
                .all(|q| [q.w, q.x, q.y, q.z].iter().all(|v| v.is_finite()))
                && pose.root_translation.iter().all(|v| v.is_finite());
            if pose.rotations.len() != self.len() || pose.root != moving || !finite {
                return Err(bad(format!(
                    "frame {t}: a pose needs {} finite rotations and the same moving joint",
                    self.len()
                )));
            }
        }
        Ok(moving)
    }

    /// World positions of every joint of `pose` in troupe's canonical axes (metres, Y up):
    /// where an engine showing the pose puts each joint.
    pub fn posed_positions(&self, pose: &RigPose) -> Vec<Vec3> {
        let (pos, _) =
            self.forward_kinematics(&pose.rotations, Some((pose.root, pose.root_translation)));
        pos.into_iter()
            .map(|p| self.format.point_to_canonical(p))
            .collect()
    }

    /// World positions and rotations of the rest pose, in the rig's units and axes.
    pub fn rest_world(&self) -> (Vec<Vec3>, Vec<Quat>) {
        self.forward_kinematics(&self.rotations, None)
    }

    /// Where each joint's end site is, for joints that have one, in the pose whose world
    /// positions and rotations are `pos` and `rot` (as [`Rig::forward_kinematics`] gives them).
    pub fn end_site_positions(&self, pos: &[Vec3], rot: &[Quat]) -> Vec<Option<Vec3>> {
        self.end_sites
            .iter()
            .enumerate()
            .map(|(j, e)| e.map(|e| add(pos[j], rot[j].rotate(e))))
            .collect()
    }

    /// The rest pose's height (highest minus lowest joint or end site along the up axis), in
    /// metres.
    pub fn height_metres(&self) -> f64 {
        let canonical_rig = self.with_format(JointsFormat::default());
        let (pos, rot) = canonical_rig.rest_world();
        let mut points = pos.clone();
        points.extend(
            canonical_rig
                .end_site_positions(&pos, &rot)
                .into_iter()
                .flatten(),
        );
        let (lo, hi) = points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
                (a.0.min(p[1]), a.1.max(p[1]))
            });
        hi - lo
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_rig_documents_are_refused_with_the_reason() {
        let joint = |name: &str, parent: &str, extra: &str| {
            format!(r#"{{"name": "{name}", "parent": {parent}, "offset": [0, 1, 0]{extra}}}"#)
        };
        let doc = |joints: &[String], head: &str| {
            format!(
                r#"{{"name": "r"{head}, "joints": [{}]}}"#,
                joints.join(", ")
            )
        };
        let root = joint("a", "null", "");
        let cases = [
            ("[]".to_string(), "not a rig document"),
            (doc(&[], ""), "0 joints"),
            (
                doc(&[root.clone(), joint("a", r#""a""#, "")], ""),
                "used twice",
            ),
            (
                doc(&[root.clone(), joint("b", r#""c""#, "")], ""),
                "not a joint before",
            ),
            (
                doc(&[root.clone(), joint("b", "null", "")], ""),
                "only joint 0 is a root",
            ),
            (
                doc(&[joint("a", "null", r#", "rotation": [2, 0, 0, 0]"#)], ""),
                "not a unit quaternion",
            ),
            (
                doc(
                    &[r#"{"name": "a", "parent": null, "offset": [1e9, 0, 0]}"#.into()],
                    "",
                ),
                "within 10000 m",
            ),
            (
                doc(std::slice::from_ref(&root), r#", "units": "furlongs""#),
                "units",
            ),
            (doc(std::slice::from_ref(&root), r#", "up": "x""#), "up"),
            (
                doc(std::slice::from_ref(&root), r#", "handedness": "both""#),
                "handedness",
            ),
            (
                doc(&[joint("a\\u0007b", "null", "")], ""),
                "control characters",
            ),
        ];
        for (text, reason) in cases {
            let err = Rig::from_json(&text).unwrap_err().to_string();
            assert!(err.contains(reason), "{text}: {err}");
        }
    }

    #[test]
    fn a_rig_keeps_its_shape_in_other_units_and_axes() {
        let text = r#"{"name": "r", "units": "cm", "up": "z", "joints": [
            {"name": "a", "parent": null, "offset": [10, 20, 90]},
            {"name": "b", "parent": "a", "offset": [0, 0, 30], "rotation": [0.7071068, 0.7071068, 0, 0]},
            {"name": "c", "parent": "b", "offset": [0, 25, 0], "end_site": [0, 5, 0]}]}"#;
        let rig = Rig::from_json(text).unwrap();
        let (pos, _) = rig.rest_world();
        let metres = rig.with_format(JointsFormat::default());
        let (again, _) = metres.rest_world();
        for (p, q) in pos.iter().zip(&again) {
            let c = rig.format().point_to_canonical(*p);
            assert!(
                (0..3).all(|d| (c[d] - q[d]).abs() < 1e-12),
                "{c:?} vs {q:?}"
            );
        }
        // Z up: from the root at 90 cm, b 30 above, c (turned up by b's rest rotation) 25 above
        // that, its end site 5 more: 60 cm from lowest to highest.
        assert!(
            (rig.height_metres() - 0.6).abs() < 1e-9,
            "{}",
            rig.height_metres()
        );
        assert_eq!(metres.names(), rig.names());
    }
}
