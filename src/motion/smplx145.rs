//! The `magnet-smplx145` frame layout (MAGNet's frames in troupe), and its body joints' positions
//! on the t2m-22 skeleton, for pictures, BVH files and JSON poses.
//!
//! Per person and frame, 145 floats, y up, metres: SMPL-X betas (10), the 21 body joints' local
//! rotations (6-D, [`SixD::ConcatenatedColumns`], 126), the pelvis's pose in the world (9-D: 6-D
//! rotation, then translation). SMPL-X's first 22 joints are the t2m-22 joints in the same order,
//! with the same rest pose (a T-pose facing +Z, +X the body's left) and the same local-rotation
//! convention, so forward kinematics over the t2m-22 skeleton poses them. The bone lengths are the
//! skeleton's (troupe's neutral body), not the person's betas: SMPL-X's shape space needs its body
//! model, whose licence keeps it out of troupe.

use std::ops::Range;

use crate::motion::rotation::{Quat, SixD};
use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};
use crate::motion::vec3::{add, Vec3};
use crate::shared::error::{Error, Result};

/// The layout's name (`motion.layout` in a magnet bundle's manifest).
pub const SMPLX145: &str = "magnet-smplx145";
/// Floats per person and frame.
pub const SMPLX145_DIM: usize = 145;
/// SMPL-X shape coefficients.
pub const SMPLX145_BETAS: Range<usize> = 0..10;
/// The 21 body joints' local rotations, 6-D each.
pub const SMPLX145_BODY: Range<usize> = 10..136;
/// The pelvis's pose in the world, 9-D.
pub const SMPLX145_ROOT: Range<usize> = 136..145;

/// A 6-D rotation of a frame as a quaternion; `None` when its columns are (nearly) parallel or
/// zero.
fn rotation(d: &[f32]) -> Option<Quat> {
    Quat::from_6d(
        std::array::from_fn(|i| f64::from(d[i])),
        SixD::ConcatenatedColumns,
    )
}

/// The joint positions `[frames][22]` (metres, y up, in the frames' world) of row-major
/// `magnet-smplx145` frames of one person, posed on `skeleton` (22 joints in SMPL order, such as
/// [`Skeleton::t2m22`]). The pelvis sits at the frame's root translation.
pub fn smplx145_positions(frames: &[f32], skeleton: &Skeleton) -> Result<Vec<Vec<Vec3>>> {
    if skeleton.len() != T2M22_JOINTS {
        return Err(Error::InvalidInput(format!(
            "posing {SMPLX145} frames needs a 22-joint skeleton in SMPL order, `{}` has {}",
            skeleton.name(),
            skeleton.len()
        )));
    }
    if !frames.len().is_multiple_of(SMPLX145_DIM) {
        return Err(Error::InvalidInput(format!(
            "{} floats is not a whole number of {SMPLX145_DIM}-float {SMPLX145} frames",
            frames.len()
        )));
    }
    let (parents, offsets) = (skeleton.parents(), skeleton.offsets());
    let mut out = Vec::with_capacity(frames.len() / SMPLX145_DIM);
    for (f, frame) in frames.chunks_exact(SMPLX145_DIM).enumerate() {
        if let Some(i) = frame.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "frame {f}: value {i} is not finite"
            )));
        }
        let degenerate = |what: String| {
            Error::InvalidInput(format!(
                "frame {f}: the 6-D rotation of {what} has parallel or zero columns"
            ))
        };
        let root = &frame[SMPLX145_ROOT];
        let mut world = vec![Quat::IDENTITY; T2M22_JOINTS];
        let mut pos = vec![[0f64; 3]; T2M22_JOINTS];
        world[0] = rotation(&root[..6]).ok_or_else(|| degenerate("the root".into()))?;
        pos[0] = [root[6] as f64, root[7] as f64, root[8] as f64];
        for j in 1..T2M22_JOINTS {
            let p = match parents[j] {
                Some(p) if p < j => p,
                _ => {
                    return Err(Error::InvalidInput(format!(
                        "skeleton `{}`: joint {j} needs a parent listed before it (SMPL order)",
                        skeleton.name()
                    )))
                }
            };
            let body = &frame[SMPLX145_BODY][(j - 1) * 6..j * 6];
            let local = rotation(body)
                .ok_or_else(|| degenerate(format!("joint {}", skeleton.names()[j])))?;
            pos[j] = add(pos[p], world[p].rotate(offsets[j]));
            world[j] = world[p] * local;
        }
        out.push(pos);
    }
    Ok(out)
}

/// The rotations of row-major `magnet-smplx145` frames of one person, per frame in t2m-22
/// order: joint 0's world orientation, then the 21 body joints' local rotations (what
/// [`crate::motion::SourceFrame::rotations`] takes, so that retargeting keeps the twist about
/// each bone that positions cannot carry).
pub fn smplx145_rotations(frames: &[f32]) -> Result<Vec<Vec<Quat>>> {
    if !frames.len().is_multiple_of(SMPLX145_DIM) {
        return Err(Error::InvalidInput(format!(
            "{} floats is not a whole number of {SMPLX145_DIM}-float {SMPLX145} frames",
            frames.len()
        )));
    }
    frames
        .chunks_exact(SMPLX145_DIM)
        .enumerate()
        .map(|(f, frame)| {
            let bad = || {
                Error::InvalidInput(format!(
                    "frame {f}: a value is not finite or a 6-D rotation has parallel or zero \
                     columns"
                ))
            };
            if frame.iter().any(|v| !v.is_finite()) {
                return Err(bad());
            }
            let mut out = Vec::with_capacity(T2M22_JOINTS);
            out.push(rotation(&frame[SMPLX145_ROOT][..6]).ok_or_else(bad)?);
            for j in 1..T2M22_JOINTS {
                out.push(rotation(&frame[SMPLX145_BODY][(j - 1) * 6..j * 6]).ok_or_else(bad)?);
            }
            Ok(out)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::vec3::sub;

    fn frame(root: Quat, at: Vec3) -> Vec<f32> {
        let mut f = vec![0f32; SMPLX145_DIM];
        let identity6 = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        for j in 0..21 {
            f[10 + j * 6..16 + j * 6].copy_from_slice(&identity6);
        }
        let cols = root.to_6d(SixD::ConcatenatedColumns);
        for (i, v) in cols.iter().enumerate() {
            f[136 + i] = *v as f32;
        }
        for i in 0..3 {
            f[142 + i] = at[i] as f32;
        }
        f
    }

    fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < tol)
    }

    #[test]
    fn the_rest_pose_is_the_skeletons_rest_pose_at_the_root() {
        let skel = Skeleton::t2m22();
        let rest = skel.rest_positions();
        let at = [1.0, 0.9, -2.0];
        let pos = smplx145_positions(&frame(Quat::IDENTITY, at), &skel).unwrap();
        for j in 0..22 {
            let want = add(sub(rest[j], rest[0]), at);
            assert!(close(pos[0][j], want, 1e-6), "joint {j}");
        }
    }

    #[test]
    fn rotations_compose_down_the_chain() {
        let skel = Skeleton::t2m22();
        let rest = skel.rest_positions();
        // Turn the body 90 degrees about y: its left (+X) goes to -Z.
        let turn = Quat::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2);
        let mut f = frame(turn, [0.0, 1.0, 0.0]);
        // Bend the left knee (joint 4) 90 degrees about x: the ankle swings back.
        let bend = Quat::from_axis_angle([1.0, 0.0, 0.0], std::f64::consts::FRAC_PI_2);
        let six = bend.to_6d(SixD::ConcatenatedColumns);
        for (i, v) in six.iter().enumerate() {
            f[10 + 3 * 6 + i] = *v as f32;
        }
        let pos = smplx145_positions(&f, &skel).unwrap();
        let hip = sub(rest[1], rest[0]);
        assert!(close(
            pos[0][1],
            add([0.0, 1.0, 0.0], turn.rotate(hip)),
            1e-6
        ));
        let shank = skel.offsets()[7];
        let want_ankle = add(pos[0][4], turn.rotate(bend.rotate(shank)));
        assert!(close(pos[0][7], want_ankle, 1e-6));
    }

    #[test]
    fn bad_frames_are_refused() {
        let skel = Skeleton::t2m22();
        let mut f = frame(Quat::IDENTITY, [0.0; 3]);
        assert!(smplx145_positions(&f[..144], &skel).is_err());
        f[20] = f32::NAN;
        assert!(smplx145_positions(&f, &skel).is_err());
        let mut g = frame(Quat::IDENTITY, [0.0; 3]);
        g[10..16].copy_from_slice(&[0.0; 6]);
        let e = smplx145_positions(&g, &skel).unwrap_err().to_string();
        assert!(e.contains("left_hip"), "{e}");
    }
}
