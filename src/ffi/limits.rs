//! `troupe_limits`: the bounds every size from a file or a caller is checked against (see
//! `src/shared/limits.rs`), so that a host can validate its inputs the same way.

use crate::ffi::boundary::{self, check_struct_size, non_null, troupe_status, write_versioned};
use crate::shared::limits::{Limits, LIMITS};

/// troupe's limits, for `troupe_limits_get`. A call given more than a limit fails with
/// `TROUPE_ERR_INVALID_ARG` (a caller's value) or `TROUPE_ERR_MODEL` / `TROUPE_ERR_IO` (a
/// bundle's), naming the limit, before anything is allocated. Fields are only ever appended.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_limits {
    /// `sizeof(troupe_limits)` as the caller compiled it (set by `troupe_limits_get`).
    pub struct_size: u32,
    /// Always 0.
    pub reserved: u32,
    /// The limits.
    pub values: Limits,
}

const LIMITS_V1_SIZE: usize = 8 + std::mem::size_of::<Limits>();
// No padding, so copying its bytes copies only initialised fields.
const _: () = assert!(std::mem::size_of::<troupe_limits>() == LIMITS_V1_SIZE);

/// Writes troupe's limits to `out` (pass `sizeof(troupe_limits)` as `size`; the library writes
/// only that many bytes, zeroing fields it does not know).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`size` smaller than the
/// first version of the struct). Thread-safe.
///
/// # Safety
/// `out` must be writable for `size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_limits_get(out: *mut troupe_limits, size: usize) -> troupe_status {
    boundary::call(
        "troupe_limits_get",
        || {},
        || {
            non_null(out, "out")?;
            check_struct_size(size, LIMITS_V1_SIZE, "troupe_limits")?;
            let value = troupe_limits {
                struct_size: size as u32,
                reserved: 0,
                values: LIMITS,
            };
            // SAFETY: writable for `size` bytes per the contract; no padding (asserted above).
            unsafe { write_versioned(out, size, &value) };
            Ok(())
        },
    )
}
