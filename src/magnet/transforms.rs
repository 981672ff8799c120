//! Rigid transforms as MAGNet stores them (`shared/spec/magnet.md` §0): "9-D" =
//! `[6-D rotation (the first two columns of R), tx, ty, tz]`, "7-D" = wxyz_xyz, and 4x4
//! matrices where `compose(a, b)` applies `b` first. Mirrors
//! `onnx/troupe_onnx/magnet/transforms.py`.

/// A homogeneous transform, row-major.
pub type Mat4 = [[f32; 4]; 4];

/// The identity.
pub const IDENTITY: Mat4 = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-12);
    [v[0] / n, v[1] / n, v[2] / n]
}

/// The rotation of a 6-D vector by Gram-Schmidt on its two columns (`SO3.from_6d`), as columns.
pub fn rotation_from_6d(d: &[f32]) -> [[f32; 3]; 3] {
    let b1 = normalize([d[0], d[1], d[2]]);
    let dot = b1[0] * d[3] + b1[1] * d[4] + b1[2] * d[5];
    let b2 = normalize([d[3] - dot * b1[0], d[4] - dot * b1[1], d[5] - dot * b1[2]]);
    let b3 = [
        b1[1] * b2[2] - b1[2] * b2[1],
        b1[2] * b2[0] - b1[0] * b2[2],
        b1[0] * b2[1] - b1[1] * b2[0],
    ];
    // r[i][j]: row i, column j; the columns are b1, b2, b3.
    [
        [b1[0], b2[0], b3[0]],
        [b1[1], b2[1], b3[1]],
        [b1[2], b2[2], b3[2]],
    ]
}

/// `[R00, R10, R20, R01, R11, R21]`.
pub fn rotation_to_6d(r: &[[f32; 3]; 3], out: &mut [f32]) {
    out[..6].copy_from_slice(&[r[0][0], r[1][0], r[2][0], r[0][1], r[1][1], r[2][1]]);
}

/// A 9-D transform as a matrix.
pub fn from_9d(t: &[f32]) -> Mat4 {
    let r = rotation_from_6d(&t[..6]);
    [
        [r[0][0], r[0][1], r[0][2], t[6]],
        [r[1][0], r[1][1], r[1][2], t[7]],
        [r[2][0], r[2][1], r[2][2], t[8]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// A matrix as a 9-D transform.
pub fn to_9d(m: &Mat4, out: &mut [f32]) {
    out[..9].copy_from_slice(&[
        m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1], m[0][3], m[1][3], m[2][3],
    ]);
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

/// A rotation's unit quaternion, wxyz, by Mike Day's four-case formula.
pub fn quaternion(r: &[[f32; 3]; 3]) -> [f32; 4] {
    let (m00, m11, m22) = (r[0][0], r[1][1], r[2][2]);
    let (t, q) = if m22 < 0.0 {
        if m00 > m11 {
            let t = 1.0 + m00 - m11 - m22;
            (
                t,
                [r[2][1] - r[1][2], t, r[1][0] + r[0][1], r[0][2] + r[2][0]],
            )
        } else {
            let t = 1.0 - m00 + m11 - m22;
            (
                t,
                [r[0][2] - r[2][0], r[1][0] + r[0][1], t, r[2][1] + r[1][2]],
            )
        }
    } else if m00 < -m11 {
        let t = 1.0 - m00 - m11 + m22;
        (
            t,
            [r[1][0] - r[0][1], r[0][2] + r[2][0], r[2][1] + r[1][2], t],
        )
    } else {
        let t = 1.0 + m00 + m11 + m22;
        (
            t,
            [t, r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]],
        )
    };
    let scale = 0.5 / t.max(1e-30).sqrt();
    q.map(|v| v * scale)
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
    fn quaternions_of_known_rotations() {
        let rz90 = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let q = quaternion(&rz90);
        let h = 0.5f32.sqrt();
        assert!((q[0] - h).abs() < 1e-6 && (q[3] - h).abs() < 1e-6);
        let q = quaternion(&[[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]);
        assert!((q[1].abs() - 1.0).abs() < 1e-6);
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
