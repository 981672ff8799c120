//! The C ABI of troupe. Everything `extern "C"` lives here, laid out like the crate: the common
//! boundary, status codes, version, limits, threads, logging and the model and session handles
//! beside one module per family, whose calls are named `troupe_<family>_...` and answer
//! `TROUPE_ERR_UNSUPPORTED` on another family's handle; `deprecated.rs` keeps the 0.1 names.
//! `include/troupe.h` is generated from these modules alone by cbindgen, laid out in one section
//! per group of files (`tests/c_header.rs`, which also checks it is up to date and names only
//! `troupe_`/`TROUPE_` identifiers); `docs/ABI.md` states what stays compatible.
//!
//! Conventions (the header's usage guide says them to C programmers):
//! - Handles: `troupe_model` is immutable and thread-safe; `troupe_session` is one stream, used by
//!   one thread at a time (a call while another thread uses it fails with `TROUPE_ERR_BUSY`). A
//!   session keeps its model alive, so handles may be freed in any order. `_free(NULL)` is a
//!   no-op.
//! - Threads: by default the library starts threads only while loading a model (up to one per
//!   core, or `troupe_set_load_threads`), all joined before the load returns, and every other
//!   call runs on the caller's thread; `troupe_set_compute_threads` opts in to a library-owned
//!   pool the matrix products split over.
//! - Sizes: every size from a file or a caller is checked against `troupe_limits_get` before
//!   anything is allocated for it.
//! - Every fallible function returns a `troupe_status`; out-parameters are written only on
//!   success; `troupe_last_error_message()` then says what failed (per thread, cleared by a
//!   success). A failed call leaves the session as it was.
//! - Memory: inputs are borrowed for the duration of the call only; outputs go into caller
//!   buffers; nothing returned needs freeing except handles. Frames are contiguous row-major
//!   float32 `[frames][frame_dim]`. Input and output buffers must not overlap.
//! - No panic crosses the boundary: a panic returns `TROUPE_ERR_PANIC` (its reason in the last
//!   error, nothing printed) and poisons the session involved until `troupe_session_reset`.
//!
//! `troupe_session_options_init` takes the model, so the defaults it writes are the bundle's
//! own (sampler steps, CFG, capacity) rather than sentinels meaning "the bundle's".
#![allow(non_camel_case_types)]

// The boundary every entry point goes through, and what every bundle answers.
pub mod boundary;
// The 0.1 names, forwarding to today's until 2.0.
pub mod deprecated;
pub mod limits;
pub mod log;
pub mod model;
pub mod motion;
pub mod progress;
pub mod session;
// A session's motion stages: joints in, poses out, guard, smoothing, foot lock.
pub mod session_motion;
pub mod status;
pub mod text;
pub mod threads;
pub mod version;
pub mod viewer;

// One module per family, mirroring `src/<family>/`.
pub mod arflow;
pub mod armflow;
pub mod magnet;
pub mod umf;
