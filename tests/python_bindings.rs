//! The Python package (`bindings/python`) through the real shared library: its pytest suite run
//! against the freshly built cdylib, then again from a wheel built by `pip wheel` and installed
//! into a scratch site directory (the library found next to the package).
//!
//! Needs numpy, pytest, setuptools and wheel (`scripts/test.sh` installs them into target/venv).

mod common;

use std::path::Path;
use std::process::Command;

use common::c_libraries;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn python(args: &[&str], env: &[(&str, &Path)], unset_library: bool) -> String {
    let mut cmd = Command::new(common::python_command());
    cmd.current_dir(root()).args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    if unset_library {
        cmd.env_remove("TROUPE_LIBRARY_PATH");
    }
    let out = cmd.output().expect("run python3");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "python3 {args:?} failed:\n{text}");
    text
}

fn require_python_tools() {
    let probe = Command::new(common::python_command())
        .args(["-c", "import numpy, pytest, setuptools, wheel"])
        .output();
    assert!(
        matches!(probe, Ok(ref o) if o.status.success()),
        "the Python binding tests need numpy, pytest, setuptools and wheel: run the suite \
         through `scripts/test.sh`, which installs them into target/venv"
    );
}

/// Runs the pytest suite of the package with `env` and asserts it passed.
fn pytest_suite(env: &[(&str, &Path)], unset_library: bool) -> String {
    let text = python(
        &[
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "bindings/python/tests",
        ],
        env,
        unset_library,
    );
    assert!(
        text.contains(" passed") && !text.contains("failed"),
        "{text}"
    );
    text
}

#[test]
fn pytest_suite_against_the_built_library() {
    require_python_tools();
    let lib = c_libraries().join("libtroupe.so");
    let bindings = root().join("bindings/python");
    let text = pytest_suite(
        &[("TROUPE_LIBRARY_PATH", &lib), ("PYTHONPATH", &bindings)],
        false,
    );
    println!("{text}");
}

#[test]
fn wheel_carries_the_library_and_passes_the_suite() {
    require_python_tools();
    let lib = c_libraries().join("libtroupe.so");
    let scratch = tempfile::tempdir().unwrap();
    let wheels = scratch.path().join("wheels");
    let site = scratch.path().join("site");
    python(
        &[
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            wheels.to_str().unwrap(),
            "bindings/python",
        ],
        &[("TROUPE_LIBRARY_PATH", &lib)],
        false,
    );
    let wheel = std::fs::read_dir(&wheels)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "whl"))
        .expect("a wheel was built");
    let listing = python(
        &[
            "-c",
            "import sys, zipfile; print('\\n'.join(zipfile.ZipFile(sys.argv[1]).namelist()))",
            wheel.to_str().unwrap(),
        ],
        &[],
        false,
    );
    assert!(
        listing.contains("troupe/libtroupe.so"),
        "the wheel lacks the library:\n{listing}"
    );
    python(
        &[
            "-m",
            "pip",
            "install",
            "--no-deps",
            "-q",
            "--target",
            site.to_str().unwrap(),
            wheel.to_str().unwrap(),
        ],
        &[],
        false,
    );
    pytest_suite(&[("PYTHONPATH", &site)], true);
}

/// The Python streaming demo runs with its defaults (the trained demo model, its first rule),
/// writes the reactor motion and measures it against the rule's partner.
#[test]
fn python_streaming_demo_runs() {
    require_python_tools();
    let lib = c_libraries().join("libtroupe.so");
    let scratch = tempfile::tempdir().unwrap();
    let npy = scratch.path().join("reactor.npy");
    let text = python(
        &[
            "examples/python/stream.py",
            "--frames",
            "200",
            "--tick",
            "3",
            "--out",
            npy.to_str().unwrap(),
        ],
        &[
            ("TROUPE_LIBRARY_PATH", &lib),
            ("PYTHONPATH", &root().join("bindings/python")),
        ],
        false,
    );
    // 200 frames at 120 fps: 50 at 30 fps, 49 feature frames, 12 tokens of 4 reactor frames.
    assert!(
        text.contains("200 actor frames") && text.contains("48 reactor frames"),
        "{text}"
    );
    assert!(text.contains("real-time factor"), "{text}");
    assert!(
        text.contains("the mirror rule's partner vs the reactor: "),
        "{text}"
    );
    let reactor: ndarray::Array3<f32> = ndarray_npy::read_npy(&npy).unwrap();
    assert_eq!(reactor.dim(), (48, 22, 3));
    assert!(npy.with_extension("html").is_file() && npy.with_extension("gif").is_file());
}

/// The Python MAGNet example runs a released configuration on the tiny bundle's golden clip and
/// writes what it generates.
#[test]
fn python_magnet_example_runs() {
    require_python_tools();
    let lib = c_libraries().join("libtroupe.so");
    let scratch = tempfile::tempdir().unwrap();
    let npy = scratch.path().join("magnet.npy");
    let text = python(
        &[
            "examples/python/magnet.py",
            "--samples",
            "1",
            "--steps",
            "2",
            "--no-x0-guidance",
            "--out",
            npy.to_str().unwrap(),
        ],
        &[
            ("TROUPE_LIBRARY_PATH", &lib),
            ("PYTHONPATH", &root().join("bindings/python")),
        ],
        false,
    );
    assert!(
        text.contains("(1, 208, 2, 145)") && text.contains("finite: True"),
        "{text}"
    );
    let out: ndarray::Array4<f32> = ndarray_npy::read_npy(&npy).unwrap();
    assert_eq!(out.dim(), (1, 208, 2, 145));
}
