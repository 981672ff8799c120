//! The host's bounds on troupe's threads: how many a model load may use, and whether the matrix
//! products split over a library-owned pool. Process-wide settings.

use super::boundary::{self, troupe_status};

/// Sets how many threads a model load may use: 0 (the default) one per core, 1 only the calling
/// thread. Loading optimises the bundle's graphs in parallel on scoped threads that are all
/// joined before the load returns; no other call starts a thread. Applies to loads that start
/// afterwards, process-wide. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_set_load_threads(threads: usize) {
    boundary::get((), || crate::set_load_threads(threads));
}

/// How many threads a model load uses now (the `troupe_set_load_threads` setting, or the number
/// of cores). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_load_threads() -> usize {
    boundary::get(1, crate::load_threads)
}

/// Sets how many threads the matrix products of every model may split over: 1 (the default)
/// runs all work on the calling thread; `n >= 2` starts a pool of `n` threads, owned by the
/// library and named `troupe-compute`, shared by every model and session of the process, and
/// kept until the setting changes (the old pool's threads then exit); 0 means one per core.
/// Sessions stepped from several host threads share the pool. Applies to calls that start
/// afterwards. Returns `TROUPE_OK`, or `TROUPE_ERR_INVALID_ARG` when `threads` is above 1024 or
/// the pool cannot be started (the setting is then unchanged). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_set_compute_threads(threads: usize) -> troupe_status {
    boundary::call(
        "troupe_set_compute_threads",
        || {},
        || {
            crate::set_compute_threads(threads)?;
            Ok(())
        },
    )
}

/// How many threads the matrix products use now (`troupe_set_compute_threads`; 1 by default).
/// Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_compute_threads() -> usize {
    boundary::get(1, crate::compute_threads)
}
