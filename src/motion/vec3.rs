//! 3-vectors in f64, the algebra beneath positions and rotations: f64 so that a round trip
//! through features and back loses only f32 rounding.

use crate::shared::error::Result;
use crate::shared::snapshot::{bad, SnapshotReader, SnapshotWriter};

/// A 3-vector.
pub type Vec3 = [f64; 3];

/// Writes optional points (a pose, a pin) to a snapshot, bit for bit.
pub(crate) fn save_points(w: &mut SnapshotWriter, points: Option<&[Vec3]>) {
    w.bool(points.is_some());
    if let Some(points) = points {
        w.f64s(points.as_flattened());
    }
}

/// The points [`save_points`] wrote: `None`, or exactly `n` finite points.
pub(crate) fn load_points(
    r: &mut SnapshotReader,
    what: &str,
    n: usize,
) -> Result<Option<Vec<Vec3>>> {
    if !r.bool(what)? {
        return Ok(None);
    }
    let values = r.f64s(what, 3 * n)?;
    if values.len() != 3 * n || !values.iter().all(|v| v.is_finite()) {
        return Err(bad(format!("{what}: not {n} finite points")));
    }
    Ok(Some(
        values.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
    ))
}

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

/// `v` with its component along `axis` (a unit vector) removed.
pub fn reject(v: Vec3, axis: Vec3) -> Vec3 {
    sub(v, scale(axis, dot(v, axis)))
}
