//! The C ABI's compatibility promise (`docs/ABI.md`), checked on the built shared library:
//! - the symbols it exports are exactly `abi/troupe.symbols` (a removal or rename cannot land
//!   unnoticed; an addition is committed with the list: `TROUPE_BLESS=1 cargo test --test abi`),
//!   every one `troupe_`-prefixed and declared in `include/troupe.h`, every header function
//!   exported;
//! - its SONAME carries the ABI version;
//! - programs compiled against the frozen 0.1.0 and 0.2.0 headers (`abi/<release>/troupe.h`) run
//!   against it;
//! - the 0.1 names compile against today's header with a deprecation warning naming the new one.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::c_libraries as libs;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn shared_library() -> PathBuf {
    libs().join("libtroupe.so")
}

/// Only in builds with the `testing` feature, which the tests' library has.
const TESTING_ONLY: &str = "troupe_testing_panic";

/// The dynamic symbols the library defines, by name.
fn exported() -> BTreeSet<String> {
    let out = Command::new("nm")
        .args(["-D", "--defined-only"])
        .arg(shared_library())
        .output()
        .expect("run nm (binutils)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter_map(|l| l.split_whitespace().nth(2))
        .map(str::to_owned)
        .collect()
}

fn committed_list() -> BTreeSet<String> {
    std::fs::read_to_string(root().join("abi/troupe.symbols"))
        .unwrap_or_default()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(str::to_owned)
        .collect()
}

/// The functions `include/troupe.h` declares (a declaration is one line ending with `);`).
fn header_functions() -> BTreeSet<String> {
    let header = std::fs::read_to_string(root().join("include/troupe.h")).unwrap();
    header
        .lines()
        .filter(|l| l.ends_with(");") && !l.starts_with([' ', '*', '/', '#']))
        .filter(|l| !l.starts_with("typedef"))
        .map(|l| {
            let l = match l.strip_prefix("TROUPE_DEPRECATED(") {
                Some(rest) => &rest[rest.find("\")").unwrap() + 2..],
                None => l,
            };
            let name: String = l[..l.find('(').unwrap()]
                .chars()
                .rev()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            name.chars().rev().collect()
        })
        .collect()
}

#[test]
fn exports_match_the_committed_symbol_list() {
    let mut exported = exported();
    assert!(
        exported.remove(TESTING_ONLY),
        "the tests' library is built with the `testing` feature"
    );
    let foreign: Vec<&String> = exported
        .iter()
        .filter(|s| !s.starts_with("troupe_"))
        .collect();
    assert!(
        foreign.is_empty(),
        "exported without the troupe_ prefix: {foreign:?}"
    );
    if std::env::var_os("TROUPE_BLESS").is_some() {
        let list: Vec<&str> = exported.iter().map(String::as_str).collect();
        std::fs::write(
            root().join("abi/troupe.symbols"),
            format!(
                "# The functions libtroupe exports (tests/abi.rs). Within ABI version 1 names are\n\
                 # only ever added; regenerate with `TROUPE_BLESS=1 cargo test --test abi`.\n{}\n",
                list.join("\n")
            ),
        )
        .unwrap();
        return;
    }
    let committed = committed_list();
    let removed: Vec<&String> = committed.difference(&exported).collect();
    let added: Vec<&String> = exported.difference(&committed).collect();
    assert!(
        removed.is_empty(),
        "symbols of abi/troupe.symbols are no longer exported (an incompatible change: \
         docs/ABI.md): {removed:?}"
    );
    assert!(
        added.is_empty(),
        "new exports not in abi/troupe.symbols (add them: `TROUPE_BLESS=1 cargo test --test \
         abi`): {added:?}"
    );
}

#[test]
fn header_and_exports_name_the_same_functions() {
    let declared = header_functions();
    assert!(declared.len() > 100, "parsed {} functions", declared.len());
    let mut exported = exported();
    exported.remove(TESTING_ONLY);
    let undeclared: Vec<&String> = exported.difference(&declared).collect();
    let missing: Vec<&String> = declared.difference(&exported).collect();
    assert!(
        undeclared.is_empty(),
        "exported, not in the header: {undeclared:?}"
    );
    assert!(
        missing.is_empty(),
        "in the header, not exported: {missing:?}"
    );
}

#[test]
fn soname_carries_the_abi_version() {
    let out = Command::new("readelf")
        .arg("-d")
        .arg(shared_library())
        .output()
        .expect("run readelf (binutils)");
    let text = String::from_utf8_lossy(&out.stdout);
    let header = std::fs::read_to_string(root().join("include/troupe.h")).unwrap();
    let abi = header
        .lines()
        .find_map(|l| l.strip_prefix("#define TROUPE_ABI_VERSION "))
        .expect("TROUPE_ABI_VERSION");
    assert!(
        text.contains(&format!("Library soname: [libtroupe.so.{abi}]")),
        "{text}"
    );
    let build = std::fs::read_to_string(root().join("build.rs")).unwrap();
    assert!(
        build.contains(&format!("const ABI_VERSION: u32 = {abi};")),
        "build.rs's ABI_VERSION differs from TROUPE_ABI_VERSION ({abi})"
    );
}

/// Compiles `tests/c/{program}.c` against the frozen header of `release` (first on the include
/// path, so `#include "troupe.h"` is that release's), runs it on the tiny bundles `bundles`
/// against this library, and asserts every check passed.
fn run_against_frozen_header(release: &str, program: &str, bundles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let binary = dir.path().join(program);
    let libdir = libs().display().to_string();
    let out = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"])
        .arg(format!("-I{}", root().join("abi").join(release).display()))
        .arg(format!("-I{}", root().join("tests/c").display()))
        .arg(root().join(format!("tests/c/{program}.c")))
        .arg("-o")
        .arg(&binary)
        .args([
            format!("-L{libdir}"),
            "-ltroupe".into(),
            format!("-Wl,-rpath,{libdir}"),
            "-lm".into(),
        ])
        .output()
        .expect("run cc");
    assert!(
        out.status.success(),
        "compiling against the {release} header failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = Command::new(&binary)
        .args(bundles.iter().map(|b| root().join("onnx/bundles").join(b)))
        .output()
        .unwrap_or_else(|e| panic!("run the {release} program: {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(run.status.success() && text.contains(" 0 failed"), "{text}");
}

#[test]
fn a_program_built_against_the_0_1_header_runs_against_this_library() {
    run_against_frozen_header(
        "0.1.0",
        "abi_0_1",
        &[
            "armflow-tiny",
            "armflow-tiny-interhuman",
            "umf-tiny",
            "magnet-tiny",
            "arflow-tiny-online",
        ],
    );
}

#[test]
fn a_program_built_against_the_0_2_header_runs_against_this_library() {
    run_against_frozen_header(
        "0.2.0",
        "abi_0_2",
        &["armflow-tiny", "arflow-tiny-online", "magnet-tiny"],
    );
}

#[test]
fn the_old_names_compile_with_a_warning_naming_the_new_one() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("old_name.c");
    std::fs::write(
        &source,
        "#include \"troupe.h\"\nint main(void) { return (int)troupe_model_clip_tokens(0); }\n",
    )
    .unwrap();
    let compile = |extra: &[&str]| {
        Command::new("cc")
            .args(["-std=c99", "-c", "-Werror=deprecated-declarations"])
            .args(extra)
            .arg(format!("-I{}", root().join("include").display()))
            .arg(&source)
            .arg("-o")
            .arg(dir.path().join("old_name.o"))
            .output()
            .expect("run cc")
    };
    let warned = compile(&[]);
    let text = String::from_utf8_lossy(&warned.stderr);
    assert!(
        !warned.status.success(),
        "the old name compiled without a warning"
    );
    assert!(
        text.contains("deprecated") && text.contains("use troupe_armflow_clip_tokens"),
        "{text}"
    );
    let quiet = compile(&["-DTROUPE_NO_DEPRECATION_WARNINGS"]);
    assert!(
        quiet.status.success(),
        "{}",
        String::from_utf8_lossy(&quiet.stderr)
    );
}

/// Every package and binding says the release `Cargo.toml` says (`docs/ABI.md`, "Releases and
/// the ABI"), and the release's header is frozen.
#[test]
fn every_package_says_one_release() {
    let release = env!("CARGO_PKG_VERSION");
    let places: [(&str, &str); 8] = [
        ("bindings/web/Cargo.toml", "\nversion = \"{}\""),
        ("bindings/python/pyproject.toml", "\nversion = \"{}\""),
        (
            "bindings/python/troupe/__init__.py",
            "\n__version__ = \"{}\"",
        ),
        ("bindings/csharp/Troupe.cs", "AssemblyVersion(\"{}\")"),
        ("unity/package.json", "\"version\": \"{}\""),
        ("include/troupe.h", "#define TROUPE_VERSION_STRING \"{}\""),
        ("README.md", "troupe-{}-py3"),
        ("docs/INSTALL.md", "troupe-{}-py3"),
    ];
    for (file, pattern) in places {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        let expected = pattern.replace("{}", release);
        assert!(
            text.contains(&expected),
            "{file} does not say release {release} (expected `{}`)",
            expected.trim()
        );
    }
    assert!(
        root().join("abi").join(release).join("troupe.h").is_file(),
        "abi/{release}/troupe.h: the release's header is not frozen"
    );
}
