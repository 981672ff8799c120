//! The log callback.

use std::ffi::{c_char, c_void};

use super::boundary::{self, troupe_status, FfiError, TROUPE_ERR_INVALID_ARG};
use crate::shared::logging::{set_sink, Sink};

/// Log level: something failed.
pub const TROUPE_LOG_ERROR: i32 = 1;
/// Log level: something looks wrong.
pub const TROUPE_LOG_WARN: i32 = 2;
/// Log level: milestones (model loaded, session created).
pub const TROUPE_LOG_INFO: i32 = 3;
/// Log level: details, including every error returned to the caller.
pub const TROUPE_LOG_DEBUG: i32 = 4;

/// A log callback: `level` is one of `TROUPE_LOG_*`; `target` and `message` are NUL-terminated
/// and valid only during the call.
pub type troupe_log_fn = Option<
    unsafe extern "C" fn(
        user_data: *mut c_void,
        level: i32,
        target: *const c_char,
        message: *const c_char,
    ),
>;

/// Routes the library's log lines at `max_level` or more severe (`TROUPE_LOG_ERROR` ..
/// `TROUPE_LOG_DEBUG`) to `callback`, with `user_data` passed back untouched. NULL restores the
/// default: silent (or stderr when the environment sets `TROUPE_LOG=error|warn|info|debug`).
///
/// Thread-safe: the callback may be swapped at any time. The callback itself may be called
/// concurrently from every thread that calls into troupe, so it must be thread-safe; it must
/// not call troupe functions, and must not unwind or `longjmp` out.
///
/// Returns `TROUPE_OK`, or `TROUPE_ERR_INVALID_ARG` for a level outside 1..=4.
#[no_mangle]
pub extern "C" fn troupe_set_log_callback(
    callback: troupe_log_fn,
    user_data: *mut c_void,
    max_level: i32,
) -> troupe_status {
    boundary::call(
        "troupe_set_log_callback",
        || {},
        || {
            let Some(callback) = callback else {
                set_sink(None);
                return Ok(());
            };
            if !(TROUPE_LOG_ERROR..=TROUPE_LOG_DEBUG).contains(&max_level) {
                return Err(FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    format!("max_level {max_level} is not a TROUPE_LOG_* level (1..=4)"),
                ));
            }
            set_sink(Some(Sink {
                callback,
                user_data: user_data as usize,
                max_level,
            }));
            Ok(())
        },
    )
}
