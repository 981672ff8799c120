//! Elapsed time for the debug log, on every target. `wasm32-unknown-unknown` (the browser build,
//! `bindings/web`) has no clock in the standard library: `Instant::now` panics there, so there a
//! stopwatch reads zero. Nothing but logging reads it.

/// Started when made; [`Stopwatch::elapsed_ms`] is the time since.
#[derive(Clone, Copy)]
pub(crate) struct Stopwatch {
    #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
    started: std::time::Instant,
}

impl Stopwatch {
    pub(crate) fn start() -> Self {
        Self {
            #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
            started: std::time::Instant::now(),
        }
    }

    /// Milliseconds since [`Stopwatch::start`] (0 where there is no clock).
    pub(crate) fn elapsed_ms(&self) -> f64 {
        #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
        return self.started.elapsed().as_secs_f64() * 1e3;
        #[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
        return 0.0;
    }
}
