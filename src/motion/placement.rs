//! Where a clip sits in the caller's world, and InterGen's canonical frame.
//!
//! InterGen (`utils/utils.py::process_motion_np`) canonicalises a clip in three moves, after
//! turning it y-up: it puts the lowest joint of the whole clip on the floor (y = 0), moves the
//! first frame's root to x = z = 0, and turns it about y so that the first frame faces +Z, the
//! facing being `up × (right hip − left hip)`. A [`Placement`] keeps those three numbers (and
//! the caller's [`JointsFormat`]), so generated motion goes back where the caller's was. Both
//! people of an interaction share the first person's placement, as InterGen's `rigid_transform`
//! puts person 2 into person 1's frame.

use crate::motion::rotation::Quat;
use crate::motion::skeleton::FACE_JOINTS;
use crate::motion::vec3::{cross, normalize, sub, Vec3};
use crate::motion::world::{JointsFormat, MAX_WORLD_METRES};
use crate::shared::error::{Error, Result};

/// The transform between a caller's world and the canonical frame of a clip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// How the caller measures positions.
    pub format: JointsFormat,
    /// Floor height in canonical axes (metres, before the shift): subtracted from y.
    pub floor: f64,
    /// First-frame root x and z in canonical axes: subtracted from x and z.
    pub origin: [f64; 2],
    /// Turn about +Y applied after the shift, so the first frame faces +Z.
    pub heading: Quat,
}

impl Placement {
    /// `self`, if its numbers are finite, within [`MAX_WORLD_METRES`] of the origin and its
    /// heading a unit quaternion (to 1e-3); an error naming what is not, otherwise.
    pub fn checked(self) -> Result<Self> {
        let q = self.heading;
        let norm = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
        let within = |v: f64| v.is_finite() && v.abs() <= MAX_WORLD_METRES;
        if !(within(self.floor) && self.origin.iter().all(|&v| within(v))) {
            return Err(Error::InvalidInput(format!(
                "placement: floor {} and origin {:?} must be finite and within {MAX_WORLD_METRES} m",
                self.floor, self.origin
            )));
        }
        if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 {
            return Err(Error::InvalidInput(format!(
                "placement: the heading {q:?} is not a unit quaternion"
            )));
        }
        Ok(self)
    }

    /// The identity placement for `format`: canonical frame = the caller's world (converted to
    /// troupe's axes).
    pub fn identity(format: JointsFormat) -> Placement {
        Placement {
            format,
            floor: 0.0,
            origin: [0.0, 0.0],
            heading: Quat::IDENTITY,
        }
    }

    /// InterGen's placement of a clip given in canonical axes (`[T][22]`, metres, y up): the
    /// floor under the lowest joint of the whole clip (`floor = None`) or at the given height,
    /// origin and facing from frame 0.
    pub fn of_clip(format: JointsFormat, clip: &[Vec<Vec3>], floor: Option<f64>) -> Result<Self> {
        let first = clip
            .first()
            .ok_or_else(|| Error::InvalidInput("a clip with no frames has no placement".into()))?;
        let floor = floor.unwrap_or_else(|| {
            clip.iter()
                .flatten()
                .map(|p| p[1])
                .fold(f64::INFINITY, f64::min)
        });
        let [r_hip, l_hip, ..] = FACE_JOINTS;
        let across = normalize(sub(first[r_hip], first[l_hip]));
        let forward = across.and_then(|a| normalize(cross([0.0, 1.0, 0.0], a)));
        let heading = forward
            .and_then(|f| Quat::between(f, [0.0, 0.0, 1.0]))
            .ok_or_else(|| {
                Error::InvalidInput(
                    "frame 0: the hips (joints 1 and 2) coincide or are vertically aligned, so \
                     the body has no facing to canonicalise"
                        .into(),
                )
            })?;
        Ok(Placement {
            format,
            floor,
            origin: [first[0][0], first[0][2]],
            heading,
        })
    }

    /// A canonical-axes position (metres, y up) in the canonical frame.
    pub fn to_frame(&self, c: Vec3) -> Vec3 {
        self.heading.rotate([
            c[0] - self.origin[0],
            c[1] - self.floor,
            c[2] - self.origin[1],
        ])
    }

    /// A canonical-frame position back in canonical axes.
    pub fn from_frame(&self, v: Vec3) -> Vec3 {
        let p = self.heading.conj().rotate(v);
        [
            p[0] + self.origin[0],
            p[1] + self.floor,
            p[2] + self.origin[1],
        ]
    }

    /// A caller position in the canonical frame.
    pub fn world_to_frame(&self, p: [f32; 3]) -> Vec3 {
        self.to_frame(self.format.to_canonical_axes(p))
    }

    /// A canonical-frame position in the caller's world.
    pub fn frame_to_world(&self, v: Vec3) -> [f32; 3] {
        self.format.from_canonical_axes(self.from_frame(v))
    }

    /// A canonical-frame *world* rotation (a root orientation) in the caller's world and axes.
    pub fn rotation_to_world(&self, q: Quat) -> Quat {
        self.format
            .rotation_from_canonical_axes(self.heading.conj() * q)
    }

    /// A canonical-frame *local* rotation (relative to a parent joint) in the caller's axes: the
    /// placement's turn does not touch it, only the axes do.
    pub fn local_rotation_to_world(&self, q: Quat) -> Quat {
        self.format.rotation_from_canonical_axes(q)
    }
}
