//! The library's version and ABI version.

use std::ffi::c_char;

/// ABI version of this library. Bumped on every incompatible change of the C ABI; bindings
/// check `troupe_abi_version() == TROUPE_ABI_VERSION` when they load the library.
pub const TROUPE_ABI_VERSION: u32 = 1;

static VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");

/// The library version, e.g. `"0.2.0"`.
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
