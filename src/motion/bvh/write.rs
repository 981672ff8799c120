//! The BVH writer: t2m-22 skeletons with local rotations as Z-Y-X Euler angles, one person per
//! file or several people under one scene root.

use std::fmt::Write as _;

use super::parse::{MAX_BVH_COORDINATE, MAX_BVH_NAME_BYTES};
use crate::motion::ik::inverse_kinematics;
use crate::motion::rotation::Quat;
use crate::motion::skeleton::Skeleton;
use crate::motion::vec3::{norm, normalize, scale, Vec3};
use crate::motion::world::{Units, FPS_RANGE};
use crate::shared::error::{excerpt, Error, Result};

/// One person to write: a name (prefixed to joint names when a file holds several people) and
/// joint positions per frame in troupe's canonical axes (metres, Y up), indexed like the
/// t2m-22 skeleton.
#[derive(Debug, Clone, Copy)]
pub struct BvhPerson<'a> {
    /// The person's name.
    pub name: &'a str,
    /// `[frames][22]` joint positions.
    pub positions: &'a [Vec<Vec3>],
}

/// How to write a BVH file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BvhWriteOptions {
    /// Units of offsets and positions in the file (centimetres, as most tools expect, by
    /// default; metres and millimetres are the alternatives).
    pub units: Units,
    /// Frames per second.
    pub fps: f32,
    /// `true`: each person's bone lengths and branch shapes are measured from their motion
    /// ([`Skeleton::fitted_to`]), so the file reproduces the positions; `false`: every person
    /// gets troupe's neutral body.
    pub fit_skeleton: bool,
}

impl Default for BvhWriteOptions {
    fn default() -> Self {
        BvhWriteOptions {
            units: Units::Centimeters,
            fps: 30.0,
            fit_skeleton: true,
        }
    }
}

/// Channels of every non-root joint: intrinsic Z, then Y, then X.
const ROTATION_CHANNELS: &str = "Zrotation Yrotation Xrotation";

/// Euler angles (degrees) with `R = Rz(z) · Ry(y) · Rx(x)`, as `[z, y, x]`.
pub(crate) fn euler_zyx_degrees(q: Quat) -> [f64; 3] {
    let m = q.to_matrix();
    let sy = (-m[2][0]).clamp(-1.0, 1.0);
    let y = sy.asin();
    let (z, x) = if sy.abs() < 1.0 - 1e-9 {
        (m[1][0].atan2(m[0][0]), m[2][1].atan2(m[2][2]))
    } else {
        // Gimbal lock: only z ± x is defined; put it all in z.
        ((-m[0][1]).atan2(m[1][1]), 0.0)
    };
    [z.to_degrees(), y.to_degrees(), x.to_degrees()]
}

/// The text of a BVH file holding `people` (at least one, all with the same number of frames,
/// at least one frame).
pub fn write_bvh(people: &[BvhPerson], options: &BvhWriteOptions) -> Result<String> {
    let bad = |m: String| Error::InvalidInput(format!("BVH out: {m}"));
    let first = people
        .first()
        .ok_or_else(|| bad("no people to write".into()))?;
    let frames = first.positions.len();
    if frames == 0 {
        return Err(bad("a clip of 0 frames".into()));
    }
    if !FPS_RANGE.contains(&options.fps) {
        return Err(bad(format!("{} fps is outside [1, 1000]", options.fps)));
    }
    let neutral = Skeleton::t2m22();
    for p in people {
        if p.positions.len() != frames {
            return Err(bad(format!(
                "{} has {} frames, {} has {frames}",
                p.name,
                p.positions.len(),
                first.name
            )));
        }
        for (t, pose) in p.positions.iter().enumerate() {
            if pose.len() != neutral.len() || pose.iter().flatten().any(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "{}, frame {t}: expected {} finite joint positions",
                    p.name,
                    neutral.len()
                )));
            }
        }
        if p.name.is_empty()
            || p.name
                .chars()
                .any(|c| c.is_whitespace() || c.is_control() || c == '{' || c == '}')
        {
            return Err(bad(format!(
                "person name `{}` cannot be part of a joint name",
                excerpt(p.name)
            )));
        }
    }
    // Every joint name once, each as the reader takes it (what is written reads back).
    let mut joint_names = std::collections::HashSet::new();
    for p in people {
        for joint in neutral.names() {
            let name = if people.len() > 1 {
                format!("{}_{joint}", p.name)
            } else {
                joint.to_string()
            };
            if name.len() > MAX_BVH_NAME_BYTES {
                return Err(bad(format!(
                    "person name `{}` makes joint names longer than {MAX_BVH_NAME_BYTES} bytes",
                    excerpt(p.name)
                )));
            }
            if name == "scene" || !joint_names.insert(name) {
                return Err(bad(format!(
                    "person name `{}` gives a joint name another person's has: names must \
                     differ",
                    excerpt(p.name)
                )));
            }
        }
    }
    let per_metre = 1.0 / options.units.meters();
    let several = people.len() > 1;
    let skeletons: Vec<Skeleton> = people
        .iter()
        .map(|p| {
            if options.fit_skeleton {
                neutral.fitted_to(p.positions)
            } else {
                neutral.clone()
            }
        })
        .collect();
    // Roots and bones within what the reader takes.
    for (p, skeleton) in people.iter().zip(&skeletons) {
        let far = |v: &Vec3| v.iter().any(|c| (c * per_metre).abs() > MAX_BVH_COORDINATE);
        if p.positions.iter().any(|pose| far(&pose[0])) || skeleton.offsets().iter().any(far) {
            return Err(bad(format!(
                "{}: a root or bone beyond ±{MAX_BVH_COORDINATE} file units",
                p.name
            )));
        }
    }

    let mut out = String::from("HIERARCHY\n");
    let mut depth = 0;
    if several {
        out.push_str("ROOT scene\n{\n\tOFFSET 0.000000 0.000000 0.000000\n");
        out.push_str("\tCHANNELS 3 Xposition Yposition Zposition\n");
        depth = 1;
    }
    for (p, skeleton) in people.iter().zip(&skeletons) {
        let prefix = if several {
            format!("{}_", p.name)
        } else {
            String::new()
        };
        write_joint(&mut out, skeleton, 0, depth, &prefix, several, per_metre);
    }
    if several {
        out.push_str("}\n");
    }
    let _ = writeln!(
        out,
        "MOTION\nFrames: {frames}\nFrame Time: {:.8}",
        1.0 / f64::from(options.fps)
    );
    let order = depth_first(&neutral, 0);
    let rotations: Vec<Vec<Vec<Quat>>> = people
        .iter()
        .map(|p| {
            p.positions
                .iter()
                .map(|pose| inverse_kinematics(&neutral, pose))
                .collect()
        })
        .collect();
    for t in 0..frames {
        let mut row: Vec<String> = Vec::new();
        if several {
            row.extend(["0.000000"; 3].map(String::from));
        }
        for (p, person_rotations) in people.iter().zip(&rotations) {
            let root = scale(p.positions[t][0], per_metre);
            row.extend(root.iter().map(|v| format!("{v:.6}")));
            // Channel values follow the hierarchy as written: depth first.
            for &j in &order {
                let q = person_rotations[t][j];
                row.extend(euler_zyx_degrees(q).iter().map(|v| format!("{v:.6}")));
            }
        }
        out.push_str(&row.join(" "));
        out.push('\n');
    }
    Ok(out)
}

/// `joint` and its descendants in the order BVH writes them: depth first, children in index
/// order.
fn depth_first(skeleton: &Skeleton, joint: usize) -> Vec<usize> {
    let mut out = vec![joint];
    for c in skeleton.children(joint) {
        out.extend(depth_first(skeleton, c));
    }
    out
}

/// [`write_bvh`] into the file at `path`, atomically: the text goes to a temporary file beside
/// it, renamed over `path` once complete, so a failure leaves no partial file.
pub fn write_bvh_file(
    path: &std::path::Path,
    people: &[BvhPerson],
    options: &BvhWriteOptions,
) -> Result<()> {
    let text = write_bvh(people, options)?;
    crate::shared::files::write_atomically(path, text.as_bytes())
}

fn write_joint(
    out: &mut String,
    skeleton: &Skeleton,
    joint: usize,
    depth: usize,
    prefix: &str,
    nested_root: bool,
    per_metre: f64,
) {
    let tabs = "\t".repeat(depth);
    let is_root = skeleton.parents()[joint].is_none();
    let keyword = if is_root && !nested_root {
        "ROOT"
    } else {
        "JOINT"
    };
    let offset = if is_root {
        [0.0; 3]
    } else {
        scale(skeleton.offsets()[joint], per_metre)
    };
    let name = format!("{prefix}{}", skeleton.names()[joint]);
    open_joint(out, &tabs, keyword, &name, offset, is_root);
    let children: Vec<usize> = skeleton.children(joint).collect();
    for &c in &children {
        write_joint(out, skeleton, c, depth + 1, prefix, nested_root, per_metre);
    }
    if children.is_empty() {
        // An end site along the joint's own bone, so tools draw the last bone with a length.
        let own = skeleton.offsets()[joint];
        let length = (0.5 * norm(own)).max(0.05);
        let end = scale(
            normalize(own).unwrap_or([0.0, 1.0, 0.0]),
            length * per_metre,
        );
        end_site(out, &tabs, end);
    }
    let _ = writeln!(out, "{tabs}}}");
}

/// A joint's opening lines: its keyword and name, `{`, its offset, and its channels (position
/// channels too when it `moves`).
pub(super) fn open_joint(
    out: &mut String,
    tabs: &str,
    keyword: &str,
    name: &str,
    offset: Vec3,
    moves: bool,
) {
    let _ = writeln!(out, "{tabs}{keyword} {name}");
    let _ = writeln!(out, "{tabs}{{");
    let _ = writeln!(
        out,
        "{tabs}\tOFFSET {:.6} {:.6} {:.6}",
        offset[0], offset[1], offset[2]
    );
    if moves {
        let _ = writeln!(
            out,
            "{tabs}\tCHANNELS 6 Xposition Yposition Zposition {ROTATION_CHANNELS}"
        );
    } else {
        let _ = writeln!(out, "{tabs}\tCHANNELS 3 {ROTATION_CHANNELS}");
    }
}

/// A joint's `End Site` block at `end` from it.
pub(super) fn end_site(out: &mut String, tabs: &str, end: Vec3) {
    let _ = writeln!(out, "{tabs}\tEnd Site\n{tabs}\t{{");
    let _ = writeln!(
        out,
        "{tabs}\t\tOFFSET {:.6} {:.6} {:.6}",
        end[0], end[1], end[2]
    );
    let _ = writeln!(out, "{tabs}\t}}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_angles_rebuild_the_rotation() {
        for k in 0..50 {
            let t = f64::from(k) * 0.41;
            let axis = normalize([t.sin(), t.cos(), 0.3]).unwrap();
            let q = Quat::from_axis_angle(axis, 2.5 * (1.7 * t).sin());
            let [z, y, x] = euler_zyx_degrees(q);
            let back = Quat::from_axis_angle([0.0, 0.0, 1.0], z.to_radians())
                * Quat::from_axis_angle([0.0, 1.0, 0.0], y.to_radians())
                * Quat::from_axis_angle([1.0, 0.0, 0.0], x.to_radians());
            let v = [0.3, -0.2, 0.9];
            let (a, b) = (q.rotate(v), back.rotate(v));
            assert!((0..3).all(|i| (a[i] - b[i]).abs() < 1e-9), "{q:?}");
        }
    }
}
