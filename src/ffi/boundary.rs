//! The boundary every C entry point goes through: errors mapped to status codes, the
//! thread-local last error, panic capture, and checked views of caller memory.

use std::cell::UnsafeCell;
use std::ffi::{c_char, CStr};
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::shared::logging::{log, Level};
use crate::shared::panics;
use crate::Error;

use super::status::set_last_error;
pub(crate) use super::status::{
    troupe_status, TROUPE_ERR_BUFFER_TOO_SMALL, TROUPE_ERR_BUSY, TROUPE_ERR_CANCELLED,
    TROUPE_ERR_INFERENCE, TROUPE_ERR_INVALID_ARG, TROUPE_ERR_IO, TROUPE_ERR_MODEL,
    TROUPE_ERR_NULL_ARG, TROUPE_ERR_PANIC, TROUPE_ERR_POISONED, TROUPE_ERR_SHAPE,
    TROUPE_ERR_UNSUPPORTED, TROUPE_OK,
};

/// An error on its way to C: a status and the message for `troupe_last_error_message`.
#[derive(Debug)]
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
            Error::Cancelled(_) => TROUPE_ERR_CANCELLED,
            Error::Unsupported(_) => TROUPE_ERR_UNSUPPORTED,
            Error::OutputTooSmall(_) => TROUPE_ERR_BUFFER_TOO_SMALL,
        };
        Self::new(status, e.to_string())
    }
}

pub(crate) type FfiResult<T = ()> = Result<T, FfiError>;

/// Runs `body` for the C function `name`: maps its error to a status, records the message,
/// and turns a panic into `TROUPE_ERR_PANIC` (calling `on_panic` first, to poison a session).
pub(crate) fn call(
    name: &'static str,
    on_panic: impl FnOnce(),
    body: impl FnOnce() -> FfiResult,
) -> troupe_status {
    let (status, message) = match panics::catch(true, body) {
        Ok(Ok(())) => (TROUPE_OK, None),
        Ok(Err(e)) => (e.status, Some(format!("{name}: {}", e.message))),
        Err(reason) => {
            on_panic();
            (
                TROUPE_ERR_PANIC,
                Some(format!("internal panic in {name}: {reason}")),
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
    panics::catch(true, body).unwrap_or(default)
}

/// Rejects a NULL pointer, naming the parameter.
pub(crate) fn non_null<T>(ptr: *const T, what: &str) -> FfiResult {
    if ptr.is_null() {
        Err(null_arg(what))
    } else {
        Ok(())
    }
}

/// The handle behind a parameter the C side passes as a nullable pointer (`Option<&T>` has the
/// layout of `const T *`, NULL being `None`), or the NULL error naming the parameter. Taking
/// handles this way needs no `unsafe` dereference at each entry point.
pub(crate) fn required<'a, T>(handle: Option<&'a T>, what: &str) -> FfiResult<&'a T> {
    handle.ok_or_else(|| null_arg(what))
}

fn null_arg(what: &str) -> FfiError {
    FfiError::new(TROUPE_ERR_NULL_ARG, format!("`{what}` is NULL"))
}

/// A NUL-terminated UTF-8 string, or `None` for NULL.
///
/// # Safety
/// A non-NULL `ptr` must be NUL-terminated and readable up to its NUL for the call.
pub(crate) unsafe fn optional_str<'a>(
    ptr: *const c_char,
    what: &str,
) -> FfiResult<Option<&'a str>> {
    if ptr.is_null() {
        return Ok(None);
    }
    // SAFETY: non-NULL and NUL-terminated per the contract.
    let text = unsafe { CStr::from_ptr(ptr) }
        .to_str()
        .map_err(|_| FfiError::new(TROUPE_ERR_INVALID_ARG, format!("`{what}` is not UTF-8")))?;
    Ok(Some(text))
}

/// A NUL-terminated UTF-8 string that must not be NULL.
///
/// # Safety
/// As [`optional_str`].
pub(crate) unsafe fn required_str<'a>(ptr: *const c_char, what: &str) -> FfiResult<&'a str> {
    // SAFETY: forwarded contract.
    unsafe { optional_str(ptr, what) }?.ok_or_else(|| null_arg(what))
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

/// Writes `value` into a caller's versioned struct of `size` bytes (its `struct_size`): only
/// `min(size, sizeof T)` bytes of it, zeroing any tail the caller has and this library does not
/// know. `T` must be `repr(C)` without padding, so that only initialised bytes are copied.
///
/// # Safety
/// `dst` must be writable for `size` bytes.
pub(crate) unsafe fn write_versioned<T: Copy>(dst: *mut T, size: usize, value: &T) {
    let ours = std::mem::size_of::<T>();
    let dst = dst.cast::<u8>();
    // SAFETY: writable for `size` bytes per the contract; `value` has `ours` initialised bytes.
    unsafe {
        std::ptr::copy_nonoverlapping((value as *const T).cast::<u8>(), dst, size.min(ours));
        if size > ours {
            std::ptr::write_bytes(dst.add(ours), 0, size - ours);
        }
    }
}

/// Reads a caller's versioned struct whose first field is `uint32_t struct_size`:
/// - older than ours (`min_size <= struct_size < sizeof T`: compiled against an older header):
///   its bytes over `defaults()`, so the fields it does not know keep the value `_init` gives
///   them (the defaults are computed only for such a caller);
/// - ours: as it is;
/// - newer (larger): accepted when every byte past ours is zero (fields this library does not
///   know, left at their "off" value), refused otherwise.
///
/// Smaller than `min_size` (the first published version) is refused. Each published version
/// ends on a field boundary, so an older size never splits a field.
///
/// # Safety
/// `src` must be readable for its `struct_size` bytes.
pub(crate) unsafe fn read_versioned<T: Copy>(
    src: *const T,
    min_size: usize,
    defaults: impl FnOnce() -> FfiResult<T>,
    what: &str,
    init: &str,
) -> FfiResult<T> {
    let ours = std::mem::size_of::<T>();
    // SAFETY: the first field, a u32, is readable in any version of the struct.
    let size = unsafe { src.cast::<u32>().read_unaligned() } as usize;
    if size < min_size {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!(
                "{what}.struct_size is {size}, smaller than any version of the struct (the first \
                 has {min_size} bytes); call {init}"
            ),
        ));
    }
    if size > ours {
        // SAFETY: the caller's struct holds `size` readable bytes.
        let tail = unsafe { std::slice::from_raw_parts(src.cast::<u8>().add(ours), size - ours) };
        if tail.iter().any(|&b| b != 0) {
            return Err(FfiError::new(
                TROUPE_ERR_INVALID_ARG,
                format!(
                    "{what} carries fields this library does not know (non-zero bytes past its \
                     {ours}); update the library or leave them zero"
                ),
            ));
        }
    }
    if size >= ours {
        // SAFETY: at least `ours` readable bytes.
        return Ok(unsafe { src.read_unaligned() });
    }
    let mut value = defaults()?;
    // SAFETY: `size` bytes are readable at `src` and writable in `value`, a `T`
    // without padding whose fields take any bit pattern (plain integers and floats).
    unsafe {
        std::ptr::copy_nonoverlapping(src.cast::<u8>(), (&mut value as *mut T).cast::<u8>(), size);
    }
    Ok(value)
}

/// Checks the `options_size` given to an `_init` function.
pub(crate) fn check_struct_size(size: usize, min_size: usize, what: &str) -> FfiResult {
    if size < min_size || size > u32::MAX as usize {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("options_size {size} is not the size of a {what}"),
        ));
    }
    Ok(())
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

/// A value behind a handle that is used from one thread at a time: a call claims it (an atomic
/// flag, no lock to wait on) and a second thread's call meanwhile fails with `TROUPE_ERR_BUSY`
/// instead of racing on it.
pub(crate) struct Exclusive<T> {
    /// Only touched through a [`Claim`].
    value: UnsafeCell<T>,
    busy: AtomicBool,
}

impl<T> Exclusive<T> {
    pub(crate) fn new(value: T) -> Self {
        Self {
            value: UnsafeCell::new(value),
            busy: AtomicBool::new(false),
        }
    }

    /// The value for the calling thread until the claim drops, or `TROUPE_ERR_BUSY` naming
    /// `what` when another thread holds it.
    pub(crate) fn claim(&self, what: &str) -> FfiResult<Claim<'_, T>> {
        if self
            .busy
            .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
        {
            return Err(FfiError::new(
                TROUPE_ERR_BUSY,
                format!(
                    "{what} is in use by another thread (it is used from one thread at a time)"
                ),
            ));
        }
        Ok(Claim { cell: self })
    }
}

/// Frees the boxed handle `handle` (NULL: nothing) unless another thread is in a call on it, as
/// `exclusive` tells: freeing it then would free memory in use, so the handle is leaked and the
/// C function `name` logs an error instead.
///
/// # Safety
/// `handle` must be NULL or from `Box::into_raw`, not freed before.
pub(crate) unsafe fn free_unless_busy<H, T>(
    handle: *mut H,
    exclusive: impl FnOnce(&H) -> &Exclusive<T>,
    name: &'static str,
) {
    // SAFETY: NULL or a live handle per the contract; only its atomic flag is read through `&`.
    let Some(live) = (unsafe { handle.as_ref() }) else {
        return;
    };
    if exclusive(live).claim("the handle").is_err() {
        log(Level::Error, "troupe::ffi", || {
            format!("{name}: the handle is in use by another thread; not freed")
        });
        return;
    }
    // SAFETY: from Box::into_raw, freed once per the contract, and no call on it in progress
    // (the claim above succeeded and was released).
    get((), || drop(unsafe { Box::from_raw(handle) }));
}

/// Exclusive use of an [`Exclusive`] value for the length of one call.
pub(crate) struct Claim<'a, T> {
    cell: &'a Exclusive<T>,
}

impl<T> Deref for Claim<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // SAFETY: `busy` was set by this claim and is cleared only when it drops: no other
        // reference into the cell exists meanwhile.
        unsafe { &*self.cell.value.get() }
    }
}

impl<T> DerefMut for Claim<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        // SAFETY: as in `deref`; `&mut self` makes this the only reference through the claim.
        unsafe { &mut *self.cell.value.get() }
    }
}

impl<T> Drop for Claim<'_, T> {
    fn drop(&mut self) {
        self.cell.busy.store(false, Ordering::Release);
    }
}

/// `TROUPE_ERR_BUFFER_TOO_SMALL` unless a buffer of `capacity` floats holds `need`.
pub(crate) fn room(need: usize, capacity: usize, what: &str) -> FfiResult {
    if capacity < need {
        return Err(FfiError::new(
            TROUPE_ERR_BUFFER_TOO_SMALL,
            format!("{what} need {need} floats, the buffer holds {capacity}"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Version 2 of a struct whose version 1 ended after `steps`.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Options {
        struct_size: u32,
        steps: u32,
        added_in_v2: u64,
    }
    const V1: usize = 8;
    const DEFAULTS: Options = Options {
        struct_size: 16,
        steps: 10,
        added_in_v2: 77,
    };

    fn read(bytes: &[u8]) -> FfiResult<Options> {
        // SAFETY: `bytes` holds the struct_size the first four bytes give (checked by callers).
        unsafe {
            read_versioned(
                bytes.as_ptr().cast::<Options>(),
                V1,
                || Ok(DEFAULTS),
                "o",
                "init",
            )
        }
    }

    fn caller(size: u32, steps: u32, rest: &[u8]) -> Vec<u8> {
        let mut v = size.to_ne_bytes().to_vec();
        v.extend(steps.to_ne_bytes());
        v.extend(rest);
        v
    }

    #[test]
    fn an_older_caller_gets_the_defaults_of_the_fields_it_does_not_know() {
        let o = read(&caller(8, 3, &[])).unwrap();
        assert_eq!((o.steps, o.added_in_v2), (3, 77));
    }

    #[test]
    fn a_current_caller_is_read_as_it_is() {
        let o = read(&caller(16, 3, &5u64.to_ne_bytes())).unwrap();
        assert_eq!((o.steps, o.added_in_v2), (3, 5));
    }

    #[test]
    fn a_newer_caller_is_accepted_only_with_zero_unknown_fields() {
        let mut newer = caller(24, 3, &5u64.to_ne_bytes());
        newer.extend([0u8; 8]);
        assert_eq!(read(&newer).unwrap().added_in_v2, 5);
        newer[20] = 1;
        let e = read(&newer).unwrap_err();
        assert_eq!(e.status, TROUPE_ERR_INVALID_ARG);
        assert!(e.message.contains("does not know"), "{}", e.message);
    }

    #[test]
    fn a_struct_smaller_than_its_first_version_is_refused() {
        let e = read(&caller(4, 3, &[])).unwrap_err();
        assert_eq!(e.status, TROUPE_ERR_INVALID_ARG);
        assert!(
            e.message.contains("smaller than any version"),
            "{}",
            e.message
        );
    }
}
