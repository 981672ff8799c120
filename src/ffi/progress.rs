//! `troupe_set_progress_callback`: progress reports from long calls, and cancelling them.

use std::ffi::c_void;

use crate::ffi::boundary::{self, troupe_status};
use crate::shared::progress::{set_thread_budget, set_thread_callback, CallBudget};

/// A progress callback: `done` of `total` units of a long call are finished. Return 0 to go on,
/// anything else to cancel the call (it then fails with `TROUPE_ERR_CANCELLED`, having written
/// nothing). Called on the thread that made the call, between units of work; it must not unwind
/// (throw) into the library. It may call troupe functions; a long call it makes runs without a
/// callback.
pub type troupe_progress_fn =
    Option<unsafe extern "C" fn(user_data: *mut c_void, done: u64, total: u64) -> i32>;

/// Sets the calling thread's progress callback (NULL removes it): from now on, long calls made
/// on this thread (`troupe_model_load_file`, `troupe_model_load_memory`,
/// `troupe_umf_generate`, `troupe_armflow_clip_generate`, `troupe_magnet_generate`,
/// `troupe_arflow_generate`, `troupe_bvh_read`, `troupe_viewer_write`) report to it between units
/// of work (graphs loaded, a group's network evaluations, clip tokens, sampler steps, BVH frames
/// by 4096, GIF frames) and stop with `TROUPE_ERR_CANCELLED` when it returns non-zero. To cancel from another thread, have the callback read a flag that thread sets.
/// `user_data` is passed back untouched and must stay valid while the callback is set.
/// Per thread, like the last error; thread-safe.
///
/// ```c
/// static int32_t keep_going(void *stop, uint64_t done, uint64_t total) {
///     (void)done; (void)total;
///     return atomic_load((atomic_int *)stop);   // non-zero cancels
/// }
/// troupe_set_progress_callback(keep_going, &stop);
/// ```
#[no_mangle]
pub extern "C" fn troupe_set_progress_callback(
    callback: troupe_progress_fn,
    user_data: *mut c_void,
) {
    let user = user_data as usize;
    boundary::get((), || {
        set_thread_callback(callback.map(|f| {
            Box::new(move |done: u64, total: u64| {
                // SAFETY: a C function pointer given by the caller, called with the pointer it
                // gave, on the thread that set it; its contract says it does not unwind.
                unsafe { f(user as *mut c_void, done, total) == 0 }
            }) as crate::shared::progress::ProgressFn
        }));
    });
}

/// What one long call may cost (`troupe_set_call_budget`). A zero field sets no bound.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct troupe_call_budget {
    /// The most work one call may take, in the call's own unit: a group's network evaluations,
    /// a clip's tokens × solver steps, a MAGNet generation's sampler iterations, an ARFlow
    /// generation's sampler steps. A call that would take more fails with
    /// `TROUPE_ERR_INVALID_ARG` before it starts.
    pub max_work: u64,
    /// The most seconds one call may run. A call past it stops at its next unit of work with
    /// `TROUPE_ERR_CANCELLED`, nothing written.
    pub max_seconds: f64,
}

/// Sets the calling thread's call budget (NULL, or all fields zero, removes it): from now on,
/// `troupe_umf_generate`, `troupe_armflow_clip_generate`, `troupe_magnet_generate` and
/// `troupe_arflow_generate` made on this thread are refused when they would take more than
/// `max_work`, and stop once they have run `max_seconds`. A bound set up front, for a service
/// that runs callers' requests, beside the progress callback's cancelling. Returns `TROUPE_OK`,
/// or `TROUPE_ERR_INVALID_ARG` when `max_seconds` is negative or not a number (the budget is
/// then unchanged). The struct is copied; the caller keeps ownership. Per thread, like the last
/// error; thread-safe.
///
/// ```c
/// troupe_call_budget budget = { .max_work = 5000, .max_seconds = 2.0 };
/// troupe_set_call_budget(&budget);
/// ```
///
/// # Safety
/// `budget` is NULL or points to a readable `troupe_call_budget`.
#[no_mangle]
pub unsafe extern "C" fn troupe_set_call_budget(
    budget: *const troupe_call_budget,
) -> troupe_status {
    boundary::call(
        "troupe_set_call_budget",
        || {},
        || {
            // SAFETY: NULL or a readable struct, by this function's contract.
            let budget = unsafe { budget.as_ref() }.copied().unwrap_or_default();
            set_thread_budget(CallBudget {
                max_work: budget.max_work,
                max_seconds: budget.max_seconds,
            })?;
            Ok(())
        },
    )
}
