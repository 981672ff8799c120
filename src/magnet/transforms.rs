//! Rigid transforms as MAGNet stores them (`docs/spec/magnet.md` §0): "9-D" = a 6-D rotation
//! ([`SixD::ConcatenatedColumns`]) then tx, ty, tz; "7-D" = wxyz_xyz (the quaternion by
//! [`wxyz_from_matrix`](crate::motion::rotation::wxyz_from_matrix)); 4x4 matrices where
//! `compose(a, b)` applies `b` first. Mirrors `onnx/troupe_onnx/magnet/transforms.py`, whose
//! rotations are `crate::motion::rotation`'s, in f32 as the official code computes them.

use crate::motion::rotation::{matrix_from_6d, matrix_to_6d, SixD};

/// A homogeneous transform, row-major.
pub type Mat4 = [[f32; 4]; 4];

/// The identity.
pub const IDENTITY: Mat4 = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// A 9-D transform as a matrix.
pub fn from_9d(t: &[f32]) -> Mat4 {
    let r = matrix_from_6d(&t[..6], SixD::ConcatenatedColumns);
    [
        [r[0][0], r[0][1], r[0][2], t[6]],
        [r[1][0], r[1][1], r[1][2], t[7]],
        [r[2][0], r[2][1], r[2][2], t[8]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// A matrix as a 9-D transform.
pub fn to_9d(m: &Mat4, out: &mut [f32]) {
    let r = [0, 1, 2].map(|i| [m[i][0], m[i][1], m[i][2]]);
    out[..6].copy_from_slice(&matrix_to_6d(&r, SixD::ConcatenatedColumns));
    out[6..9].copy_from_slice(&[m[0][3], m[1][3], m[2][3]]);
}

/// `a ∘ b`: `b` first.
pub fn compose(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut out = [[0f32; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            let mut acc = 0f32;
            for k in 0..4 {
                acc += a[i][k] * b[k][j];
            }
            out[i][j] = acc;
        }
    }
    out
}

/// The inverse of a rigid transform.
pub fn inverse(m: &Mat4) -> Mat4 {
    let mut out = IDENTITY;
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = m[j][i];
        }
    }
    for row in out.iter_mut().take(3) {
        row[3] = -(row[0] * m[0][3] + row[1] * m[1][3] + row[2] * m[2][3]);
    }
    out
}

/// The canonical frame of a root pose (§1.2 step 4): the root's heading about y (the yaw of
/// its x axis) at its position on the floor.
pub fn canonical_frame(root: &Mat4) -> Mat4 {
    let (ex, ez) = (root[0][0], root[2][0]);
    let psi = -(ez.atan2(ex));
    let (s, c) = psi.sin_cos();
    [
        [c, 0.0, s, root[0][3]],
        [0.0, 1.0, 0.0, 0.0],
        [-s, 0.0, c, root[2][3]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_inverse() {
        let t = [0.9f32, 0.1, -0.3, 0.2, 1.1, 0.4, 0.5, -0.2, 1.5];
        let m = from_9d(&t);
        let mut back = [0f32; 9];
        to_9d(&m, &mut back);
        let again = from_9d(&back);
        let id = compose(&inverse(&m), &m);
        for i in 0..4 {
            for j in 0..4 {
                assert!((again[i][j] - m[i][j]).abs() < 1e-6);
                assert!((id[i][j] - IDENTITY[i][j]).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn canonical_frames_keep_heading_and_floor_position() {
        let yaw = 0.7f32;
        let root = compose(
            &[
                [yaw.cos(), 0.0, yaw.sin(), 1.0],
                [0.0, 1.0, 0.0, 0.9],
                [-yaw.sin(), 0.0, yaw.cos(), -2.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
            &IDENTITY,
        );
        let c = canonical_frame(&root);
        for i in 0..3 {
            for j in 0..3 {
                assert!((c[i][j] - root[i][j]).abs() < 1e-6);
            }
        }
        assert_eq!((c[0][3], c[1][3], c[2][3]), (1.0, 0.0, -2.0));
    }
}
