//! Link settings of the shared library: its SONAME carries the ABI version, so that a program
//! linked against `libtroupe.so` asks for `libtroupe.so.1` at run time, keeps working across
//! compatible releases and refuses an incompatible one (`docs/ABI.md`). What it exports needs no
//! script of ours: rustc's own version script exports exactly the `#[no_mangle]` C functions,
//! and tests/abi.rs checks that list against `abi/troupe.symbols`.

/// The C ABI's major version: bumped only by an incompatible change. Equals
/// `TROUPE_ABI_VERSION` in `src/ffi/version.rs` (tests/abi.rs checks the two agree).
const ABI_VERSION: u32 = 1;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    // ELF platforms; Apple's linker names libraries by install name, Windows' by DLL name.
    if matches!(os.as_str(), "linux" | "android" | "freebsd") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libtroupe.so.{ABI_VERSION}");
    }
}
