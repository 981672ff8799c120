//! Features from joint positions one frame at a time, for sessions fed by an engine.

use ndarray::ArrayView2;

use crate::motion::features::{feature_frame, read_frame, FEATURE_DIM};
use crate::motion::placement::Placement;
use crate::motion::resample::Resampler;
use crate::motion::rotation::Quat;
use crate::motion::skeleton::Skeleton;
use crate::motion::skeleton::T2M22_JOINTS;
use crate::motion::vec3::{load_points, save_points, Vec3};
use crate::motion::world::{Handedness, JointsFormat, Units, UpAxis};
use crate::shared::error::Result;
use crate::shared::snapshot::{bad, SnapshotReader, SnapshotWriter};

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

    /// Writes the stream to a snapshot: its format and rate, its placement, how far its
    /// resampler is and the last frame it placed.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        save_format(w, self.format, self.resampler.fps_out());
        w.bool(self.placement.is_some());
        if let Some(p) = &self.placement {
            let q = p.heading;
            w.f64(p.floor).f64(p.origin[0]).f64(p.origin[1]);
            w.f64(q.w).f64(q.x).f64(q.y).f64(q.z);
        }
        self.resampler.save_progress(w);
        save_points(w, self.previous.as_deref());
    }

    /// The format and output rate [`save_format`] wrote, both validated.
    pub(crate) fn load_format(r: &mut SnapshotReader) -> Result<(JointsFormat, f32)> {
        let units = match r.u32("the joints' units")? {
            0 => Units::Meters,
            1 => Units::Centimeters,
            2 => Units::Millimeters,
            3 => Units::Inches,
            v => return Err(bad(format!("joints' units {v}"))),
        };
        let up = match r.u32("the joints' up axis")? {
            0 => UpAxis::Y,
            1 => UpAxis::Z,
            v => return Err(bad(format!("joints' up axis {v}"))),
        };
        let handedness = match r.u32("the joints' handedness")? {
            0 => Handedness::Right,
            1 => Handedness::Left,
            v => return Err(bad(format!("joints' handedness {v}"))),
        };
        let fps = r.f32("the joints' frame rate")?;
        let fps_out = r.f64("the features' frame rate")? as f32;
        let format = JointsFormat {
            units,
            up,
            handedness,
            fps,
        };
        format.validate()?;
        JointsFormat {
            fps: fps_out,
            ..format
        }
        .validate()?;
        Ok((format, fps_out))
    }

    /// The stream [`FeatureStream::save`] wrote; its format and placement are checked as
    /// [`FeatureStream::new`] checks them.
    pub(crate) fn load(r: &mut SnapshotReader) -> Result<Self> {
        let (format, fps_out) = Self::load_format(r)?;
        let placement = if r.bool("whether the joints are placed")? {
            let mut v = [0.0; 7];
            for x in &mut v {
                *x = r.finite("the joints' placement")?;
            }
            Some(Placement {
                format,
                floor: v[0],
                origin: [v[1], v[2]],
                heading: Quat {
                    w: v[3],
                    x: v[4],
                    y: v[5],
                    z: v[6],
                },
            })
        } else {
            None
        };
        let mut stream = FeatureStream::new(format, fps_out, placement)?;
        stream.resampler.load_progress(r)?;
        stream.previous = load_points(r, "the joints' last frame", T2M22_JOINTS)?;
        Ok(stream)
    }
}

/// Writes how a caller measures positions (`f`) and the rate they are resampled to.
pub(crate) fn save_format(w: &mut SnapshotWriter, f: JointsFormat, fps_out: f64) {
    w.u32(f.units as u32)
        .u32(f.up as u32)
        .u32(f.handedness as u32)
        .f32(f.fps)
        .f64(fps_out);
}
