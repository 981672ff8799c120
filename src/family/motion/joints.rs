//! Joint positions in, poses out, for any stream whose frames [`FrameLayout`] knows.
//!
//! - `interhuman262` (ARMFlow, ARFlow): positions become feature frames through a
//!   [`FeatureStream`] (one frame of latency: velocities and contacts need the next frame), placed
//!   by the first frame in InterGen's canonical frame; output frames decode to poses put back in
//!   the caller's world, after the foot lock (when on).
//! - `magnet-smplx145` (MAGNet): positions become SMPL-X frames by inverse kinematics on the
//!   t2m-22 skeleton (no latency beyond resampling). Positions cannot say how a bone is twisted
//!   about itself, nor the person's shape: the frames carry no twist beyond what a joint's
//!   children fix, and zero betas. The world is the caller's (only units and axes change), so a
//!   partner's opening frames and the poses sent back share it. Output frames are posed by
//!   forward kinematics; their contacts are 0 (the layout has none), so the foot lock is refused.

use ndarray::ArrayView2;

use super::layout::FrameLayout;
use crate::motion::features::{decode_canonical, read_frame, CanonicalPose, Pose};
use crate::motion::foot_lock::FootLock;
use crate::motion::ik::inverse_kinematics;
use crate::motion::placement::Placement;
use crate::motion::resample::Resampler;
use crate::motion::rotation::{Quat, SixD};
use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};
use crate::motion::smplx145::{
    smplx145_positions, smplx145_rotations, SMPLX145_BODY, SMPLX145_DIM, SMPLX145_ROOT,
};
use crate::motion::stream::{save_format, FeatureStream, STREAM_LATENCY_FRAMES};
use crate::motion::world::JointsFormat;
use crate::shared::error::Result;
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};

/// The conversion of a session's incoming joint positions into its stream's frames.
#[derive(Debug, Clone)]
pub(crate) enum JointsInput {
    /// Into `interhuman262` features.
    Features(Box<FeatureStream>),
    /// Into `magnet-smplx145` frames by inverse kinematics.
    Smplx(SmplxInput),
}

/// Positions into `magnet-smplx145` frames.
#[derive(Debug, Clone)]
pub(crate) struct SmplxInput {
    format: JointsFormat,
    resampler: Resampler,
}

impl JointsInput {
    /// A fresh conversion of positions measured as `format` into `layout` frames at `fps`.
    pub(crate) fn new(layout: FrameLayout, format: JointsFormat, fps: f32) -> Result<Self> {
        Ok(match layout {
            FrameLayout::Features => {
                JointsInput::Features(Box::new(FeatureStream::new(format, fps, None)?))
            }
            FrameLayout::Smplx => {
                format.validate()?;
                JointsFormat { fps, ..format }.validate()?;
                JointsInput::Smplx(SmplxInput {
                    format,
                    resampler: Resampler::new(format.fps, fps),
                })
            }
        })
    }

    /// Frames of latency the conversion adds.
    pub(crate) fn latency_frames(layout: FrameLayout) -> usize {
        match layout {
            FrameLayout::Features => STREAM_LATENCY_FRAMES,
            FrameLayout::Smplx => 0,
        }
    }

    /// Where poses are put: fixed by the first frame for features (`None` before it), the
    /// caller's own world for SMPL-X frames.
    pub(crate) fn placement(&self) -> Option<Placement> {
        match self {
            JointsInput::Features(s) => s.placement().copied(),
            JointsInput::Smplx(s) => Some(Placement::identity(s.format)),
        }
    }

    /// How many frames the next `n` position frames give.
    pub(crate) fn rows_after(&self, n: usize) -> usize {
        match self {
            JointsInput::Features(s) => s.rows_after(n),
            JointsInput::Smplx(s) => s.resampler.outputs_after(n),
        }
    }

    /// Takes one frame of positions (`[22, 3]`) and appends the frames it completes to `out`.
    /// A refused frame leaves the conversion as it was.
    pub(crate) fn push(&mut self, frame: ArrayView2<f32>, out: &mut Vec<f32>) -> Result<()> {
        match self {
            JointsInput::Features(s) => {
                out.extend(s.push(frame)?.iter().flatten());
                Ok(())
            }
            JointsInput::Smplx(s) => {
                let positions = read_frame(&s.format, frame, "joint positions")?;
                let mut resampled = Vec::new();
                s.resampler.push(positions, &mut resampled);
                let skeleton = Skeleton::t2m22();
                for f in resampled {
                    smplx_frame(&skeleton, &f, out);
                }
                Ok(())
            }
        }
    }

    /// Forgets the motion (and the features' placement), as if new.
    pub(crate) fn reset(&mut self) {
        match self {
            JointsInput::Features(s) => s.reset(None).expect("no placement to refuse"),
            JointsInput::Smplx(s) => {
                s.resampler = Resampler::new(s.format.fps, s.resampler.fps_out() as f32);
            }
        }
    }

    /// Writes the conversion to a snapshot.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        match self {
            JointsInput::Features(s) => s.save(w),
            JointsInput::Smplx(s) => {
                save_format(w, s.format, s.resampler.fps_out());
                s.resampler.save_progress(w);
            }
        }
    }

    /// The conversion [`JointsInput::save`] wrote for a `layout` stream.
    pub(crate) fn load(layout: FrameLayout, r: &mut SnapshotReader) -> Result<Self> {
        Ok(match layout {
            FrameLayout::Features => JointsInput::Features(Box::new(FeatureStream::load(r)?)),
            FrameLayout::Smplx => {
                let (format, fps) = FeatureStream::load_format(r)?;
                let mut resampler = Resampler::new(format.fps, fps);
                resampler.load_progress(r)?;
                JointsInput::Smplx(SmplxInput { format, resampler })
            }
        })
    }
}

/// Appends the `magnet-smplx145` frame of one pose (canonical axes) found by inverse kinematics.
fn smplx_frame(skeleton: &Skeleton, positions: &[[f64; 3]], out: &mut Vec<f32>) {
    let local = inverse_kinematics(skeleton, positions);
    let start = out.len();
    out.resize(start + SMPLX145_DIM, 0.0);
    let frame = &mut out[start..];
    let six = |q: Quat| q.to_6d(SixD::ConcatenatedColumns).map(|v| v as f32);
    for j in 1..T2M22_JOINTS {
        frame[SMPLX145_BODY][(j - 1) * 6..j * 6].copy_from_slice(&six(local[j]));
    }
    let root = &mut frame[SMPLX145_ROOT];
    root[..6].copy_from_slice(&six(local[0]));
    for (d, v) in positions[0].iter().enumerate() {
        root[6 + d] = *v as f32;
    }
}

/// The poses of a step's output frames (`layout`, row-major, finite), put in the caller's world
/// by `placement`, the foot lock (interhuman262 only) applied in the stream's canonical frame.
pub(crate) fn poses(
    layout: FrameLayout,
    frames: &[f32],
    frame_dim: usize,
    placement: &Placement,
    mut foot_lock: Option<&mut FootLock>,
) -> Result<Vec<Pose>> {
    match layout {
        FrameLayout::Features => frames
            .chunks_exact(frame_dim)
            .map(|row| {
                let mut pose = decode_canonical(ndarray::ArrayView1::from(row))?;
                if let Some(lock) = foot_lock.as_deref_mut() {
                    lock.apply(&mut pose);
                }
                Ok(pose.placed(placement))
            })
            .collect(),
        FrameLayout::Smplx => {
            let positions = smplx145_positions(frames, &Skeleton::t2m22())?;
            let rotations = smplx145_rotations(frames)?;
            Ok(positions
                .into_iter()
                .zip(rotations)
                .map(|(p, r)| {
                    CanonicalPose {
                        positions: std::array::from_fn(|j| p[j]),
                        rotations: std::array::from_fn(|j| r[j]),
                        contacts: [0.0; 4],
                    }
                    .placed(placement)
                })
                .collect())
        }
    }
}
