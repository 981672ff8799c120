//! MeanFlow's time grid, shared by the streaming sessions and the official clip loop.

/// MeanFlow time grid `tau_k = (n - k) / n`, k = 0..=n, each rounded once to f32. t = 1 is
/// noise and t = 0 is data (models.md 1.6).
pub fn meanflow_grid(steps: u32) -> Vec<f32> {
    (0..=steps)
        .map(|k| (f64::from(steps - k) / f64::from(steps)) as f32)
        .collect()
}
