//! Helpers shared by the examples and benches/step.rs (included with `#[path]` there).
#![allow(dead_code)] // each includer uses what it needs

use ndarray::Array2;

/// A smooth, motion-like synthetic actor clip `[frames, dim]`: every feature a sinusoid at 30 fps
/// with its own frequency (0.2 to 2 Hz) and phase.
pub fn synthetic_actor(frames: usize, dim: usize) -> Array2<f32> {
    Array2::from_shape_fn((frames, dim), |(t, d)| {
        let freq = 0.2 + 1.8 * ((d as f32 * 0.618_034).fract());
        0.5 * (std::f32::consts::TAU * freq * t as f32 / 30.0 + d as f32).sin()
    })
}

/// The sample at rank `round(p (n - 1))` of sorted samples; NaN when there are none.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}
