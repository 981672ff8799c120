//! The boundary every C entry point goes through: status codes, the thread-local last error,
//! panic capture, and checked views of caller memory.

use std::cell::RefCell;
use std::ffi::{c_char, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::logging::{log, Level};
use crate::Error;

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
/// A file could not be read.
pub const TROUPE_ERR_IO: troupe_status = 5;
/// The bundle is corrupt, unsupported, or inconsistent with its graphs.
pub const TROUPE_ERR_MODEL: troupe_status = 6;
/// A network failed while running.
pub const TROUPE_ERR_INFERENCE: troupe_status = 7;
/// The session panicked earlier; only `troupe_session_reset` and `troupe_session_free` work.
pub const TROUPE_ERR_POISONED: troupe_status = 8;
/// An internal panic was caught; a session involved is poisoned.
pub const TROUPE_ERR_PANIC: troupe_status = 9;

/// An error on its way to C: a status and the message for `troupe_last_error_message`.
pub(crate) struct FfiError {
    pub status: troupe_status,
    pub message: String,
}

impl FfiError {
    pub(crate) fn new(status: troupe_status, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }
}

impl From<Error> for FfiError {
    fn from(e: Error) -> Self {
        let status = match &e {
            Error::Io { .. } => TROUPE_ERR_IO,
            Error::Manifest { .. } | Error::Graph { .. } => TROUPE_ERR_MODEL,
            Error::InvalidInput(_) | Error::InvalidOption(_) => TROUPE_ERR_INVALID_ARG,
            Error::Inference { .. } => TROUPE_ERR_INFERENCE,
        };
        Self::new(status, e.to_string())
    }
}

pub(crate) type FfiResult<T = ()> = Result<T, FfiError>;

thread_local! {
    static LAST_ERROR: RefCell<Option<CString>> = const { RefCell::new(None) };
}

fn set_last_error(message: Option<String>) {
    let message = message.map(|m| CString::new(m.replace('\0', " ")).unwrap_or_default());
    LAST_ERROR.with(|slot| *slot.borrow_mut() = message);
}

/// Pointer to this thread's last error message (NULL after a success).
pub(crate) fn last_error_ptr() -> *const c_char {
    LAST_ERROR.with(|slot| {
        slot.borrow()
            .as_ref()
            .map_or(std::ptr::null(), |m| m.as_ptr())
    })
}

/// This thread's last error message as bytes, without the NUL.
pub(crate) fn last_error_bytes() -> Vec<u8> {
    LAST_ERROR.with(|slot| {
        slot.borrow()
            .as_ref()
            .map(|m| m.as_bytes().to_vec())
            .unwrap_or_default()
    })
}

/// Runs `body` for the C function `name`: maps its error to a status, records the message,
/// and turns a panic into `TROUPE_ERR_PANIC` (calling `on_panic` first, to poison a session).
pub(crate) fn call(
    name: &'static str,
    on_panic: impl FnOnce(),
    body: impl FnOnce() -> FfiResult,
) -> troupe_status {
    let outcome = catch_unwind(AssertUnwindSafe(body));
    let (status, message) = match outcome {
        Ok(Ok(())) => (TROUPE_OK, None),
        Ok(Err(e)) => (e.status, Some(format!("{name}: {}", e.message))),
        Err(payload) => {
            on_panic();
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic payload".into());
            (
                TROUPE_ERR_PANIC,
                Some(format!("internal panic in {name}: {what}")),
            )
        }
    };
    if let Some(m) = &message {
        let level = if status == TROUPE_ERR_PANIC {
            Level::Error
        } else {
            Level::Debug
        };
        log(level, "troupe::ffi", || m.clone());
    }
    set_last_error(message);
    status
}

/// Runs an infallible getter, giving `default` on a panic (and leaving the last error alone).
pub(crate) fn get<T>(default: T, body: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(body)).unwrap_or(default)
}

/// Rejects a NULL pointer, naming the parameter.
pub(crate) fn non_null<T>(ptr: *const T, what: &str) -> FfiResult {
    if ptr.is_null() {
        Err(FfiError::new(
            TROUPE_ERR_NULL_ARG,
            format!("`{what}` is NULL"),
        ))
    } else {
        Ok(())
    }
}

/// A borrowed slice of `len` elements at `ptr` (`ptr` may be NULL only when `len` is 0).
///
/// # Safety
/// A non-NULL `ptr` must point to `len` initialised elements that stay valid and unaliased by
/// writers for the duration of the call.
pub(crate) unsafe fn slice<'a, T>(ptr: *const T, len: usize, what: &str) -> FfiResult<&'a [T]> {
    if len == 0 {
        return Ok(&[]);
    }
    non_null(ptr, what)?;
    if len
        .checked_mul(std::mem::size_of::<T>())
        .is_none_or(|b| b > isize::MAX as usize)
    {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("`{what}` length {len} overflows"),
        ));
    }
    // SAFETY: non-NULL, size checked against isize::MAX, validity guaranteed by the caller.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// `a * b`, or an error naming the product when it overflows.
pub(crate) fn checked_mul(a: usize, b: usize, what: &str) -> FfiResult<usize> {
    a.checked_mul(b).ok_or_else(|| {
        FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("{what}: {a} x {b} overflows"),
        )
    })
}
