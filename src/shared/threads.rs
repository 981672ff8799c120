//! The threads tract's matrix products may split over: by default none but the caller's (every
//! call runs on the thread that makes it); with [`set_compute_threads`] a pool of that many
//! threads, owned by troupe and shared by every model and session of the process, which tract
//! hands the panels of each large enough product to. A host engine bounds troupe's threads
//! with this number.

use std::sync::Mutex;

use tract_linalg::multithread::{set_default_executor, Executor};

use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, LIMITS};
use crate::shared::panics;

/// How many threads the executor tract uses now has.
static COMPUTE: Mutex<usize> = Mutex::new(1);

/// Sets how many threads the matrix products of every model may use: 1 (the default) runs all
/// work on the calling thread; `n >= 2` starts a pool of `n` threads (troupe's, named
/// `troupe-compute-N`) that tract splits large products over, and keeps it until the setting
/// changes; 0 means one per core. Applies to calls that start afterwards, process-wide.
pub fn set_compute_threads(threads: usize) -> Result<()> {
    let n = match threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    };
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
