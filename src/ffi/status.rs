//! Status codes and the last error: what every fallible call returns, and how a caller reads
//! what went wrong. Codes are only ever added, never renumbered.

use std::cell::RefCell;
use std::ffi::{c_char, CString};

/// Status returned by every fallible function: `TROUPE_OK` or one of the `TROUPE_ERR_*` codes.
pub type troupe_status = i32;

/// Success.
pub const TROUPE_OK: troupe_status = 0;
/// A required pointer argument was NULL.
pub const TROUPE_ERR_NULL_ARG: troupe_status = 1;
/// An argument is out of range, malformed, or non-finite.
pub const TROUPE_ERR_INVALID_ARG: troupe_status = 2;
/// A buffer's size does not match what the model needs (e.g. noise length).
pub const TROUPE_ERR_SHAPE: troupe_status = 3;
/// The output buffer cannot hold the frames this call would return.
pub const TROUPE_ERR_BUFFER_TOO_SMALL: troupe_status = 4;
/// A file could not be read or written.
pub const TROUPE_ERR_IO: troupe_status = 5;
/// The bundle is corrupt, unsupported, or inconsistent with its graphs.
pub const TROUPE_ERR_MODEL: troupe_status = 6;
/// A network failed while running.
pub const TROUPE_ERR_INFERENCE: troupe_status = 7;
/// The session panicked earlier; only `troupe_session_reset` and `troupe_session_free` work.
pub const TROUPE_ERR_POISONED: troupe_status = 8;
/// An internal panic was caught; a session involved is poisoned.
pub const TROUPE_ERR_PANIC: troupe_status = 9;
/// The handle is in use by another thread: a session or joint stream is used from one thread
/// at a time. Nothing was done; the call may be retried once the other thread is done.
pub const TROUPE_ERR_BUSY: troupe_status = 10;
/// The call was stopped by the calling thread's progress callback
/// (`troupe_set_progress_callback`); nothing was written.
pub const TROUPE_ERR_CANCELLED: troupe_status = 11;

/// The bundle's family does not offer this call or setting (a group asked of an `armflow`
/// bundle, a MAGNet setting of an ARMFlow stream); the message names the family and the one
/// that does. Nothing was done.
pub const TROUPE_ERR_UNSUPPORTED: troupe_status = 12;

thread_local! {
    static LAST_ERROR: RefCell<Option<CString>> = const { RefCell::new(None) };
}

pub(crate) fn set_last_error(message: Option<String>) {
    let message = message.map(|m| CString::new(m.replace('\0', " ")).unwrap_or_default());
    LAST_ERROR.with(|slot| *slot.borrow_mut() = message);
}

/// Pointer to this thread's last error message (NULL after a success).
fn last_error_ptr() -> *const c_char {
    LAST_ERROR.with(|slot| {
        slot.borrow()
            .as_ref()
            .map_or(std::ptr::null(), |m| m.as_ptr())
    })
}

/// This thread's last error message as bytes, without the NUL.
fn last_error_bytes() -> Vec<u8> {
    LAST_ERROR.with(|slot| {
        slot.borrow()
            .as_ref()
            .map(|m| m.as_bytes().to_vec())
            .unwrap_or_default()
    })
}

/// A static name for a status code (`"TROUPE_OK"`, `"TROUPE_ERR_NULL_ARG"`, ...), or
/// `"TROUPE_ERR_UNKNOWN"`. Never free it. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_status_name(status: troupe_status) -> *const c_char {
    let name: &'static str = match status {
        0 => "TROUPE_OK\0",
        1 => "TROUPE_ERR_NULL_ARG\0",
        2 => "TROUPE_ERR_INVALID_ARG\0",
        3 => "TROUPE_ERR_SHAPE\0",
        4 => "TROUPE_ERR_BUFFER_TOO_SMALL\0",
        5 => "TROUPE_ERR_IO\0",
        6 => "TROUPE_ERR_MODEL\0",
        7 => "TROUPE_ERR_INFERENCE\0",
        8 => "TROUPE_ERR_POISONED\0",
        9 => "TROUPE_ERR_PANIC\0",
        10 => "TROUPE_ERR_BUSY\0",
        11 => "TROUPE_ERR_CANCELLED\0",
        12 => "TROUPE_ERR_UNSUPPORTED\0",
        _ => "TROUPE_ERR_UNKNOWN\0",
    };
    name.as_ptr().cast()
}

/// The message of the last failed troupe call on this thread, or NULL if the last call
/// succeeded.
///
/// The string is owned by the library and valid until the next troupe call on the same thread;
/// copy it (or use `troupe_last_error_copy`) to keep it. Thread-safe (per-thread state).
#[no_mangle]
pub extern "C" fn troupe_last_error_message() -> *const c_char {
    last_error_ptr()
}

/// Copies the last error message of this thread into `buf` (capacity `capacity` bytes, always
/// NUL-terminated when `capacity > 0`, truncated if needed) and writes the bytes the whole
/// message needs, NUL included, to `*needed` (1 when there is no error). `buf` may be NULL when
/// `capacity` is 0. Does not clear the error.
///
/// Returns `TROUPE_OK`, or `TROUPE_ERR_NULL_ARG` if `needed` is NULL or `buf` is NULL with a
/// non-zero capacity. Thread-safe.
///
/// # Safety
/// `buf` must be writable for `capacity` bytes; `needed` must be writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_last_error_copy(
    buf: *mut c_char,
    capacity: usize,
    needed: *mut usize,
) -> troupe_status {
    let message = last_error_bytes();
    if needed.is_null() || (buf.is_null() && capacity > 0) {
        return TROUPE_ERR_NULL_ARG;
    }
    if capacity > 0 {
        let n = message.len().min(capacity - 1);
        // SAFETY: the caller guarantees `buf` holds `capacity` bytes; n + 1 <= capacity.
        unsafe {
            std::ptr::copy_nonoverlapping(message.as_ptr().cast(), buf, n);
            *buf.add(n) = 0;
        }
    }
    // SAFETY: checked non-NULL above; the caller guarantees it is writable.
    unsafe { *needed = message.len() + 1 };
    TROUPE_OK
}
