//! Helpers shared by the integration tests: the committed tiny bundle and its golden files.
#![allow(dead_code)]

pub mod c_programs;
pub mod pictures;
pub mod samples;
pub mod static_server;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use ndarray::{Array1, Array2};
use ndarray_npy::read_npy;
use troupe::{Model, Reactor, ReactorOptions, Session, TokenNoise, TokenTrace};

/// A directory for the whole test process (programs compiled once, an install prefix), under
/// cargo's scratch folder for integration tests, and removed when the process exits, whether
/// its tests passed or failed. A `TempDir` kept in a static is never dropped: each run used to
/// leave half a gigabyte of compiled programs and installs behind in the system's temp folder.
pub fn process_scratch() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    extern "C" fn remove_at_exit() {
        if let Some(dir) = DIR.get() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
    DIR.get_or_init(|| {
        let dir = tempfile::Builder::new()
            .prefix("scratch-")
            .tempdir_in(env!("CARGO_TARGET_TMPDIR"))
            .unwrap()
            .keep();
        // SAFETY: registers a plain function, run by `exit` once `main` (the test harness,
        // passing or failing) has returned; it only reads the set `DIR`.
        #[cfg(unix)]
        unsafe {
            libc::atexit(remove_at_exit);
        }
        dir
    })
}

/// The committed tiny bundle.
pub fn bundle_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-tiny")
}

/// A copy of the tiny bundle's files in a fresh directory.
pub fn bundle_copy() -> tempfile::TempDir {
    copy_of_bundle("armflow-tiny")
}

/// A copy of the files of the committed bundle `onnx/bundles/NAME` (not its goldens) in a
/// fresh directory.
pub fn copy_of_bundle(name: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    copy_bundle_into(name, dir.path());
    dir
}

/// Copies the files of the committed bundle `onnx/bundles/NAME` (not its goldens) into `to`,
/// which is created if missing.
pub fn copy_bundle_into(name: &str, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    let from = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("onnx/bundles")
        .join(name);
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(&path, to.join(path.file_name().unwrap())).unwrap();
        }
    }
}

/// Rewrites the `troupe.json` in `dir` with `edit`.
pub fn edit_manifest(dir: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let path = dir.join("troupe.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

/// Records again, in `dir`'s manifest, the SHA-256 of each file it lists: for a test that
/// changes a graph on purpose to reach a check that runs after the digests' (the loader refuses
/// a file whose digest is not the recorded one before anything else looks at it).
pub fn record_digests(dir: &Path) {
    use sha2::{Digest, Sha256};
    edit_manifest(dir, |v| {
        if let Some(digests) = v["sha256"].as_object_mut() {
            for (name, digest) in digests.iter_mut() {
                let bytes = std::fs::read(dir.join(name)).unwrap();
                let hex: String = Sha256::digest(&bytes)
                    .iter()
                    .map(|b| format!("{b:02x}"))
                    .collect();
                *digest = hex.into();
            }
        }
    });
}

/// The tiny model, loaded once per test binary.
pub fn model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| Model::load(bundle_dir()).expect("the committed bundle loads"))
}

pub fn golden2(name: &str) -> Array2<f32> {
    read_npy(bundle_dir().join("golden").join(format!("{name}.npy")))
        .unwrap_or_else(|e| panic!("golden {name}: {e}"))
}

pub fn golden1(name: &str) -> Array1<f32> {
    read_npy(bundle_dir().join("golden").join(format!("{name}.npy")))
        .unwrap_or_else(|e| panic!("golden {name}: {e}"))
}

/// The golden actor clip, `[frames, 262]`.
pub fn actor() -> Array2<f32> {
    golden2("actor")
}

pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "length mismatch");
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Queues the golden case's injected noise into a session.
pub fn queue_golden_noise(session: &mut Session, case: &str) {
    queue_noise_rows(
        session,
        &golden2(&format!("{case}_xi")),
        &golden2(&format!("{case}_eps")),
    );
}

/// Queues one token's noise per row: the actor's standard normals `xi`, the reactor's `eps`.
#[allow(dead_code)] // not every test binary queues noise
pub fn queue_noise_rows(session: &mut Session, xi: &Array2<f32>, eps: &Array2<f32>) {
    let reactor = session.family_mut::<Reactor>().unwrap();
    for (a, r) in xi.rows().into_iter().zip(eps.rows()) {
        reactor
            .queue_noise(TokenNoise {
                actor: a.to_vec(),
                reactor: r.to_vec(),
            })
            .unwrap();
    }
}

/// Feeds `actor` in chunks of `chunk` frames; returns all frames and the token traces.
pub fn run_chunked(
    session: &mut Session,
    actor: &Array2<f32>,
    chunk: usize,
) -> (Vec<f32>, Vec<TokenTrace>) {
    let (mut frames, mut tokens) = (Vec::new(), Vec::new());
    for rows in actor.axis_chunks_iter(ndarray::Axis(0), chunk) {
        let out = session.step_detailed(rows).unwrap();
        frames.extend(out.frames.iter());
        tokens.extend(out.tokens);
    }
    (frames, tokens)
}

pub fn default_options() -> ReactorOptions {
    ReactorOptions {
        seed: 11,
        ..Default::default()
    }
}

/// Builds the C libraries (libtroupe.so, libtroupe.a) once per test binary with the `testing`
/// feature (which adds the `troupe_testing_panic` hook); returns the directory holding them.
pub fn c_libraries() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let status = Command::new(cargo)
            .current_dir(root)
            // The library alone: the dependencies are those the tests were built with (the
            // manifest's resolver 1 resolves dev-dependencies' features into every build), and
            // under `cargo test --features testing` (scripts/test.sh) the library too.
            .args(["build", "--lib", "--features", "testing"])
            .status()
            .expect("run cargo build");
        assert!(status.success(), "building the C libraries failed");
        let dir = target_dir().join("debug");
        // Programs linked with -ltroupe ask for the SONAME, libtroupe.so.1, at run time; an
        // install names it so (docs/ABI.md), and so does the build folder here.
        let soname = dir.join("libtroupe.so.1");
        if std::fs::read_link(&soname).is_err() {
            let _ = std::fs::remove_file(&soname);
            #[cfg(unix)]
            std::os::unix::fs::symlink("libtroupe.so", &soname).expect("link libtroupe.so.1");
        }
        dir
    })
}

/// The target directory: `CARGO_TARGET_DIR`, else the repository's `target/`.
pub fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"))
}

/// Where skipped checks are recorded: `target/test-skips.txt`, one line per skip,
/// `<test binary>::<test><TAB><reason>`. `scripts/test.sh` empties it before `cargo test` and
/// prints it after, so a check that did not run is counted in the suite's summary.
pub fn skip_record() -> PathBuf {
    target_dir().join("test-skips.txt")
}

/// Says that `test` could not run its check and why: prints `SKIPPED <test>: <reason>` and
/// appends a line to [`skip_record`]. The caller then returns; a test must never pass silently
/// without its check. Opened with O_APPEND and written in one `write`, so the lines of tests
/// running in parallel (threads or binaries) do not interleave.
pub fn skip(test: &str, reason: &str) {
    use std::io::Write;
    println!("SKIPPED {test}: {reason}");
    // One line per skip, whatever the reason's text holds.
    let reason = reason.replace(['\n', '\t'], " ");
    let line = format!("{}::{test}\t{reason}\n", env!("CARGO_CRATE_NAME"));
    let path = skip_record();
    let written = std::fs::create_dir_all(target_dir()).and_then(|()| {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)?
            .write_all(line.as_bytes())
    });
    if let Err(e) = written {
        panic!(
            "{test} is skipped ({reason}) and the skip could not be recorded in {}: {e}",
            path.display()
        );
    }
}

/// Runs `cmd` and returns its output; panics showing its stdout and stderr unless it succeeds.
#[allow(dead_code)] // not every test binary runs commands
pub fn run_ok(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().unwrap_or_else(|e| panic!("run {cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?} failed ({}):\n{}",
        out.status,
        output_text(&out)
    );
    out
}

/// A command's stdout then stderr, as text.
#[allow(dead_code)]
pub fn output_text(out: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Whether every one of `tools` runs (`TOOL --version`). When one does not, `test` cannot run
/// its check: under CI (`CI` set, where `scripts/test.sh` installs `packages`) that is a
/// failure; elsewhere a skip the suite counts, and the caller returns.
#[allow(dead_code)] // not every test binary needs a tool
pub fn tools_or_skip(test: &str, tools: &[&str], packages: &str) -> bool {
    let missing: Vec<&str> = tools
        .iter()
        .copied()
        .filter(|tool| {
            !Command::new(tool)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .collect();
    if missing.is_empty() {
        return true;
    }
    assert!(
        std::env::var_os("CI").is_none_or(|v| v.is_empty()),
        "{} not installed and CI is set: {test} is required there (scripts/test.sh installs it: \
         apt-get install {packages})",
        missing.join(", ")
    );
    skip(test, &format!("{} not installed", missing.join(", ")));
    false
}

/// The Python interpreter the tests run: `TROUPE_PYTHON`, else the project's environment that
/// `scripts/test.sh` makes (`target/venv`), else `python3` on PATH.
pub fn python_command() -> &'static str {
    static PYTHON: OnceLock<String> = OnceLock::new();
    PYTHON.get_or_init(|| {
        if let Ok(p) = std::env::var("TROUPE_PYTHON") {
            return p;
        }
        let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/venv/bin/python3");
        if venv.is_file() {
            return venv.to_string_lossy().into_owned();
        }
        "python3".to_owned()
    })
}

/// Runs Python with `args` and the extra environment `env` in the repository root; returns
/// whether it exited with 0, and its stdout and stderr together.
pub fn run_python(args: &[&str], env: &[(&str, &str)]) -> (bool, String) {
    let out = Command::new(python_command())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .unwrap_or_else(|e| panic!("run {} {args:?}: {e}", python_command()));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// The unpacked source distribution of `requirement` (`name==version`) from PyPI, downloaded
/// once into `target/pypi/` with pip: how tests reach motion-capture files whose licences let
/// them be used but not committed (LAFAN1 is CC BY-NC-ND). A download failure fails the test.
pub fn pypi_sdist(requirement: &str) -> PathBuf {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root
        .join("target/pypi")
        .join(requirement.replace("==", "-"));
    let unpacked = dir.join("unpacked");
    if !unpacked.is_dir() {
        let script = "import pathlib, subprocess, sys, tarfile\n\
            req, dest = sys.argv[1], pathlib.Path(sys.argv[2])\n\
            dest.mkdir(parents=True, exist_ok=True)\n\
            subprocess.check_call([sys.executable, '-m', 'pip', 'download', '--quiet', \
            '--disable-pip-version-check', '--no-deps', '--no-binary', ':all:', req, '-d', \
            str(dest)])\n\
            (tar,) = dest.glob('*.tar.gz')\n\
            tmp = dest / 'unpacking'\n\
            tarfile.open(tar).extractall(tmp)\n\
            tmp.rename(dest / 'unpacked')\n";
        let (ok, text) = run_python(&["-c", script, requirement, dir.to_str().unwrap()], &[]);
        assert!(
            ok,
            "downloading {requirement} from PyPI failed (the test needs the package index):\n{text}"
        );
    }
    std::fs::read_dir(&unpacked)
        .unwrap()
        .next()
        .expect("an unpacked sdist")
        .unwrap()
        .path()
}

/// The normals MAGNet's draw `draw` takes under `seed`, its size read from `refusal`: the error
/// of a run whose queued normals stopped short of that draw ("draw {draw} needs {n} normals,
/// ..."), as a caller replaying a recorded run knows each draw's size from its recording.
pub fn magnet_draw_refused(refusal: &troupe::Error, draw: u64, seed: u64) -> Vec<f32> {
    let e = refusal.to_string();
    let needs = format!("draw {draw} needs ");
    let at = e.find(&needs).unwrap_or_else(|| panic!("{e}")) + needs.len();
    let n: usize = e[at..].split(' ').next().unwrap().parse().unwrap();
    let mut normals = vec![0f32; n];
    troupe::noise::fill_normals(seed, draw, troupe::magnet::STREAM_MAGNET, &mut normals);
    normals
}

/// An example built with the tests (`cargo test` builds them beside its own binaries).
pub fn example(name: &str) -> PathBuf {
    let deps = std::env::current_exe().unwrap();
    let path = deps
        .parent()
        .and_then(Path::parent)
        .unwrap()
        .join("examples")
        .join(name);
    assert!(
        path.is_file(),
        "{} is not built (cargo test builds the examples)",
        path.display()
    );
    path
}
