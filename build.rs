//! Link settings of the shared library: its SONAME carries the ABI version, so that a program
//! linked against `libtroupe.so` asks for `libtroupe.so.1` at run time, keeps working across
//! compatible releases and refuses an incompatible one (`docs/ABI.md`). What it exports needs no
//! script of ours: rustc's own version script exports exactly the `#[no_mangle]` C functions,
//! and tests/abi.rs checks that list against `abi/troupe.symbols`.
//!
//! It also gathers the Rust samples of the README and the docs into one Markdown file that
//! `src/lib.rs` hands to rustdoc, so that `cargo test` runs each as a doc test.

use std::fmt::Write as _;
use std::path::Path;

// The samples' reader, shared with the tests that run the other languages' samples.
#[allow(dead_code)]
mod samples {
    include!("tests/common/samples.rs");
}

/// The C ABI's major version: bumped only by an incompatible change. Equals
/// `TROUPE_ABI_VERSION` in `src/ffi/version.rs` (tests/abi.rs checks the two agree).
const ABI_VERSION: u32 = 1;

/// Every Rust sample as a doc test: its setup and code inside a `main` returning a `Result`
/// (the setup's lines hidden, as rustdoc hides lines starting with `# `), named by its file and
/// line.
fn rust_samples(root: &Path) -> String {
    let mut doc = String::from("The Rust samples of the README and the docs (`build.rs`).\n\n");
    for sample in samples::samples(root, "rust") {
        let _ = writeln!(doc, "`{}` line {}:\n\n```rust", sample.file, sample.line);
        if let Some(reason) = &sample.skip {
            panic!(
                "{}:{}: a Rust sample is compiled and run, never skipped ({reason})",
                sample.file, sample.line
            );
        }
        doc.push_str(
            "# #![allow(unused)]\n# fn main() -> Result<(), Box<dyn std::error::Error>> {\n",
        );
        for line in sample.setup.lines() {
            let _ = writeln!(doc, "# {line}");
        }
        doc.push_str(&sample.code);
        doc.push_str("# Ok(())\n# }\n```\n\n");
    }
    doc
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=tests/common/samples.rs");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for file in samples::sample_files(root) {
        println!("cargo:rerun-if-changed={}", file.display());
    }
    // `docs/` too, so that a new page's samples are gathered. Cargo walks a watched folder on
    // every build: the other folders (`onnx/` holds the bundles) are watched by their README only.
    println!("cargo:rerun-if-changed={}", root.join("docs").display());
    let out =
        Path::new(&std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("doc_samples.md");
    std::fs::write(&out, rust_samples(root)).expect("write the doc samples");
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    // ELF platforms; Apple's linker names libraries by install name, Windows' by DLL name.
    if matches!(os.as_str(), "linux" | "android" | "freebsd") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libtroupe.so.{ABI_VERSION}");
    }
}
