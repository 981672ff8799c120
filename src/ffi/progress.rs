//! `troupe_set_progress_callback`: progress reports from long calls, and cancelling them.

use std::ffi::c_void;

use crate::ffi::boundary;
use crate::shared::progress::set_thread_callback;

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
