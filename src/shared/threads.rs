//! The threads troupe may start, and how a host bounds them: a model load optimises its graphs
//! on up to [`load_threads`] scoped threads, all joined before it returns; tract's matrix
//! products run on the calling thread, unless [`set_compute_threads`] gives them a pool of that
//! many threads, owned by troupe and shared by every model and session of the process, which
//! tract hands the panels of each large enough product to.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use tract_linalg::multithread::{set_default_executor, Executor};

use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, LIMITS};
use crate::shared::panics;

/// Threads a model load may use at once; 0 (the default): one per core.
static LOAD_THREADS: AtomicUsize = AtomicUsize::new(0);

/// Sets how many threads loading a model may use (0: one per core, 1: only the calling thread).
/// Applies to loads that start afterwards, in the whole process.
pub fn set_load_threads(threads: usize) {
    LOAD_THREADS.store(threads, Ordering::Relaxed);
}

/// How many threads loading a model uses: the [`set_load_threads`] setting, or one per core.
pub fn load_threads() -> usize {
    one_per_core_if_zero(LOAD_THREADS.load(Ordering::Relaxed))
}

/// `threads`, or the number of cores when it is 0 (what both settings mean by 0).
fn one_per_core_if_zero(threads: usize) -> usize {
    match threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
}

/// What [`compute_threads`] reports: the threads of the executor tract uses now.
static COMPUTE: Mutex<usize> = Mutex::new(1);

/// Sets how many threads the matrix products of every model may use: 1 (the default) runs all
/// work on the calling thread; `n >= 2` starts a pool of `n` threads (troupe's, named
/// `troupe-compute-N`) that tract splits large products over, and keeps it until the setting
/// changes; 0 means one per core. Applies to calls that start afterwards, process-wide.
pub fn set_compute_threads(threads: usize) -> Result<()> {
    let n = one_per_core_if_zero(threads);
    at_most(
        "compute threads",
        n as u64,
        LIMITS.max_compute_threads,
        true,
    )?;
    let mut current = COMPUTE.lock().unwrap_or_else(|e| e.into_inner());
    let executor = if n == 1 {
        Executor::SingleThread
    } else {
        panics::catch(panics::is_quiet(), || {
            Executor::multithread_with_name(n, "troupe-compute")
        })
        .map_err(|reason| {
            Error::InvalidOption(format!("starting {n} compute threads failed: {reason}"))
        })?
    };
    set_default_executor(executor);
    *current = n;
    Ok(())
}

/// How many threads the matrix products use now ([`set_compute_threads`]; 1 by default).
pub fn compute_threads() -> usize {
    *COMPUTE.lock().unwrap_or_else(|e| e.into_inner())
}
