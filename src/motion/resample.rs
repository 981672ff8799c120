//! Linear resampling of joint positions to the bundle's frame rate, one frame at a time, so the
//! batch and streaming paths give the same frames.

use crate::motion::skeleton::T2M22_JOINTS;
use crate::motion::vec3::{load_points, save_points, Vec3};
use crate::shared::error::Result;
use crate::shared::snapshot::{bad as bad_snapshot, SnapshotReader, SnapshotWriter};

/// The most input frames a restored resampler may claim: past 2^52 its `f64` frame times stop
/// being exact (and a stream at 1,000 fps takes 140,000 years to get there).
const MAX_FRAMES_IN: u64 = 1 << 52;

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
    /// The counts are checked against each other and against the rates, as untrusted input: a
    /// count that no sequence of pushes could give would make the next push emit frames without
    /// end (or none), so it is refused, naming the field, and `self` is left as it was.
    pub(crate) fn load_progress(&mut self, r: &mut SnapshotReader) -> Result<()> {
        let received = r.u64("the resampler's frames in")?;
        let emitted = r.u64("the resampler's frames out")?;
        let last = load_points(r, "the resampler's last frame", T2M22_JOINTS)?;
        if received > MAX_FRAMES_IN {
            return Err(bad_snapshot(format!(
                "the resampler's frames in: {received} is over the {MAX_FRAMES_IN} a stream can \
                 have taken"
            )));
        }
        let due = self.due_after(received);
        if emitted != due {
            return Err(bad_snapshot(format!(
                "the resampler's frames out: {emitted}, but {received} frames in give {due}"
            )));
        }
        if last.is_some() != (received > 0) {
            return Err(bad_snapshot(format!(
                "the resampler's last frame: {} after {received} frames in",
                if last.is_some() { "present" } else { "absent" }
            )));
        }
        (self.received, self.emitted, self.last) = (received, emitted, last);
        Ok(())
    }

    /// How many output frames the first `received` input frames give: what `emitted` is after
    /// that many pushes, i.e. the first `k` that [`Resampler::push`]'s test `k fps_in <= i
    /// fps_out` (rounding included) fails for the last frame `i`.
    fn due_after(&self, received: u64) -> u64 {
        if received == 0 {
            return 0;
        }
        let bound = (received - 1) as f64 * self.fps_out + 1e-9 * self.fps_out;
        let is_due = |k: u64| (k as f64) * self.fps_in <= bound;
        // The quotient lands within a frame or two of the answer; the test settles it exactly.
        let mut k = (bound / self.fps_in).floor().max(0.0) as u64 + 1;
        while k > 0 && !is_due(k - 1) {
            k -= 1;
        }
        while is_due(k) {
            k += 1;
        }
        k
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
        // Output frames k with k fps_in <= last fps_out, less those already emitted.
        let due = self.due_after(self.received.saturating_add(n as u64));
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
            // What a restored snapshot's counts are checked against.
            assert_eq!(r.emitted, r.due_after(r.received), "{fps_in} -> {fps_out}");
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

    /// A snapshot's counts are untrusted: ones no run of pushes gives (a tampered file whose
    /// checksum was recomputed) are refused, naming the field, and leave the resampler as it was.
    #[test]
    fn restoring_counts_no_stream_could_have_is_refused() {
        use crate::shared::snapshot::MODEL_ID_BYTES;
        let model = [7u8; MODEL_ID_BYTES];
        let frame = vec![[0.5, 1.0, 0.0]; T2M22_JOINTS];
        let saved = |received: u64, emitted: u64, last: bool| {
            let mut w = SnapshotWriter::new("armflow", &model, 0);
            w.u64(received).u64(emitted);
            save_points(&mut w, last.then_some(&frame[..]));
            w.finish()
        };
        let restore = |r: &mut Resampler, bytes: &[u8]| {
            let mut reader = SnapshotReader::open(bytes, "armflow", &model).unwrap();
            r.load_progress(&mut reader).map_err(|e| e.to_string())
        };
        // 120 fps in, 30 out: 9 frames in give frames out 0, 1 and 2.
        let mut r = Resampler::new(120.0, 30.0);
        restore(&mut r, &saved(9, 3, true)).unwrap();
        for (received, emitted, last, field) in [
            (u64::MAX, 3, true, "frames in"),
            (1 << 40, 3, true, "frames out"),
            (9, 4, true, "frames out"),
            (9, 2, true, "frames out"),
            (9, 3, false, "last frame"),
            (0, 0, true, "last frame"),
        ] {
            let e = restore(&mut r, &saved(received, emitted, last)).unwrap_err();
            assert!(e.contains(field), "{received}/{emitted}: {e}");
            assert_eq!((r.received, r.emitted), (9, 3), "left as it was");
        }
        let mut out = Vec::new();
        r.push(frame.clone(), &mut out);
        assert!(
            out.is_empty(),
            "frame 9 completes no output frame at 120 -> 30"
        );
    }
}
