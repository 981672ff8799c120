//! Features from joint positions one frame at a time, for sessions fed by an engine.

use ndarray::ArrayView2;

use crate::motion::features::{feature_frame, read_frame, FEATURE_DIM};
use crate::motion::placement::Placement;
use crate::motion::resample::Resampler;
use crate::motion::skeleton::Skeleton;
use crate::motion::vec3::Vec3;
use crate::motion::world::JointsFormat;
use crate::shared::error::Result;

/// Frames of latency the conversion adds: feature frame `t` needs position frame `t + 1` for
/// its velocities and contacts.
pub const STREAM_LATENCY_FRAMES: usize = 1;

/// Turns a stream of joint-position frames into `interhuman262` feature frames.
///
/// The canonical frame is fixed by the first frame: origin and facing as InterGen takes them,
/// and the floor under that frame's lowest joint (a clip's later frames cannot be waited for),
/// unless a placement is given. Feature frame `t` is emitted when position frame `t + 1`
/// arrives ([`STREAM_LATENCY_FRAMES`]).
#[derive(Debug, Clone)]
pub struct FeatureStream {
    format: JointsFormat,
    skeleton: Skeleton,
    resampler: Resampler,
    placement: Option<Placement>,
    previous: Option<Vec<Vec3>>,
}

impl FeatureStream {
    /// A stream of positions measured as `format` says, giving features at `fps`. `placement`:
    /// the canonical frame to use (e.g. another person's), or `None` to take it from the first
    /// frame.
    pub fn new(format: JointsFormat, fps: f32, placement: Option<Placement>) -> Result<Self> {
        format.validate()?;
        JointsFormat { fps, ..format }.validate()?;
        let placement = placement
            .map(|p| Placement { format, ..p }.checked())
            .transpose()?;
        Ok(FeatureStream {
            format,
            skeleton: Skeleton::t2m22(),
            resampler: Resampler::new(format.fps, fps),
            placement,
            previous: None,
        })
    }

    /// How the caller measures positions.
    pub fn format(&self) -> JointsFormat {
        self.format
    }

    /// The canonical frame, once the first frame has fixed it.
    pub fn placement(&self) -> Option<&Placement> {
        self.placement.as_ref()
    }

    /// The most feature frames one [`push`](Self::push) returns.
    pub fn max_out_per_frame(&self) -> usize {
        self.resampler.max_out_per_frame()
    }

    /// How many feature frames the next `n` position frames give (the first resampled frame
    /// of a stream gives none).
    pub fn rows_after(&self, n: usize) -> usize {
        let frames = self.resampler.outputs_after(n);
        frames - usize::from(self.previous.is_none() && frames > 0)
    }

    /// Takes one frame of positions (`[22, 3]`) and returns the feature frames it completes
    /// (none for the first frame at equal rates; more than one when upsampling). A refused
    /// frame leaves the stream as it was.
    pub fn push(&mut self, frame: ArrayView2<f32>) -> Result<Vec<[f32; FEATURE_DIM]>> {
        let frame = read_frame(&self.format, frame, "joint positions")?;
        let placement = match self.placement {
            Some(p) => p,
            None => Placement::of_clip(self.format, std::slice::from_ref(&frame), None)?,
        };
        let mut resampled = Vec::new();
        self.resampler.push(frame, &mut resampled);
        self.placement = Some(placement);
        let mut out = Vec::with_capacity(resampled.len());
        for f in resampled {
            let now: Vec<Vec3> = f.iter().map(|p| placement.to_frame(*p)).collect();
            if let Some(prev) = &self.previous {
                let mut row = [0f32; FEATURE_DIM];
                feature_frame(&self.skeleton, prev, &now, &mut row);
                out.push(row);
            }
            self.previous = Some(now);
        }
        Ok(out)
    }

    /// Forgets the motion and the canonical frame, as if new; a placement that
    /// [`Placement::checked`] refuses leaves the stream as it was.
    pub fn reset(&mut self, placement: Option<Placement>) -> Result<()> {
        let format = self.format;
        let placement = placement
            .map(|p| Placement { format, ..p }.checked())
            .transpose()?;
        *self = FeatureStream {
            format,
            skeleton: Skeleton::t2m22(),
            resampler: Resampler::new(format.fps, self.resampler.fps_out() as f32),
            placement,
            previous: None,
        };
        Ok(())
    }
}
