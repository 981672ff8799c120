//! Poses for robots and tools that do not read BVH: a JSON document of joint positions and
//! rotations per person and frame, with its axes, units and skeleton stated in the document.
//!
//! ```json
//! {"format": "troupe-poses", "version": 1,
//!  "skeleton": {"name": "t2m22", "joints": ["pelvis", ...], "parents": [-1, 0, ...]},
//!  "units": "m", "up": "y", "handedness": "right", "fps": 30.0,
//!  "rotations": "unit quaternions [w, x, y, z]: joint 0 the root's world orientation, ...",
//!  "people": [{"name": "actor", "positions": [[[x, y, z], ...22], ...frames],
//!              "rotations": [[[w, x, y, z], ...22], ...], "contacts": [[la, lf, ra, rf], ...]}]}
//! ```

use ndarray::ArrayView3;
use serde::Serialize;

use crate::motion::features::{contacts, read_frame};
use crate::motion::ik::inverse_kinematics;
use crate::motion::placement::Placement;
use crate::motion::rotation::SixD;
use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};
use crate::motion::vec3::Vec3;
use crate::motion::world::{Handedness, JointsFormat, Units, UpAxis};
use crate::motion::Pose;
use crate::shared::error::{Error, Result};

/// The poses of a clip of joint positions (`[T, 22, 3]` in the world `format` describes):
/// rotations by inverse kinematics, contacts by InterGen's rule (the last frame, which has no
/// next, gets none). Positions are passed through.
pub fn poses_from_positions(
    positions: ArrayView3<f32>,
    format: &JointsFormat,
) -> Result<Vec<Pose>> {
    if positions.shape()[1..] != [T2M22_JOINTS, 3] {
        return Err(Error::InvalidInput(format!(
            "joint positions must be [frames, 22, 3], got {:?}",
            positions.shape()
        )));
    }
    let placement = Placement::identity(*format);
    let skeleton = Skeleton::t2m22();
    let mut canonical: Vec<Vec<Vec3>> = Vec::with_capacity(positions.shape()[0]);
    for (t, frame) in positions.outer_iter().enumerate() {
        let frame = read_frame(format, frame, &format!("frame {t}"))?;
        canonical.push(frame.iter().map(|p| placement.to_frame(*p)).collect());
    }
    let mut poses = Vec::with_capacity(canonical.len());
    for (t, pose) in canonical.iter().enumerate() {
        let rotations = inverse_kinematics(&skeleton, pose);
        let mut out = Pose {
            positions: [[0.0; 3]; T2M22_JOINTS],
            rotations: [[0.0; 4]; T2M22_JOINTS],
            rotations_6d: [[0.0; 6]; T2M22_JOINTS],
            contacts: [0.0; 4],
        };
        for j in 0..T2M22_JOINTS {
            out.positions[j] = std::array::from_fn(|d| positions[[t, j, d]]);
            let q = if j == 0 {
                placement.rotation_to_world(rotations[0])
            } else {
                placement.local_rotation_to_world(rotations[j])
            };
            out.rotations[j] = q.to_wxyz().map(|v| v as f32);
            out.rotations_6d[j] = q.to_6d(SixD::InterleavedColumns).map(|v| v as f32);
        }
        if let Some(next) = canonical.get(t + 1) {
            out.contacts = contacts(pose, next);
        }
        poses.push(out);
    }
    Ok(poses)
}

#[derive(Serialize)]
struct SkeletonDoc<'a> {
    name: &'a str,
    joints: &'a [String],
    parents: Vec<i32>,
}

#[derive(Serialize)]
struct PersonDoc<'a> {
    name: &'a str,
    positions: Vec<&'a [[f32; 3]; T2M22_JOINTS]>,
    rotations: Vec<&'a [[f32; 4]; T2M22_JOINTS]>,
    contacts: Vec<&'a [f32; 4]>,
}

#[derive(Serialize)]
struct PosesDoc<'a> {
    format: &'static str,
    version: u32,
    skeleton: SkeletonDoc<'a>,
    units: &'static str,
    up: &'static str,
    handedness: &'static str,
    fps: f32,
    rotations: &'static str,
    contacts: &'static str,
    people: Vec<PersonDoc<'a>>,
}

/// The JSON document of people's poses (see the module documentation), positions and
/// rotations in the world `format` describes.
pub fn poses_json(people: &[(&str, &[Pose])], format: &JointsFormat) -> Result<String> {
    format.validate()?;
    if people.is_empty() {
        return Err(Error::InvalidInput("poses JSON: no people".into()));
    }
    let skeleton = Skeleton::t2m22();
    let doc = PosesDoc {
        format: "troupe-poses",
        version: 1,
        skeleton: SkeletonDoc {
            name: skeleton.name(),
            joints: skeleton.names(),
            parents: skeleton
                .parents()
                .iter()
                .map(|p| p.map_or(-1, |p| p as i32))
                .collect(),
        },
        units: match format.units {
            Units::Meters => "m",
            Units::Centimeters => "cm",
            Units::Millimeters => "mm",
            Units::Inches => "in",
        },
        up: match format.up {
            UpAxis::Y => "y",
            UpAxis::Z => "z",
        },
        handedness: match format.handedness {
            Handedness::Right => "right",
            Handedness::Left => "left",
        },
        fps: format.fps,
        rotations: "unit quaternions [w, x, y, z] in these axes: joint 0 the root's world \
                    orientation, every other joint local to its parent (its rotation turns its \
                    children's rest offsets)",
        contacts: "left ankle, left foot, right ankle, right foot: 1 in contact, 0 not",
        people: people
            .iter()
            .map(|(name, poses)| PersonDoc {
                name,
                positions: poses.iter().map(|p| &p.positions).collect(),
                rotations: poses.iter().map(|p| &p.rotations).collect(),
                contacts: poses.iter().map(|p| &p.contacts).collect(),
            })
            .collect(),
    };
    serde_json::to_string(&doc).map_err(|e| Error::InvalidInput(format!("poses JSON: {e}")))
}

/// [`poses_json`] written to `path` atomically (nothing is left on error).
pub fn write_poses_json(
    path: &std::path::Path,
    people: &[(&str, &[Pose])],
    format: &JointsFormat,
) -> Result<()> {
    let text = poses_json(people, format)?;
    crate::shared::files::write_atomically(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::ik::forward_kinematics;
    use crate::motion::rotation::Quat;
    use ndarray::Array3;

    #[test]
    fn json_poses_reproduce_the_positions_and_state_their_axes() {
        // The neutral body standing still, then stepping: z up, centimetres.
        let skeleton = Skeleton::t2m22();
        let format = JointsFormat {
            units: Units::Centimeters,
            up: UpAxis::Z,
            ..JointsFormat::default()
        };
        let rest = skeleton.rest_positions();
        let clip = Array3::from_shape_fn((6, 22, 3), |(t, j, d)| {
            let moved = [
                rest[j][0],
                rest[j][1],
                rest[j][2] + 0.1 * t as f64 * f64::from(t > 2),
            ];
            format.from_canonical_axes(moved)[d]
        });
        let poses = poses_from_positions(clip.view(), &format).unwrap();
        // Standing feet on the floor are in contact; after the body moves 10 cm a frame they are not.
        assert_eq!(poses[0].contacts, [1.0, 1.0, 1.0, 1.0]);
        assert_eq!(poses[3].contacts, [0.0; 4]);
        assert_eq!(poses[5].contacts, [0.0; 4], "the last frame has no next");
        // Rotations in the caller's axes rebuild the pose from the rest offsets in those axes.
        let offsets: Vec<[f64; 3]> = skeleton
            .offsets()
            .iter()
            .map(|o| format.from_canonical_axes(*o).map(f64::from))
            .collect();
        let callers = skeleton.clone().with_offsets(offsets);
        for pose in &poses {
            let local: Vec<Quat> = pose
                .rotations
                .iter()
                .map(|q| Quat::from_wxyz(q.map(f64::from)))
                .collect();
            let again = forward_kinematics(&callers, pose.positions[0].map(f64::from), &local);
            for (a, b) in pose.positions.iter().zip(&again) {
                assert!(
                    (0..3).all(|d| (f64::from(a[d]) - b[d]).abs() < 1e-3),
                    "{a:?} vs {b:?}"
                );
            }
        }
        let json = poses_json(&[("actor", &poses)], &format).unwrap();
        let doc: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(doc["units"], "cm");
        assert_eq!(doc["up"], "z");
        assert_eq!(doc["skeleton"]["joints"][21], "right_wrist");
        assert_eq!(doc["people"][0]["positions"].as_array().unwrap().len(), 6);
        let y = doc["people"][0]["positions"][4][15][2].as_f64().unwrap();
        assert!((y - f64::from(clip[[4, 15, 2]])).abs() < 1e-3);
    }
}
