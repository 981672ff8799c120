//! What the motion stages need to know of a frame layout: where a frame's joints are and how
//! to move a frame on the floor. The stages wrap a stream by its layout, never by its family.

use crate::motion::features::{FEATURE_DIM, POSITIONS, VELOCITIES};
use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};
use crate::motion::smplx145::{smplx145_positions, SMPLX145, SMPLX145_DIM, SMPLX145_ROOT};
use crate::motion::vec3::Vec3;
use crate::shared::error::{Error, Result};

/// The `interhuman262` layout's name (ARMFlow, ARFlow).
pub(crate) const INTERHUMAN262: &str = "interhuman262";

/// A frame layout the motion stages know.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FrameLayout {
    /// `interhuman262`: joint positions, velocities, 6-D rotations and foot contacts in the
    /// stream's canonical frame.
    Features,
    /// `magnet-smplx145`: SMPL-X betas, the body's local rotations and the pelvis's pose in the
    /// world, posed on the t2m-22 skeleton.
    Smplx,
}

/// Where the root's translation sits in a `magnet-smplx145` frame (after its 6-D rotation).
const SMPLX_TRANSLATION: usize = SMPLX145_ROOT.start + 6;

impl FrameLayout {
    /// The layout called `name` with frames of `dim` floats, if the stages know it.
    pub(crate) fn of(name: &str, dim: usize) -> Option<Self> {
        match (name, dim) {
            (INTERHUMAN262, FEATURE_DIM) => Some(FrameLayout::Features),
            (SMPLX145, SMPLX145_DIM) => Some(FrameLayout::Smplx),
            _ => None,
        }
    }

    /// The layout of a stream whose frames are `name`, or [`Error::Unsupported`] saying that
    /// `what` needs one the stages know.
    pub(crate) fn required(name: &str, dim: usize, what: &str) -> Result<Self> {
        Self::of(name, dim).ok_or_else(|| {
            Error::Unsupported(format!(
                "{what} needs `{INTERHUMAN262}` or `{SMPLX145}` frames; this stream's are `{name}`"
            ))
        })
    }

    /// The 22 joints' positions of one frame (metres, y up, in the stream's world). The frame
    /// is finite (the session checked its input; streams refuse non-finite output).
    pub(crate) fn joints(self, frame: &[f32]) -> Vec<Vec3> {
        match self {
            FrameLayout::Features => frame[POSITIONS..POSITIONS + 3 * T2M22_JOINTS]
                .chunks_exact(3)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
                .collect(),
            FrameLayout::Smplx => smplx145_positions(frame, &Skeleton::t2m22())
                .ok()
                .and_then(|mut frames| frames.pop())
                .unwrap_or_else(|| vec![[0.0; 3]; T2M22_JOINTS]),
        }
    }

    /// The root's position on the floor (x, z).
    pub(crate) fn root_on_floor(self, frame: &[f32]) -> [f64; 2] {
        let at = match self {
            FrameLayout::Features => POSITIONS,
            FrameLayout::Smplx => SMPLX_TRANSLATION,
        };
        [f64::from(frame[at]), f64::from(frame[at + 2])]
    }

    /// Moves a frame rigidly by `offset` on the floor (x, z): every joint (the root's
    /// translation, which carries them all, in `magnet-smplx145`), and in `interhuman262` every
    /// joint velocity by the offset's change from the previous frame's `previous`.
    pub(crate) fn shift_on_floor(self, row: &mut [f32], offset: [f64; 2], previous: [f64; 2]) {
        match self {
            FrameLayout::Features => {
                for j in 0..T2M22_JOINTS {
                    row[POSITIONS + 3 * j] += offset[0] as f32;
                    row[POSITIONS + 3 * j + 2] += offset[1] as f32;
                    row[VELOCITIES + 3 * j] += (offset[0] - previous[0]) as f32;
                    row[VELOCITIES + 3 * j + 2] += (offset[1] - previous[1]) as f32;
                }
            }
            FrameLayout::Smplx => {
                row[SMPLX_TRANSLATION] += offset[0] as f32;
                row[SMPLX_TRANSLATION + 2] += offset[1] as f32;
            }
        }
    }
}
