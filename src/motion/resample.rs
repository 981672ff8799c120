//! Linear resampling of joint positions to the bundle's frame rate, one frame at a time, so the
//! batch and streaming paths give the same frames.

use crate::motion::skeleton::T2M22_JOINTS;
use crate::motion::vec3::{load_points, save_points, Vec3};
use crate::shared::error::Result;
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};

/// Turns frames at `fps_in` into frames at `fps_out` by linear interpolation: output frame `k`
/// is the caller's motion at time `k / fps_out`, emitted as soon as the input frame at or after
/// that time has arrived.
#[derive(Debug, Clone)]
pub struct Resampler {
    fps_in: f64,
    fps_out: f64,
    received: u64,
    emitted: u64,
    last: Option<Vec<Vec3>>,
}

impl Resampler {
    /// A resampler from `fps_in` to `fps_out` (both positive; callers validate the range).
    pub fn new(fps_in: f32, fps_out: f32) -> Resampler {
        Resampler {
            fps_in: f64::from(fps_in),
            fps_out: f64::from(fps_out),
            received: 0,
            emitted: 0,
            last: None,
        }
    }

    /// Writes how far the resampler is (its rates are its owner's to write).
    pub(crate) fn save_progress(&self, w: &mut SnapshotWriter) {
        w.u64(self.received).u64(self.emitted);
        save_points(w, self.last.as_deref());
    }

    /// Takes back the progress [`Resampler::save_progress`] wrote.
    pub(crate) fn load_progress(&mut self, r: &mut SnapshotReader) -> Result<()> {
        self.received = r.u64("the resampler's frames in")?;
        self.emitted = r.u64("the resampler's frames out")?;
        self.last = load_points(r, "the resampler's last frame", T2M22_JOINTS)?;
        Ok(())
    }

    /// The output frame rate.
    pub fn fps_out(&self) -> f64 {
        self.fps_out
    }

    /// Output frames per input frame, rounded up: what one `push` can emit at most.
    pub fn max_out_per_frame(&self) -> usize {
        (self.fps_out / self.fps_in).ceil() as usize
    }

    /// Output frames a clip of `n` input frames gives.
    pub fn output_len(fps_in: f32, fps_out: f32, n: usize) -> usize {
        if n == 0 {
            return 0;
        }
        let span = (n - 1) as f64 * f64::from(fps_out) / f64::from(fps_in);
        // Saturating: a length beyond `usize` (more frames than memory holds) stays the largest.
        ((span + 1e-9).floor() as usize).saturating_add(1)
    }

    /// How many output frames the next `n` input frames complete.
    pub fn outputs_after(&self, n: usize) -> usize {
        if n == 0 {
            return 0;
        }
        let last = (self.received + n as u64 - 1) as f64;
        // Output frames k with k fps_in <= last fps_out, less those already emitted.
        let due = ((last * self.fps_out + 1e-9 * self.fps_out) / self.fps_in).floor() as u64 + 1;
        due.saturating_sub(self.emitted) as usize
    }

    /// Takes the next input frame; appends the output frames it completes to `out`.
    pub fn push(&mut self, frame: Vec<Vec3>, out: &mut Vec<Vec<Vec3>>) {
        let i = self.received as f64;
        // Output frame k is due once k / fps_out <= i / fps_in, i.e. k fps_in <= i fps_out.
        while (self.emitted as f64) * self.fps_in <= i * self.fps_out + 1e-9 * self.fps_out {
            let k = self.emitted as f64;
            let alpha = match &self.last {
                None => 1.0,
                Some(_) => ((k * self.fps_in - (i - 1.0) * self.fps_out) / self.fps_out).min(1.0),
            };
            let frame_out = match &self.last {
                Some(prev) if alpha < 1.0 => prev
                    .iter()
                    .zip(&frame)
                    .map(|(a, b)| std::array::from_fn(|d| a[d] + alpha * (b[d] - a[d])))
                    .collect(),
                _ => frame.clone(),
            };
            out.push(frame_out);
            self.emitted += 1;
        }
        self.received += 1;
        self.last = Some(frame);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(fps_in: f32, fps_out: f32, n: usize) -> Vec<f64> {
        let mut r = Resampler::new(fps_in, fps_out);
        let mut out = Vec::new();
        assert_eq!(
            r.outputs_after(n),
            Resampler::output_len(fps_in, fps_out, n)
        );
        for i in 0..n {
            let (before, predicted) = (out.len(), r.outputs_after(1));
            r.push(vec![[i as f64 / f64::from(fps_in), 0.0, 0.0]], &mut out);
            assert_eq!(
                out.len() - before,
                predicted,
                "{fps_in} -> {fps_out}, frame {i}"
            );
        }
        assert_eq!(out.len(), Resampler::output_len(fps_in, fps_out, n));
        out.iter().map(|f| f[0][0]).collect()
    }

    #[test]
    fn equal_rates_pass_frames_through() {
        let times = run(30.0, 30.0, 7);
        assert_eq!(times.len(), 7);
        for (k, t) in times.iter().enumerate() {
            assert_eq!(*t, k as f64 / 30.0);
        }
    }

    #[test]
    fn other_rates_sample_the_motion_at_the_output_times() {
        for (fps_in, fps_out) in [(120.0, 30.0), (24.0, 30.0), (60.0, 20.0), (29.97, 30.0)] {
            for (k, t) in run(fps_in, fps_out, 50).iter().enumerate() {
                assert!(
                    (t - k as f64 / f64::from(fps_out)).abs() < 1e-9,
                    "{fps_in}->{fps_out}"
                );
            }
        }
    }
}
