//! Rotations, once for the whole crate: unit quaternions (w, x, y, z; Hamilton product),
//! rotation matrices (row-major, acting on column vectors) and the two 6-D layouts in use.
//!
//! troupe's own motion (features, inverse kinematics, BVH, poses) computes in f64 through
//! [`Quat`]. MAGNet's parity with its official code needs float32 computed in the same order
//! as `onnx/troupe_onnx/magnet/transforms.py`, so the matrix functions are generic over
//! [`Real`] and called with `f32` there.

use std::ops::{Add, Div, Mul, Neg, Sub};

use crate::motion::vec3::{add, cross, dot, normalize, scale, sub, Vec3};

/// The float types rotations are computed in: `f32` for MAGNet, `f64` for the rest.
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 2.
    const TWO: Self;
    /// 0.5.
    const HALF: Self;
    /// PyTorch's `F.normalize` floor on a length (1e-12), which [`matrix_from_6d`] mirrors.
    const NORMALIZE_FLOOR: Self;
    /// The floor under the square root of [`wxyz_from_matrix`] (1e-30).
    const SQRT_FLOOR: Self;
    /// The square root.
    fn sqrt(self) -> Self;
    /// The larger of the two (the other when one is NaN), as `f32::max` and `f64::max`.
    fn max(self, other: Self) -> Self;
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    const TWO: f32 = 2.0;
    const HALF: f32 = 0.5;
    const NORMALIZE_FLOOR: f32 = 1e-12;
    const SQRT_FLOOR: f32 = 1e-30;
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    fn max(self, other: f32) -> f32 {
        f32::max(self, other)
    }
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
    const TWO: f64 = 2.0;
    const HALF: f64 = 0.5;
    const NORMALIZE_FLOOR: f64 = 1e-12;
    const SQRT_FLOOR: f64 = 1e-30;
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    fn max(self, other: f64) -> f64 {
        f64::max(self, other)
    }
}

/// A 3×3 matrix, row-major: `m[row][column]`.
pub type Mat3<T> = [[T; 3]; 3];

/// How a 6-D rotation (Zhou et al. 2019) lays out its six numbers. Both layouts hold the first
/// two columns of the rotation matrix; they differ in the order, and mixing them up gives
/// another, wrong rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SixD {
    /// `[m00, m01, m10, m11, m20, m21]`: the two columns interleaved (the 3×2 block read row by
    /// row). InterHuman's, in `interhuman262` features: InterGen's `swap_left_right_rot`
    /// mirrors by negating entries 1, 2 and 4, which are `m01, m10, m20` only in this order.
    InterleavedColumns,
    /// `[m00, m10, m20, m01, m11, m21]`: the first column, then the second. MAGNet's, in
    /// `magnet-smplx145` frames and 9-D transforms (`SO3.from_6d`, `docs/MAGNET.md`).
    ConcatenatedColumns,
}

impl SixD {
    /// The two columns that the first six values of `d` hold.
    fn columns<T: Copy>(self, d: &[T]) -> ([T; 3], [T; 3]) {
        match self {
            SixD::InterleavedColumns => ([d[0], d[2], d[4]], [d[1], d[3], d[5]]),
            SixD::ConcatenatedColumns => ([d[0], d[1], d[2]], [d[3], d[4], d[5]]),
        }
    }
}

/// The 6-D vector of `m` (its first two columns) in `layout`.
pub fn matrix_to_6d<T: Copy>(m: &Mat3<T>, layout: SixD) -> [T; 6] {
    match layout {
        SixD::InterleavedColumns => [m[0][0], m[0][1], m[1][0], m[1][1], m[2][0], m[2][1]],
        SixD::ConcatenatedColumns => [m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1]],
    }
}

/// `v / max(|v|, 1e-12)`, as PyTorch's `F.normalize`: a zero vector stays zero.
fn normalize_floored<T: Real>(v: [T; 3]) -> [T; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .sqrt()
        .max(T::NORMALIZE_FLOOR);
    [v[0] / n, v[1] / n, v[2] / n]
}

/// The rotation matrix of the first six values of `d` in `layout`, by Gram-Schmidt on its two
/// columns as MAGNet's official code computes it (`SO3.from_6d`): it never fails, and
/// degenerate columns give a degenerate matrix. [`Quat::from_6d`] refuses them instead.
pub fn matrix_from_6d<T: Real>(d: &[T], layout: SixD) -> Mat3<T> {
    let (a, b) = layout.columns(d);
    let b1 = normalize_floored(a);
    let dot = b1[0] * b[0] + b1[1] * b[1] + b1[2] * b[2];
    let b2 = normalize_floored([b[0] - dot * b1[0], b[1] - dot * b1[1], b[2] - dot * b1[2]]);
    let b3 = [
        b1[1] * b2[2] - b1[2] * b2[1],
        b1[2] * b2[0] - b1[0] * b2[2],
        b1[0] * b2[1] - b1[1] * b2[0],
    ];
    [
        [b1[0], b2[0], b3[0]],
        [b1[1], b2[1], b3[1]],
        [b1[2], b2[2], b3[2]],
    ]
}

/// The rotation matrix of the unit quaternion `[w, x, y, z]`.
pub fn matrix_from_wxyz<T: Real>(q: [T; 4]) -> Mat3<T> {
    let [w, x, y, z] = q;
    let (one, two) = (T::ONE, T::TWO);
    [
        [
            one - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
        ],
        [
            two * (x * y + w * z),
            one - two * (x * x + z * z),
            two * (y * z - w * x),
        ],
        [
            two * (x * z - w * y),
            two * (y * z + w * x),
            one - two * (x * x + y * y),
        ],
    ]
}

/// A rotation matrix's unit quaternion `[w, x, y, z]` by Mike Day's four-case formula, sign as
/// it falls and not renormalised: MAGNet's 7-D (`quaternion_from_rotation`), whose sign the
/// official code fixes this way. [`Quat::from_matrix`] (Shepperd's, renormalised) serves the
/// rest.
pub fn wxyz_from_matrix<T: Real>(r: &Mat3<T>) -> [T; 4] {
    let (m00, m11, m22) = (r[0][0], r[1][1], r[2][2]);
    let one = T::ONE;
    let (t, q) = if m22 < T::ZERO {
        if m00 > m11 {
            let t = one + m00 - m11 - m22;
            (
                t,
                [r[2][1] - r[1][2], t, r[1][0] + r[0][1], r[0][2] + r[2][0]],
            )
        } else {
            let t = one - m00 + m11 - m22;
            (
                t,
                [r[0][2] - r[2][0], r[1][0] + r[0][1], t, r[2][1] + r[1][2]],
            )
        }
    } else if m00 < -m11 {
        let t = one - m00 - m11 + m22;
        (
            t,
            [r[1][0] - r[0][1], r[0][2] + r[2][0], r[2][1] + r[1][2], t],
        )
    } else {
        let t = one + m00 + m11 + m22;
        (
            t,
            [t, r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]],
        )
    };
    let scale = T::HALF / t.max(T::SQRT_FLOOR).sqrt();
    q.map(|v| v * scale)
}

/// A rotation as a unit quaternion `w + xi + yj + zk`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quat {
    /// Scalar part.
    pub w: f64,
    /// i component.
    pub x: f64,
    /// j component.
    pub y: f64,
    /// k component.
    pub z: f64,
}

impl std::ops::Mul for Quat {
    type Output = Quat;

    /// The Hamilton product: `a * b` rotates by `b`, then by `a`.
    fn mul(self, o: Quat) -> Quat {
        Quat {
            w: self.w * o.w - self.x * o.x - self.y * o.y - self.z * o.z,
            x: self.w * o.x + self.x * o.w + self.y * o.z - self.z * o.y,
            y: self.w * o.y - self.x * o.z + self.y * o.w + self.z * o.x,
            z: self.w * o.z + self.x * o.y - self.y * o.x + self.z * o.w,
        }
    }
}

impl Quat {
    /// No rotation.
    pub const IDENTITY: Quat = Quat {
        w: 1.0,
        x: 0.0,
        y: 0.0,
        z: 0.0,
    };

    /// From `[w, x, y, z]`.
    pub fn from_wxyz(q: [f64; 4]) -> Quat {
        Quat {
            w: q[0],
            x: q[1],
            y: q[2],
            z: q[3],
        }
    }

    /// As `[w, x, y, z]`, with `w >= 0` so that equal rotations print equal.
    pub fn to_wxyz(self) -> [f64; 4] {
        let s = if self.w < 0.0 { -1.0 } else { 1.0 };
        [s * self.w, s * self.x, s * self.y, s * self.z]
    }

    /// Rotation by `angle` radians about the unit `axis`.
    pub fn from_axis_angle(axis: Vec3, angle: f64) -> Quat {
        let (s, c) = (angle / 2.0).sin_cos();
        Quat {
            w: c,
            x: axis[0] * s,
            y: axis[1] * s,
            z: axis[2] * s,
        }
    }

    /// The inverse rotation (the conjugate of a unit quaternion).
    pub fn conj(self) -> Quat {
        Quat {
            w: self.w,
            x: -self.x,
            y: -self.y,
            z: -self.z,
        }
    }

    /// Scaled to unit length (identity if it has none).
    pub fn normalized(self) -> Quat {
        let n = (self.w * self.w + self.x * self.x + self.y * self.y + self.z * self.z).sqrt();
        if n > 0.0 && n.is_finite() {
            Quat {
                w: self.w / n,
                x: self.x / n,
                y: self.y / n,
                z: self.z / n,
            }
        } else {
            Quat::IDENTITY
        }
    }

    /// `v` rotated by this quaternion.
    pub fn rotate(self, v: Vec3) -> Vec3 {
        // v + 2 q_v × (q_v × v + w v)
        let q = [self.x, self.y, self.z];
        let t = add(cross(q, v), scale(v, self.w));
        add(v, scale(cross(q, t), 2.0))
    }

    /// The shortest-arc rotation taking direction `from` onto direction `to` (neither needs unit
    /// length). `None` when either has no direction. Antiparallel vectors turn by half a turn
    /// about an axis perpendicular to `from`.
    pub fn between(from: Vec3, to: Vec3) -> Option<Quat> {
        let (a, b) = (normalize(from)?, normalize(to)?);
        let w = 1.0 + dot(a, b);
        if w < 1e-12 {
            // Half a turn: any axis perpendicular to `a` will do; pick the most stable one.
            let other = if a[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let axis = normalize(cross(a, other))?;
            return Some(Quat::from_axis_angle(axis, std::f64::consts::PI));
        }
        let c = cross(a, b);
        Some(
            Quat {
                w,
                x: c[0],
                y: c[1],
                z: c[2],
            }
            .normalized(),
        )
    }

    /// The rotation matrix, row-major, acting on column vectors.
    pub fn to_matrix(self) -> Mat3<f64> {
        matrix_from_wxyz([self.w, self.x, self.y, self.z])
    }

    /// The quaternion of a rotation matrix (row-major, column vectors); Shepperd's method, which
    /// stays accurate for every angle.
    pub fn from_matrix(m: Mat3<f64>) -> Quat {
        let trace = m[0][0] + m[1][1] + m[2][2];
        let q = if trace > 0.0 {
            let s = (trace + 1.0).sqrt() * 2.0;
            Quat {
                w: s / 4.0,
                x: (m[2][1] - m[1][2]) / s,
                y: (m[0][2] - m[2][0]) / s,
                z: (m[1][0] - m[0][1]) / s,
            }
        } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
            let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
            Quat {
                w: (m[2][1] - m[1][2]) / s,
                x: s / 4.0,
                y: (m[0][1] + m[1][0]) / s,
                z: (m[0][2] + m[2][0]) / s,
            }
        } else if m[1][1] > m[2][2] {
            let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
            Quat {
                w: (m[0][2] - m[2][0]) / s,
                x: (m[0][1] + m[1][0]) / s,
                y: s / 4.0,
                z: (m[1][2] + m[2][1]) / s,
            }
        } else {
            let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
            Quat {
                w: (m[1][0] - m[0][1]) / s,
                x: (m[0][2] + m[2][0]) / s,
                y: (m[1][2] + m[2][1]) / s,
                z: s / 4.0,
            }
        };
        q.normalized()
    }

    /// The 6-D vector of this rotation in `layout`.
    pub fn to_6d(self, layout: SixD) -> [f64; 6] {
        matrix_to_6d(&self.to_matrix(), layout)
    }

    /// The rotation nearest a 6-D vector in `layout` ([`Quat::from_columns`] on its two
    /// columns). `None` when the columns are (nearly) parallel or zero, which no rotation
    /// produces.
    pub fn from_6d(d: [f64; 6], layout: SixD) -> Option<Quat> {
        let (first, second) = layout.columns(&d);
        Quat::from_columns(first, second)
    }

    /// The rotation whose first matrix column is `first`'s direction and whose second is
    /// `second` made perpendicular to it (Gram-Schmidt; neither needs unit length). `None`
    /// when either is degenerate or they are parallel.
    pub fn from_columns(first: Vec3, second: Vec3) -> Option<Quat> {
        let x = normalize(first)?;
        let y = normalize(sub(second, scale(x, dot(x, second))))?;
        Some(Quat::from_frame(x, y))
    }

    /// The rotation whose matrix has the orthonormal columns `x`, `y`, `x × y`.
    pub fn from_frame(x: Vec3, y: Vec3) -> Quat {
        let z = cross(x, y);
        Quat::from_matrix([[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAYOUTS: [SixD; 2] = [SixD::InterleavedColumns, SixD::ConcatenatedColumns];

    fn close(a: Vec3, b: Vec3) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12)
    }

    /// 64 rotations spread over axes and angles in (-3, 8) radians: every branch of both
    /// matrix-to-quaternion formulas.
    fn rotations() -> impl Iterator<Item = Quat> {
        (0..64).map(|k| {
            let t = f64::from(k) * 0.37;
            let axis = normalize([t.sin(), (2.0 * t).cos(), 0.3 + t.cos()]).unwrap();
            Quat::from_axis_angle(axis, t * 1.7 - 3.0)
        })
    }

    /// `a` and `b` are the same rotation: equal quaternions up to sign.
    fn same_rotation<T: Real + Into<f64>>(a: [T; 4], b: [T; 4], tol: f64) -> bool {
        let (a, b) = (a.map(Into::into), b.map(Into::into));
        let plus = (0..4).all(|i| (a[i] - b[i]).abs() < tol);
        let minus = (0..4).all(|i| (a[i] + b[i]).abs() < tol);
        plus || minus
    }

    #[test]
    fn f64_matrix_and_each_6d_layout_round_trip_every_quadrant() {
        let v = [0.3, -1.2, 0.7];
        for q in rotations() {
            let back = Quat::from_matrix(q.to_matrix());
            assert!(close(q.rotate(v), back.rotate(v)));
            for layout in LAYOUTS {
                let six = Quat::from_6d(q.to_6d(layout), layout).unwrap();
                assert!(close(q.rotate(v), six.rotate(v)), "{layout:?}");
            }
        }
    }

    #[test]
    fn f32_each_6d_layout_round_trips() {
        for q in rotations() {
            let wxyz = [q.w, q.x, q.y, q.z].map(|v| v as f32);
            let m = matrix_from_wxyz(wxyz);
            for layout in LAYOUTS {
                let back = matrix_from_6d(&matrix_to_6d(&m, layout), layout);
                for i in 0..3 {
                    for j in 0..3 {
                        assert!((back[i][j] - m[i][j]).abs() < 1e-6, "{layout:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_layouts_hold_the_first_two_columns_in_their_orders() {
        let m = [[0.0, 1.0, 2.0], [10.0, 11.0, 12.0], [20.0, 21.0, 22.0]];
        assert_eq!(
            matrix_to_6d(&m, SixD::InterleavedColumns),
            [0.0, 1.0, 10.0, 11.0, 20.0, 21.0]
        );
        assert_eq!(
            matrix_to_6d(&m, SixD::ConcatenatedColumns),
            [0.0, 10.0, 20.0, 1.0, 11.0, 21.0]
        );
        // Read in the other layout, a 6-D vector is another rotation.
        let q = Quat::from_axis_angle(normalize([0.2, 0.9, -0.4]).unwrap(), 0.8);
        let wrong = Quat::from_6d(q.to_6d(SixD::InterleavedColumns), SixD::ConcatenatedColumns);
        let v = [0.3, -1.2, 0.7];
        assert!(!close(q.rotate(v), wrong.unwrap().rotate(v)));
    }

    #[test]
    fn the_floored_and_the_checked_gram_schmidt_agree_but_on_degenerate_columns() {
        let d = [0.9, 0.1, -0.3, 0.2, 1.1, 0.4];
        for layout in LAYOUTS {
            let floored = matrix_from_6d(&d, layout);
            let checked = Quat::from_6d(d, layout).unwrap().to_matrix();
            for i in 0..3 {
                for j in 0..3 {
                    assert!((floored[i][j] - checked[i][j]).abs() < 1e-12);
                }
            }
        }
        let flat = [1.0, 0.0, 0.0, 2.0, 0.0, 0.0];
        assert!(Quat::from_6d(flat, SixD::ConcatenatedColumns).is_none());
        let m = matrix_from_6d(&flat.map(|v| v as f32), SixD::ConcatenatedColumns);
        assert!(m.iter().flatten().all(|v| v.is_finite()));
        assert!(matrix_from_6d(&[0f32; 6], SixD::ConcatenatedColumns)
            .iter()
            .flatten()
            .all(|v| *v == 0.0));
    }

    #[test]
    fn quaternion_and_matrix_round_trip_in_both_precisions() {
        for q in rotations() {
            let wxyz = [q.w, q.x, q.y, q.z];
            // f64: Shepperd's and Day's give the same rotation.
            let m = q.to_matrix();
            let shepperd = Quat::from_matrix(m);
            let shepperd = [shepperd.w, shepperd.x, shepperd.y, shepperd.z];
            assert!(same_rotation(shepperd, wxyz, 1e-12));
            assert!(same_rotation(wxyz_from_matrix(&m), wxyz, 1e-12));
            // f32: Day's, as MAGNet computes it.
            let wxyz32 = wxyz.map(|v| v as f32);
            let back = wxyz_from_matrix(&matrix_from_wxyz(wxyz32));
            assert!(same_rotation(back, wxyz32, 1e-6));
        }
    }

    #[test]
    fn days_formula_on_known_rotations() {
        let rz90 = [[0.0f32, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let q = wxyz_from_matrix(&rz90);
        let h = 0.5f32.sqrt();
        assert!((q[0] - h).abs() < 1e-6 && (q[3] - h).abs() < 1e-6);
        let q = wxyz_from_matrix(&[[1.0f32, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]);
        assert!((q[1].abs() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn between_takes_one_direction_onto_the_other() {
        let cases = [
            ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([0.0, 0.0, 2.0], [0.0, 0.0, -3.0]),
            ([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]),
            ([0.3, -0.4, 0.1], [0.3, -0.4, 0.1]),
        ];
        for (a, b) in cases {
            let q = Quat::between(a, b).unwrap();
            assert!(close(
                q.rotate(normalize(a).unwrap()),
                normalize(b).unwrap()
            ));
        }
        assert!(Quat::between([0.0; 3], [1.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn interleaved_columns_match_the_interhuman_mirror_rule() {
        // Mirroring x (M R M, M = diag(-1, 1, 1)) negates 6-D entries 1, 2 and 4 in InterGen.
        let q = Quat::from_axis_angle(normalize([0.2, 0.9, -0.4]).unwrap(), 0.8);
        let m = q.to_matrix();
        let s = [-1.0, 1.0, 1.0];
        let mut mirrored = m;
        for (i, row) in mirrored.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v *= s[i] * s[j];
            }
        }
        let layout = SixD::InterleavedColumns;
        let (a, b) = (q.to_6d(layout), Quat::from_matrix(mirrored).to_6d(layout));
        for i in 0..6 {
            let sign = if [1, 2, 4].contains(&i) { -1.0 } else { 1.0 };
            assert!((a[i] * sign - b[i]).abs() < 1e-12, "entry {i}");
        }
    }
}
