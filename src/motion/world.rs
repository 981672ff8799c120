//! The caller's world: how the joint positions a caller hands troupe are measured (units, up
//! axis, handedness, frame rate), and the conversion to and from troupe's canonical axes
//! (metres, +Y up, right-handed, +X the body's left when it faces +Z).

use crate::motion::rotation::Quat;
use crate::motion::vec3::Vec3;
use crate::shared::error::{Error, Result};

/// Length unit of caller positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u32)]
pub enum Units {
    /// Metres.
    #[default]
    Meters = 0,
    /// Centimetres (most BVH files, Unreal).
    Centimeters = 1,
    /// Millimetres (optical mocap systems).
    Millimeters = 2,
    /// Inches.
    Inches = 3,
}

impl Units {
    /// Metres per unit.
    pub fn meters(self) -> f64 {
        match self {
            Units::Meters => 1.0,
            Units::Centimeters => 0.01,
            Units::Millimeters => 0.001,
            Units::Inches => 0.0254,
        }
    }
}

/// The caller's up axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u32)]
pub enum UpAxis {
    /// +Y up (troupe, InterGen, Unity, glTF, BVH as most tools write it).
    #[default]
    Y = 0,
    /// +Z up (SMPL/AMASS raw data, Blender, ROS, Unreal). Converted with InterGen's
    /// `trans_matrix`: `(x, y, z) -> (x, z, -y)`.
    Z = 1,
}

/// The caller's handedness.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u32)]
pub enum Handedness {
    /// Right-handed axes (troupe, SMPL, Blender, ROS, glTF).
    #[default]
    Right = 0,
    /// Left-handed axes (Unity, Unreal): x is negated before anything else.
    Left = 1,
}

/// How caller joint positions are measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointsFormat {
    /// Length unit.
    pub units: Units,
    /// Up axis.
    pub up: UpAxis,
    /// Handedness.
    pub handedness: Handedness,
    /// Frames per second of the caller's motion.
    pub fps: f32,
}

impl Default for JointsFormat {
    /// Metres, Y up, right-handed, 30 fps: troupe's canonical axes at InterHuman's rate.
    fn default() -> Self {
        JointsFormat {
            units: Units::Meters,
            up: UpAxis::Y,
            handedness: Handedness::Right,
            fps: 30.0,
        }
    }
}

/// Frame rates troupe accepts, frames per second.
pub const FPS_RANGE: std::ops::RangeInclusive<f32> = 1.0..=1000.0;

/// The video rates that are not whole numbers (NTSC's 24, 30 and 60 × 1000/1001), which a file's
/// frame time may approximate as it approximates whole rates.
const NTSC_RATES: [f64; 3] = [24000.0 / 1001.0, 30000.0 / 1001.0, 60000.0 / 1001.0];

/// How close, relatively, a file's frame rate must be to a whole or NTSC rate to be read as it:
/// a frame time written with 7 significant digits (`0.0333333`) is 1e-6 off.
const RATE_TOLERANCE: f64 = 1e-4;

/// The frame rate a file's author meant by `fps`, computed from a rounded frame time: the
/// nearest whole rate or NTSC rate (23.976, 29.97, 59.94) when `fps` is within 1e-4 of it
/// relatively, else `fps` itself. A BVH's `Frame Time: 0.0333333` is 30.00003 fps; taken
/// literally it would make troupe resample a 30 fps clip onto 30 fps.
pub fn rate_meant(fps: f64) -> f64 {
    let whole = fps.round();
    std::iter::once(whole)
        .chain(NTSC_RATES)
        .filter(|&rate| rate >= 1.0)
        .find(|&rate| (fps - rate).abs() <= RATE_TOLERANCE * rate)
        .unwrap_or(fps)
}

/// The farthest a joint position or a placement may lie from the origin along any axis, in
/// metres (1000 km). Beyond, single-precision features lose all precision and differences can
/// overflow to infinity: such input is refused, so that finite input gives finite output.
pub const MAX_WORLD_METRES: f64 = 1e6;

impl JointsFormat {
    /// Refuses a frame rate outside [`FPS_RANGE`] (which also bounds what resampling allocates).
    pub fn validate(&self) -> Result<()> {
        if !FPS_RANGE.contains(&self.fps) {
            return Err(Error::InvalidInput(format!(
                "joint positions at {} fps: the frame rate must be in [{}, {}]",
                self.fps,
                FPS_RANGE.start(),
                FPS_RANGE.end()
            )));
        }
        Ok(())
    }

    /// The orthogonal matrix taking the caller's axes to troupe's (units aside).
    fn axes(&self) -> [[f64; 3]; 3] {
        let flip = match self.handedness {
            Handedness::Right => 1.0,
            Handedness::Left => -1.0,
        };
        match self.up {
            UpAxis::Y => [[flip, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            UpAxis::Z => [[flip, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
        }
    }

    /// A caller position in troupe's canonical axes, metres.
    pub fn to_canonical_axes(&self, p: [f32; 3]) -> Vec3 {
        self.point_to_canonical(p.map(f64::from))
    }

    /// A canonical-axes position (metres) in the caller's axes and units.
    pub fn from_canonical_axes(&self, c: Vec3) -> [f32; 3] {
        self.point_from_canonical(c).map(|v| v as f32)
    }

    /// [`JointsFormat::to_canonical_axes`] in double precision (rig offsets, poses).
    pub fn point_to_canonical(&self, p: Vec3) -> Vec3 {
        let (m, s) = (self.axes(), self.units.meters());
        std::array::from_fn(|i| s * (m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2]))
    }

    /// [`JointsFormat::from_canonical_axes`] in double precision.
    pub fn point_from_canonical(&self, c: Vec3) -> Vec3 {
        let (m, s) = (self.axes(), self.units.meters());
        // The inverse of an orthogonal matrix is its transpose.
        std::array::from_fn(|i| (m[0][i] * c[0] + m[1][i] * c[1] + m[2][i] * c[2]) / s)
    }

    /// A rotation given in troupe's axes, expressed in the caller's axes: `M⁻¹ R M` for the
    /// axes matrix `M`. (A left-handed caller's rotations are then proper rotations of its own
    /// axes; applied to its own rest offsets they give its positions.)
    pub fn rotation_from_canonical_axes(&self, q: Quat) -> Quat {
        let (m, r) = (self.axes(), q.to_matrix());
        let mut out = [[0.0; 3]; 3];
        for (i, row) in out.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3)
                    .flat_map(|a| (0..3).map(move |b| (a, b)))
                    .map(|(a, b)| m[a][i] * r[a][b] * m[b][j])
                    .sum();
            }
        }
        Quat::from_matrix(out)
    }

    /// A rotation given in the caller's axes, expressed in troupe's: `M R M⁻¹`, the inverse of
    /// [`JointsFormat::rotation_from_canonical_axes`].
    pub fn rotation_to_canonical_axes(&self, q: Quat) -> Quat {
        let (m, r) = (self.axes(), q.to_matrix());
        let mut out = [[0.0; 3]; 3];
        for (i, row) in out.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3)
                    .flat_map(|a| (0..3).map(move |b| (a, b)))
                    .map(|(a, b)| m[i][a] * r[a][b] * m[j][b])
                    .sum();
            }
        }
        Quat::from_matrix(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_up_is_intergens_trans_matrix_and_round_trips() {
        let f = JointsFormat {
            up: UpAxis::Z,
            units: Units::Centimeters,
            ..Default::default()
        };
        let c = f.to_canonical_axes([100.0, 200.0, 300.0]);
        assert_eq!(c, [1.0, 3.0, -2.0]);
        assert_eq!(f.from_canonical_axes(c), [100.0, 200.0, 300.0]);
    }

    #[test]
    fn rotations_follow_the_axes() {
        for (up, handedness) in [
            (UpAxis::Y, Handedness::Left),
            (UpAxis::Z, Handedness::Right),
            (UpAxis::Z, Handedness::Left),
        ] {
            let f = JointsFormat {
                up,
                handedness,
                ..Default::default()
            };
            let q = Quat::from_axis_angle([0.6, 0.0, 0.8], 0.9);
            let v = [0.2f32, -0.5, 0.9];
            // Rotating in canonical axes then converting equals converting then rotating.
            let a = f.from_canonical_axes(q.rotate(f.to_canonical_axes(v)));
            let b = f
                .rotation_from_canonical_axes(q)
                .rotate(v.map(f64::from))
                .map(|x| x as f32);
            let back = f.rotation_to_canonical_axes(f.rotation_from_canonical_axes(q));
            let (back, q) = (back.to_wxyz(), q.to_wxyz());
            assert!(
                (0..4).all(|i| (back[i] - q[i]).abs() < 1e-12),
                "{back:?} vs {q:?}"
            );
            for i in 0..3 {
                assert!(
                    (a[i] - b[i]).abs() < 1e-6,
                    "{up:?} {handedness:?}: {a:?} vs {b:?}"
                );
            }
        }
    }
}
