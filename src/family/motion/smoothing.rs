//! Root smoothing of a stream: the output person's root path in the floor plane filtered
//! causally, against the jitter a token-by-token generator shows at its token boundaries.
//!
//! Per reactor frame `t`, with the decoded root `r[t]` (x, z) and `a = 1 − exp(−1 / (fps · τ))`:
//! `s[t] = s[t−1] + a (r[t] − s[t−1])` (`s` starts at the first frame's root), and every joint
//! moves by `s[t] − r[t]` (a rigid shift in the floor plane; heights, rotations and the body's
//! shape unchanged), every velocity by that shift's own change. No frame is held back; the cost
//! is a lag of about `τ` in where the root is. It runs before the penetration guard, so the
//! guard's promise holds for what is sent.

use ndarray::Array2;

use super::layout::FrameLayout;
use crate::motion::world::MAX_WORLD_METRES;
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};

/// The root smoothing's setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RootSmoothing {
    /// The filter's time constant, seconds (in (0, 2]): the larger, the smoother and the later.
    pub time_constant: f64,
}

impl Default for RootSmoothing {
    fn default() -> Self {
        // Measured on the demo model's held-out streams (docs/DEMO.md): 0.1 s removes about a
        // quarter of the jitter and a third of the foot skate without adding error.
        RootSmoothing { time_constant: 0.1 }
    }
}

impl RootSmoothing {
    /// Checks the setting's range.
    pub fn check(&self) -> Result<()> {
        if !(self.time_constant.is_finite()
            && self.time_constant > 0.0
            && self.time_constant <= 2.0)
        {
            return Err(Error::InvalidOption(format!(
                "root smoothing: time_constant {} s is not in (0, 2] s",
                self.time_constant
            )));
        }
        Ok(())
    }
}

/// What the smoothing carries between steps: the filtered root and the last shift.
#[derive(Debug, Clone, Default)]
pub(crate) struct SmoothingState {
    root: Option<[f64; 2]>,
    shift: [f64; 2],
}

impl SmoothingState {
    /// Smooths `frames` (the output's, `[n, frame_dim]`) in place.
    pub(crate) fn apply(
        &mut self,
        layout: FrameLayout,
        smoothing: &RootSmoothing,
        frames: &mut Array2<f32>,
        fps: f64,
    ) {
        let a = 1.0 - (-1.0 / (fps * smoothing.time_constant)).exp();
        for mut frame in frames.outer_iter_mut() {
            let row = frame
                .as_slice_mut()
                .expect("rows of a standard-layout array");
            let r = layout.root_on_floor(row);
            let s = match self.root {
                Some(s) => [s[0] + a * (r[0] - s[0]), s[1] + a * (r[1] - s[1])],
                None => r,
            };
            let shift = [s[0] - r[0], s[1] - r[1]];
            layout.shift_on_floor(row, shift, self.shift);
            self.root = Some(s);
            self.shift = shift;
        }
    }

    /// Writes the filtered root and the last shift.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        w.bool(self.root.is_some());
        let root = self.root.unwrap_or_default();
        w.f64(root[0])
            .f64(root[1])
            .f64(self.shift[0])
            .f64(self.shift[1]);
    }

    /// The state [`SmoothingState::save`] wrote.
    pub(crate) fn load(r: &mut SnapshotReader) -> Result<Self> {
        let started = r.bool("whether the smoothing started")?;
        let root = [
            r.metres("the smoothed root", MAX_WORLD_METRES)?,
            r.metres("the smoothed root", MAX_WORLD_METRES)?,
        ];
        let shift = [
            r.metres("the smoothing's shift", MAX_WORLD_METRES)?,
            r.metres("the smoothing's shift", MAX_WORLD_METRES)?,
        ];
        Ok(SmoothingState {
            root: started.then_some(root),
            shift,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::features::{FEATURE_DIM, POSITIONS, VELOCITIES};
    use crate::motion::T2M22_JOINTS as JOINTS;

    /// Frames whose every joint is at `(x, 0, 0)` for the given root x's.
    fn frames(xs: &[f32]) -> Array2<f32> {
        let mut f = Array2::<f32>::zeros((xs.len(), FEATURE_DIM));
        for (t, &x) in xs.iter().enumerate() {
            for j in 0..JOINTS {
                f[[t, POSITIONS + 3 * j]] = x;
            }
        }
        f
    }

    #[test]
    fn a_step_is_followed_exponentially_and_the_body_moves_rigidly() {
        let smoothing = RootSmoothing { time_constant: 0.1 };
        let mut state = SmoothingState::default();
        let mut f = frames(&[0.0, 1.0, 1.0, 1.0]);
        state.apply(FrameLayout::Features, &smoothing, &mut f, 30.0);
        let a = 1.0 - (-1.0f64 / 3.0).exp();
        let want = [0.0, a, a + a * (1.0 - a), 1.0 - (1.0 - a).powi(3)];
        for (t, w) in want.iter().enumerate() {
            for j in 0..JOINTS {
                assert!((f64::from(f[[t, POSITIONS + 3 * j]]) - w).abs() < 1e-6);
            }
        }
        // Velocities were 0 in the input: they now carry the shift's change.
        assert!((f64::from(f[[1, VELOCITIES]]) - (a - 1.0)).abs() < 1e-6);
    }

    #[test]
    fn steps_in_two_calls_equal_one_call() {
        let smoothing = RootSmoothing::default();
        let xs = [0.0, 0.3, -0.2, 0.5, 0.4, 0.1];
        let mut whole = frames(&xs);
        SmoothingState::default().apply(FrameLayout::Features, &smoothing, &mut whole, 30.0);
        let mut state = SmoothingState::default();
        let mut a = frames(&xs[..2]);
        let mut b = frames(&xs[2..]);
        state.apply(FrameLayout::Features, &smoothing, &mut a, 30.0);
        state.apply(FrameLayout::Features, &smoothing, &mut b, 30.0);
        assert_eq!(whole.slice(ndarray::s![..2, ..]), a);
        assert_eq!(whole.slice(ndarray::s![2.., ..]), b);
    }

    #[test]
    fn time_constants_out_of_range_are_refused() {
        for bad in [0.0, -1.0, 2.5, f64::NAN, f64::INFINITY] {
            assert!(RootSmoothing { time_constant: bad }.check().is_err());
        }
        assert!(RootSmoothing::default().check().is_ok());
    }
}
