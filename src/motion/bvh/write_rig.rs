//! The BVH writer for a caller's rig: its hierarchy and rest offsets, and poses retargeted onto
//! it, so that BVH-only tools get the motion on the character too.
//!
//! BVH has no rest rotations: each joint's channels hold its whole local rotation (a glTF or
//! FBX rig's rest rotation included), which forward kinematics composes exactly as the rig's
//! own transforms do; only the file's all-zero pose differs from the rig's rest pose. Axes are
//! BVH's (Y up, right-handed) in the units asked for; the root joint and the joint whose
//! translation moves (the pelvis) get position channels.

use std::fmt::Write as _;

use super::parse::{MAX_BVH_COORDINATE, MAX_BVH_NAME_BYTES};
use super::write::{end_site, euler_zyx_degrees, open_joint, BvhWriteOptions};
use crate::motion::rig::{Rig, RigPose};
use crate::motion::vec3::Vec3;
use crate::motion::world::JointsFormat;
use crate::shared::error::{excerpt, Error, Result};

/// The text of a BVH file of `rig` posed by `poses` (at least one, each with one rotation per
/// joint and the same moving joint). `options.fit_skeleton` does not apply: the rig is the
/// skeleton.
pub fn write_rig_bvh(rig: &Rig, poses: &[RigPose], options: &BvhWriteOptions) -> Result<String> {
    let bad =
        |m: String| Error::InvalidInput(format!("BVH out on rig {}: {m}", excerpt(rig.name())));
    let moving = rig.check_poses(poses, options.fps, "BVH")?;
    for name in rig.names() {
        if name.len() > MAX_BVH_NAME_BYTES
            || name
                .chars()
                .any(|c| c.is_whitespace() || c == '{' || c == '}')
        {
            return Err(bad(format!(
                "joint `{}`: BVH names have no spaces or braces",
                excerpt(name)
            )));
        }
    }
    let format = JointsFormat {
        units: options.units,
        ..JointsFormat::default()
    };
    let out_rig = rig.with_format(format);
    let far = |v: &Vec3| v.iter().any(|c| c.abs() > MAX_BVH_COORDINATE);
    let translation = |pose: &RigPose| {
        format.point_from_canonical(rig.format().point_to_canonical(pose.root_translation))
    };
    if out_rig.offsets().iter().any(far) || poses.iter().any(|p| far(&translation(p))) {
        return Err(bad(format!(
            "a bone or the root beyond ±{MAX_BVH_COORDINATE} file units"
        )));
    }
    let order = depth_first(&out_rig, 0);
    let mut text = String::from("HIERARCHY\n");
    write_joint(&mut text, &out_rig, 0, 0, moving);
    let _ = writeln!(
        text,
        "MOTION\nFrames: {}\nFrame Time: {:.8}",
        poses.len(),
        1.0 / f64::from(options.fps)
    );
    for pose in poses {
        let mut row: Vec<String> = Vec::new();
        for &j in &order {
            if j == 0 || j == moving {
                let t = if j == moving {
                    translation(pose)
                } else {
                    out_rig.offsets()[j]
                };
                row.extend(t.iter().map(|v| format!("{v:.6}")));
            }
            let q = format.rotation_from_canonical_axes(
                rig.format().rotation_to_canonical_axes(pose.rotations[j]),
            );
            row.extend(euler_zyx_degrees(q).iter().map(|v| format!("{v:.6}")));
        }
        text.push_str(&row.join(" "));
        text.push('\n');
    }
    Ok(text)
}

/// [`write_rig_bvh`] into the file at `path`, atomically.
pub fn write_rig_bvh_file(
    path: &std::path::Path,
    rig: &Rig,
    poses: &[RigPose],
    options: &BvhWriteOptions,
) -> Result<()> {
    let text = write_rig_bvh(rig, poses, options)?;
    crate::shared::files::write_atomically(path, text.as_bytes())
}

fn depth_first(rig: &Rig, joint: usize) -> Vec<usize> {
    let mut out = vec![joint];
    for c in rig.children(joint) {
        out.extend(depth_first(rig, c));
    }
    out
}

fn write_joint(out: &mut String, rig: &Rig, joint: usize, depth: usize, moving: usize) {
    let tabs = "\t".repeat(depth);
    let keyword = if joint == 0 { "ROOT" } else { "JOINT" };
    let moves = joint == 0 || joint == moving;
    open_joint(
        out,
        &tabs,
        keyword,
        &rig.names()[joint],
        rig.offsets()[joint],
        moves,
    );
    let children: Vec<usize> = rig.children(joint).collect();
    for &c in &children {
        write_joint(out, rig, c, depth + 1, moving);
    }
    if children.is_empty() {
        // The rig's end site, or one along the joint's own bone so tools draw it with a length.
        let end = rig.end_sites()[joint].unwrap_or(rig.offsets()[joint].map(|v| 0.5 * v));
        end_site(out, &tabs, end);
    }
    let _ = writeln!(out, "{tabs}}}");
}
