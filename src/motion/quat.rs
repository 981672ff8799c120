//! The little 3-D algebra motion needs: vectors, unit quaternions (w, x, y, z; Hamilton product,
//! acting on column vectors) and rotation matrices. Computed in f64 so that a round trip through
//! features and back loses only f32 rounding.

/// A 3-vector.
pub type Vec3 = [f64; 3];

/// Component-wise `a - b`.
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Component-wise `a + b`.
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a * s`.
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Dot product.
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product `a × b`.
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Euclidean length.
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// `a / |a|`, or `None` when `a` is too short to have a direction.
pub fn normalize(a: Vec3) -> Option<Vec3> {
    let n = norm(a);
    (n > 1e-9 && n.is_finite()).then(|| scale(a, 1.0 / n))
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
    pub fn to_matrix(self) -> [[f64; 3]; 3] {
        let Quat { w, x, y, z } = self;
        [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ]
    }

    /// The quaternion of a rotation matrix (row-major, column vectors); Shepperd's method, which
    /// stays accurate for every angle.
    pub fn from_matrix(m: [[f64; 3]; 3]) -> Quat {
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

    /// The continuous 6-D representation as InterHuman stores it: the first two columns of the
    /// rotation matrix, flattened row by row, `[m00, m01, m10, m11, m20, m21]`. (InterGen's
    /// `swap_left_right_rot` mirrors a rotation by negating entries 1, 2 and 4, which is
    /// `m01, m10, m20` in exactly this order.)
    pub fn to_6d(self) -> [f64; 6] {
        let m = self.to_matrix();
        [m[0][0], m[0][1], m[1][0], m[1][1], m[2][0], m[2][1]]
    }

    /// The rotation nearest a 6-D vector (Gram-Schmidt on its two columns, Zhou et al. 2019).
    /// `None` when the columns are (nearly) parallel or zero, which no rotation produces.
    pub fn from_6d(d: [f64; 6]) -> Option<Quat> {
        let a = normalize([d[0], d[2], d[4]])?;
        let b_raw = [d[1], d[3], d[5]];
        let b = normalize(sub(b_raw, scale(a, dot(a, b_raw))))?;
        let c = cross(a, b);
        Some(Quat::from_matrix([
            [a[0], b[0], c[0]],
            [a[1], b[1], c[1]],
            [a[2], b[2], c[2]],
        ]))
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

    fn close(a: Vec3, b: Vec3) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12)
    }

    #[test]
    fn matrix_and_6d_round_trip_every_quadrant() {
        for k in 0..64 {
            let t = f64::from(k) * 0.37;
            let axis = normalize([t.sin(), (2.0 * t).cos(), 0.3 + t.cos()]).unwrap();
            let q = Quat::from_axis_angle(axis, t * 1.7 - 3.0);
            let back = Quat::from_matrix(q.to_matrix());
            let v = [0.3, -1.2, 0.7];
            assert!(close(q.rotate(v), back.rotate(v)));
            let six = Quat::from_6d(q.to_6d()).unwrap();
            assert!(close(q.rotate(v), six.rotate(v)));
        }
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
    fn six_d_matches_the_interhuman_mirror_rule() {
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
        let (a, b) = (q.to_6d(), Quat::from_matrix(mirrored).to_6d());
        for i in 0..6 {
            let sign = if [1, 2, 4].contains(&i) { -1.0 } else { 1.0 };
            assert!((a[i] * sign - b[i]).abs() < 1e-12, "entry {i}");
        }
    }
}
