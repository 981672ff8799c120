//! Version queries and error-message accessors.

use std::ffi::c_char;

use super::boundary::{self, troupe_status, TROUPE_ERR_NULL_ARG, TROUPE_OK};

/// ABI version of this library. Bumped on every incompatible change of the C ABI; bindings
/// check `troupe_abi_version() == TROUPE_ABI_VERSION` when they load the library.
pub const TROUPE_ABI_VERSION: u32 = 1;

static VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");

/// The library version, e.g. `"0.1.0"`.
///
/// Returns a static NUL-terminated string (never free it). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_version_string() -> *const c_char {
    VERSION.as_ptr().cast()
}

/// The library version packed as `(major << 16) | (minor << 8) | patch`; equals
/// `TROUPE_VERSION_NUMBER` of the header the caller compiled against when they match. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_version_number() -> u32 {
    let part = |s: &str| s.parse::<u32>().unwrap_or(0);
    (part(env!("CARGO_PKG_VERSION_MAJOR")) << 16)
        | (part(env!("CARGO_PKG_VERSION_MINOR")) << 8)
        | part(env!("CARGO_PKG_VERSION_PATCH"))
}

/// The ABI version the library was built with (see `TROUPE_ABI_VERSION`). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_abi_version() -> u32 {
    TROUPE_ABI_VERSION
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
    boundary::last_error_ptr()
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
    let message = boundary::last_error_bytes();
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
