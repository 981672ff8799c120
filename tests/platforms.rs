//! troupe on the other targets engines ship to, built and run on this Linux x86-64 machine
//! (docs/PLATFORMS.md): Windows x64 (cross-built with MinGW-w64, run under Wine) and Linux arm64
//! (cross-built with Debian's aarch64 toolchain, run under qemu-user). For each target:
//!
//! - the library is cross-built (`cargo build --release --lib --features testing --target
//!   TRIPLE`: optimised, because emulated unoptimised code is slow; `scripts/test.sh` has
//!   built it already, with the target's unit and golden tests, so here it is fresh), and
//!   every C test program of `tests/c` is compiled with the target's C compiler against it and
//!   run there with the same golden parity and bad-input checks as on the host (the smoke test
//!   also as C++17);
//! - the paths an engine gives (`tests/c/paths.c`): either separator, drive letters, names in
//!   several scripts, Windows device names (`NUL`, `CON`, `\\.\NUL`, `aux.bvh`) and a bundle
//!   file linked from outside the bundle, all refused without a hang;
//! - the C streaming example (`examples/c/stream.c`) writes its reactor, compared with the
//!   host's: bit-identical, or the largest difference printed and held to the golden tolerance.
//!
//! The Rust unit tests and the golden parity tests run on each target through cargo itself
//! (`cargo test --release --target TRIPLE --features testing --lib --test golden`, in
//! `scripts/test.sh`, sharing the library's build),
//! with `scripts/platform-run.sh` as the runner (`.cargo/config.toml`).
//!
//! The cross compilers, Wine and qemu are Debian packages `scripts/test.sh` installs, with the
//! Rust targets; when one is missing a test fails under CI and elsewhere records a counted skip.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use common::c_programs::{c_programs, compile, root, run, scratch};

/// A target troupe is cross-built for and run on here.
struct Target {
    triple: &'static str,
    /// Its C and C++ compilers.
    cc: &'static str,
    cxx: &'static str,
    /// What must be installed (checked with `--version`), and the Debian packages holding it.
    tools: &'static [&'static str],
    packages: &'static str,
}

const WINDOWS_X64: Target = Target {
    triple: "x86_64-pc-windows-gnu",
    cc: "x86_64-w64-mingw32-gcc",
    cxx: "x86_64-w64-mingw32-g++",
    tools: &["x86_64-w64-mingw32-gcc", "x86_64-w64-mingw32-g++", "wine"],
    packages: "gcc-mingw-w64-x86-64 g++-mingw-w64-x86-64 wine wine64",
};

const LINUX_ARM64: Target = Target {
    triple: "aarch64-unknown-linux-gnu",
    cc: "aarch64-linux-gnu-gcc",
    cxx: "aarch64-linux-gnu-g++",
    tools: &[
        "aarch64-linux-gnu-gcc",
        "aarch64-linux-gnu-g++",
        "qemu-aarch64",
    ],
    packages: "gcc-aarch64-linux-gnu g++-aarch64-linux-gnu qemu-user",
};

impl Target {
    fn windows(&self) -> bool {
        self.triple.contains("windows")
    }

    /// Whether the tools and the Rust target are installed; if not, fails under CI and records
    /// a counted skip elsewhere (`common::tools_or_skip`).
    fn ready(&self, test: &str) -> bool {
        if !common::tools_or_skip(test, self.tools, self.packages) {
            return false;
        }
        let sysroot = Command::new("rustc")
            .args(["--print", "sysroot"])
            .output()
            .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()))
            .unwrap_or_default();
        if sysroot.join("lib/rustlib").join(self.triple).is_dir() {
            return true;
        }
        assert!(
            std::env::var_os("CI").is_none_or(|v| v.is_empty()),
            "the Rust target {} is not installed and CI is set: {test} is required there \
             (scripts/test.sh installs it: rustup target add {})",
            self.triple,
            self.triple
        );
        common::skip(
            test,
            &format!(
                "the Rust target {} is not installed (rustup target add)",
                self.triple
            ),
        );
        false
    }

    /// The folder holding the library built for this target (built once per test binary).
    fn library(&self) -> &'static Path {
        static WINDOWS: OnceLock<PathBuf> = OnceLock::new();
        static ARM64: OnceLock<PathBuf> = OnceLock::new();
        let cell = if self.windows() { &WINDOWS } else { &ARM64 };
        cell.get_or_init(|| {
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let status = Command::new(cargo)
                .current_dir(root())
                .args([
                    "build",
                    "--release",
                    "--lib",
                    "--features",
                    "testing",
                    "--target",
                ])
                .arg(self.triple)
                .status()
                .expect("run cargo build");
            assert!(
                status.success(),
                "building troupe for {} failed",
                self.triple
            );
            let dir = common::target_dir().join(self.triple).join("release");
            if !self.windows() {
                // The SONAME programs ask for at run time (docs/ABI.md).
                let soname = dir.join("libtroupe.so.1");
                let _ = std::fs::remove_file(&soname);
                std::os::unix::fs::symlink("libtroupe.so", &soname).expect("link libtroupe.so.1");
            }
            dir
        })
    }

    /// How a program links the library: Windows through the import library, so `troupe.dll` is
    /// loaded at run time; Linux through the SONAME with the build folder as run path.
    fn link(&self) -> Vec<String> {
        let dir = self.library().display().to_string();
        if self.windows() {
            vec![format!("{dir}/libtroupe.dll.a")]
        } else {
            vec![
                format!("-L{dir}"),
                "-ltroupe".into(),
                format!("-Wl,-rpath,{dir}"),
                "-lm".into(),
            ]
        }
    }

    /// The command prefix that runs one of this target's programs here, against the library
    /// built for it.
    fn runner(&self) -> Vec<String> {
        self.runner_with(self.library())
    }

    /// The command prefix that runs one of this target's programs here: the runner script,
    /// with Windows' DLL search path holding `dll_dir` (where `troupe.dll` is) and MinGW's
    /// run-time DLLs (winpthread for the threaded test, libstdc++ for the C++ one).
    fn runner_with(&self, dll_dir: &Path) -> Vec<String> {
        let script = root().join("scripts/platform-run.sh").display().to_string();
        let mut prefix = Vec::new();
        if self.windows() {
            let mut dirs = vec![dll_dir.to_path_buf()];
            for dll in ["libwinpthread-1.dll", "libstdc++-6.dll"] {
                let out = Command::new(self.cxx)
                    .arg(format!("-print-file-name={dll}"))
                    .output()
                    .expect("ask the MinGW compiler for its DLLs");
                let path = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
                if let Some(parent) = path.parent().filter(|_| path.is_file()) {
                    dirs.push(parent.to_path_buf());
                }
            }
            let joined: Vec<String> = dirs.iter().map(|d| windows_path(d)).collect();
            prefix.extend(["env".to_string(), format!("WINEPATH={}", joined.join(";"))]);
        }
        prefix.extend([script, self.triple.to_string()]);
        prefix
    }

    /// `tests/c/NAME.c` (or another source) compiled for this target as C99 (or C++17).
    fn compile(&self, source: &Path, flags: &[&str], cpp: bool, name: &str) -> PathBuf {
        let (compiler, standard): (&str, &[&str]) = if cpp {
            (self.cxx, &["-std=c++17", "-x", "c++"])
        } else {
            (self.cc, &["-std=c99"])
        };
        let suffix = if self.windows() { ".exe" } else { "" };
        // `-x c++` would also apply to the import library: back to guessing by extension.
        let link = [vec!["-x".to_string(), "none".to_string()], self.link()].concat();
        compile(
            compiler,
            &[standard, flags].concat(),
            &[source],
            &link,
            &format!("{name}-{}{suffix}", self.triple),
        )
    }
}

/// `path` as a Windows program sees it under Wine: the Unix root is drive Z:.
fn windows_path(path: &Path) -> String {
    format!("Z:{}", path.display()).replace('/', "\\")
}

/// Every C test program compiled for `target` and run there: the checks it makes (golden
/// parity, every bad input) must all pass, as on the host.
fn c_programs_on(target: &Target, test: &str) {
    if !target.ready(test) {
        return;
    }
    std::fs::create_dir_all(scratch().join("viewer-sanitized")).unwrap();
    let runner = target.runner();
    let runner: Vec<&str> = runner.iter().map(String::as_str).collect();
    for (name, args, flags) in c_programs() {
        let source = root().join(format!("tests/c/{name}.c"));
        let bin = target.compile(&source, flags, false, name);
        let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
        let start = std::time::Instant::now();
        let text = run(&runner, &bin, &args);
        println!(
            "{} {name}: {} ({:.1} s)",
            target.triple,
            text.lines().last().unwrap_or(""),
            start.elapsed().as_secs_f64()
        );
        if name == "smoke" {
            let bin = target.compile(&source, &["-DTROUPE_TESTING"], true, "smoke_cpp");
            run(&runner, &bin, &args);
        }
    }
}

#[test]
fn windows_x64_c_programs_under_wine() {
    c_programs_on(&WINDOWS_X64, "windows_x64_c_programs_under_wine");
}

#[test]
fn linux_arm64_c_programs_under_qemu() {
    c_programs_on(&LINUX_ARM64, "linux_arm64_c_programs_under_qemu");
}

/// The paths test (`tests/c/paths.c`) on `target`: a copy of the tiny bundle under a folder
/// named in several scripts, loaded by every spelling of its path the platform has; a copy
/// whose graph is a link to a file outside it; device names and special files, refused.
fn paths_on(target: &Target, test: &str) {
    if !target.ready(test) {
        return;
    }
    let base = scratch().join(format!("paths-{}", target.triple));
    let unicode = base.join("bündel ü-ß 日本 Ωμέγα");
    let bundle = unicode.join("armflow-tiny");
    common::copy_bundle_into("armflow-tiny", &bundle);
    // A bundle whose velocity graph is a symbolic link to a copy outside the bundle.
    let linked = base.join("linked");
    common::copy_bundle_into("armflow-tiny", &linked);
    let outside = base.join("outside.onnx");
    std::fs::rename(linked.join("velocity.onnx"), &outside).unwrap();
    std::os::unix::fs::symlink(&outside, linked.join("velocity.onnx")).unwrap();

    let mut lines = Vec::new();
    let unix = |p: &Path| p.display().to_string();
    if target.windows() {
        let win = |p: &Path| windows_path(p);
        lines.extend([
            format!("load {}", win(&bundle)),
            format!("load {}", unix(&bundle)),
            format!("load {}", win(&bundle).replace('\\', "/")),
            // Relative to the working directory, with backslashes.
            "load bündel ü-ß 日本 Ωμέγα\\armflow-tiny".to_string(),
            format!("refuse {}", win(&linked)),
            "refuse NUL".to_string(),
            "refuse CON".to_string(),
            "refuse nul.troupe".to_string(),
            "refuse COM1".to_string(),
            "refuse \\\\.\\NUL".to_string(),
            format!("refuse {}\\con.tar", win(&unicode)),
            format!("bvh {}\\take ü.bvh", win(&unicode)),
            "refuse-write NUL".to_string(),
            format!("refuse-write {}\\aux.bvh", win(&unicode)),
            "refuse-bvh CON".to_string(),
            "refuse-bvh nul.bvh".to_string(),
        ]);
    } else {
        lines.extend([
            format!("load {}", unix(&bundle)),
            format!("load {}/./armflow-tiny/", unix(&unicode)),
            "load bündel ü-ß 日本 Ωμέγα/armflow-tiny".to_string(),
            format!("refuse {}", unix(&linked)),
            "refuse /dev/null".to_string(),
            format!("bvh {}/take ü.bvh", unix(&unicode)),
            "refuse-write /dev/null".to_string(),
            "refuse-bvh /dev/null".to_string(),
        ]);
    }
    let list = base.join("paths.txt");
    std::fs::write(&list, lines.join("\n") + "\n").unwrap();
    let bin = target.compile(&root().join("tests/c/paths.c"), &[], false, "paths_test");
    let runner = target.runner();
    let out = Command::new(&runner[0])
        .args(&runner[1..])
        .arg(&bin)
        .arg(&list)
        .current_dir(&base)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run the paths test");
    let text = common::output_text(&out);
    println!("{text}");
    assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
    assert_eq!(
        text.matches(": ok").count(),
        lines.len(),
        "every line ran:\n{text}"
    );
    if target.windows() {
        assert!(
            text.contains("the path names the Windows device `NUL`, not a file"),
            "device names are refused as such:\n{text}"
        );
    }
}

#[test]
fn windows_x64_paths_under_wine() {
    paths_on(&WINDOWS_X64, "windows_x64_paths_under_wine");
}

#[test]
fn linux_arm64_paths_under_qemu() {
    paths_on(&LINUX_ARM64, "linux_arm64_paths_under_qemu");
}

/// The reactor the C streaming example writes for `bundle` (`frames` actor frames of the CMU
/// clip, one token per step), run with `runner` (empty: natively).
fn stream_example(
    bin: &Path,
    runner: &[String],
    bundle: &str,
    frames: &str,
    out: &Path,
) -> Vec<u8> {
    let mut command = match runner.split_first() {
        Some((first, rest)) => {
            let mut c = Command::new(first);
            c.args(rest).arg(bin);
            c
        }
        None => Command::new(bin),
    };
    let result = command
        .current_dir(root())
        .args([bundle, frames, "1"])
        .arg(out)
        .arg("tests/data/mocap/cmu-playground-120fps.npy")
        .output()
        .expect("run the streaming example");
    assert!(
        result.status.success(),
        "{}{}",
        String::from_utf8_lossy(&result.stdout),
        String::from_utf8_lossy(&result.stderr)
    );
    std::fs::read(out).unwrap()
}

/// The float32 payload of a .npy file the example wrote (its header is 128 bytes, format 1.0).
fn floats(npy: &[u8]) -> Vec<f32> {
    let header = 10 + u16::from_le_bytes([npy[8], npy[9]]) as usize;
    npy[header..]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// The C streaming example on `target` against the same example on the host, on the tiny
/// bundle and the trained demo model: the reactor's joint positions compared bit for bit,
/// else the largest difference (metres) printed and held to the goldens' frame tolerance.
fn same_bits_on(target: &Target, test: &str) {
    if !target.ready(test) {
        return;
    }
    let source = root().join("examples/c/stream.c");
    let host = compile(
        "cc",
        &["-std=c99", "-O2"],
        &[&source],
        &[
            format!("-L{}", common::c_libraries().display()),
            "-ltroupe".into(),
            format!("-Wl,-rpath,{}", common::c_libraries().display()),
            "-lm".into(),
        ],
        "stream-host",
    );
    let cross = target.compile(&source, &["-O2"], false, "stream");
    let runner = target.runner();
    for (bundle, frames) in [
        ("onnx/bundles/armflow-tiny", "400"),
        ("onnx/bundles/armflow-demo", "400"),
    ] {
        let name = Path::new(bundle).file_name().unwrap().to_str().unwrap();
        let want = stream_example(
            &host,
            &[],
            bundle,
            frames,
            &scratch().join(format!("{name}-host.npy")),
        );
        let got = stream_example(
            &cross,
            &runner,
            bundle,
            frames,
            &scratch().join(format!("{name}-{}.npy", target.triple)),
        );
        let (want, got) = (floats(&want), floats(&got));
        assert_eq!(want.len(), got.len());
        let identical = want
            .iter()
            .zip(&got)
            .filter(|(a, b)| a.to_bits() == b.to_bits())
            .count();
        let worst = want
            .iter()
            .zip(&got)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        println!(
            "{} {name}: {identical} of {} floats bit-identical to the host's, largest \
             difference {worst:.3e} m",
            target.triple,
            want.len()
        );
        assert!(worst <= 1e-4, "{name}: {worst}");
    }
}

#[test]
fn windows_x64_streams_the_same_bits_as_the_host() {
    same_bits_on(
        &WINDOWS_X64,
        "windows_x64_streams_the_same_bits_as_the_host",
    );
}

#[test]
fn linux_arm64_streams_the_same_bits_as_the_host() {
    same_bits_on(
        &LINUX_ARM64,
        "linux_arm64_streams_the_same_bits_as_the_host",
    );
}

/// `scripts/install.sh --target TRIPLE` lays out the library as that platform's users expect
/// (docs/PLATFORMS.md), and the C streaming example, built against the installed files only,
/// runs there. On Windows the `.def` for MSVC lists exactly what the DLL exports.
fn install_on(target: &Target, test: &str) {
    if !target.ready(test) {
        return;
    }
    target.library();
    let prefix = scratch().join(format!("install-{}", target.triple));
    common::run_ok(Command::new("bash").current_dir(root()).args([
        "scripts/install.sh",
        "--prefix",
        prefix.to_str().unwrap(),
        "--target",
        target.triple,
        "--profile",
        "release",
        "--no-build",
    ]));
    let installed: &[&str] = if target.windows() {
        &[
            "bin/troupe.dll",
            "lib/libtroupe.dll.a",
            "lib/troupe.def",
            "lib/libtroupe.a",
            "lib/pkgconfig/troupe.pc",
        ]
    } else {
        &[
            "lib/libtroupe.so.1",
            "lib/libtroupe.so",
            "lib/libtroupe.a",
            "lib/pkgconfig/troupe.pc",
            "lib/pkgconfig/troupe-static.pc",
        ]
    };
    for file in installed.iter().chain(&[
        "include/troupe/troupe.h",
        "include/troupe/troupe.hpp",
        "lib/cmake/troupe/troupeConfig.cmake",
        "lib/cmake/troupe/troupeConfigVersion.cmake",
        "share/troupe/bundles/armflow-demo/troupe.json",
    ]) {
        let path = prefix.join(file);
        let size = std::fs::metadata(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .len();
        println!("{} {file}: {size} bytes", target.triple);
    }
    let (library, link) = if target.windows() {
        let dll = prefix.join("bin/troupe.dll");
        // The DLL's export table against the .def an MSVC user builds troupe.lib from.
        let dump = common::output_text(&common::run_ok(
            Command::new("x86_64-w64-mingw32-objdump")
                .arg("-p")
                .arg(&dll),
        ));
        let mut exported: Vec<&str> = dump
            .lines()
            .skip_while(|l| !l.contains("[Ordinal/Name Pointer] Table"))
            .filter_map(|l| l.split_whitespace().last())
            .filter(|name| name.starts_with("troupe_") && *name != "troupe_testing_panic")
            .collect();
        exported.sort_unstable();
        exported.dedup();
        let def = std::fs::read_to_string(prefix.join("lib/troupe.def")).unwrap();
        let mut listed: Vec<&str> = def.lines().skip(2).map(str::trim).collect();
        listed.sort_unstable();
        assert_eq!(exported, listed, "the DLL's exports and troupe.def");
        assert!(listed.len() > 100, "{listed:?}");
        (
            prefix.join("bin"),
            vec![prefix.join("lib/libtroupe.dll.a").display().to_string()],
        )
    } else {
        let lib = prefix.join("lib");
        // An arm64 ELF file: EM_AARCH64 (183) at offset 18.
        let elf = std::fs::read(lib.join("libtroupe.so.1")).unwrap();
        assert_eq!((&elf[..4], elf[18]), (&b"\x7fELF"[..], 183));
        (
            lib.clone(),
            vec![
                format!("-L{}", lib.display()),
                "-ltroupe".into(),
                format!("-Wl,-rpath,{}", lib.display()),
                "-lm".into(),
            ],
        )
    };
    let out = scratch().join(format!("installed-{}", target.triple));
    std::fs::create_dir_all(&out).unwrap();
    let result = Command::new(target.cc)
        .args(["-std=c99", "-O2"])
        .args(common::c_programs::STRICT)
        .arg(format!("-I{}", prefix.join("include/troupe").display()))
        .arg(root().join("examples/c/stream.c"))
        .arg("-o")
        .arg(out.join("stream"))
        .args(&link)
        .output()
        .unwrap();
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let bin = if target.windows() {
        out.join("stream.exe")
    } else {
        out.join("stream")
    };
    let runner = target.runner_with(&library);
    let text = common::output_text(&common::run_ok(
        Command::new(&runner[0])
            .args(&runner[1..])
            .arg(&bin)
            .current_dir(root())
            .args([
                "onnx/bundles/armflow-tiny",
                "200",
                "3",
                out.join("reactor.npy").to_str().unwrap(),
                "tests/data/mocap/cmu-playground-120fps.npy",
            ]),
    ));
    assert!(text.contains("48 reactor frames"), "{text}");
}

#[test]
fn windows_x64_install_layout_and_a_program_built_against_it() {
    install_on(
        &WINDOWS_X64,
        "windows_x64_install_layout_and_a_program_built_against_it",
    );
}

#[test]
fn linux_arm64_install_layout_and_a_program_built_against_it() {
    install_on(
        &LINUX_ARM64,
        "linux_arm64_install_layout_and_a_program_built_against_it",
    );
}

/// One Unity package for every platform built here: `scripts/install.sh --unity-package` run
/// for the host, then for Windows x64 and Linux arm64 into the same folder, gathers the three
/// plugins. Each plugin's importer enables it for its own OS and CPU only, every asset has its
/// own GUID, and the assembly definition includes the editor and the two players present.
#[test]
fn unity_package_gathers_the_plugins_of_every_platform() {
    let test = "unity_package_gathers_the_plugins_of_every_platform";
    if !WINDOWS_X64.ready(test) || !LINUX_ARM64.ready(test) {
        return;
    }
    common::c_libraries();
    WINDOWS_X64.library();
    LINUX_ARM64.library();
    let unity = scratch().join("unity-every-platform");
    let _ = std::fs::remove_dir_all(&unity);
    for (target, profile) in [
        (None, "dev"),
        (Some(WINDOWS_X64.triple), "release"),
        (Some(LINUX_ARM64.triple), "release"),
    ] {
        let prefix = scratch().join(format!("unity-prefix-{}", target.unwrap_or("host")));
        let mut install = Command::new("bash");
        install
            .current_dir(root())
            .arg("scripts/install.sh")
            .arg("--prefix")
            .arg(&prefix)
            .args(["--profile", profile, "--no-build", "--unity-package"])
            .arg(&unity);
        if let Some(triple) = target {
            install.args(["--target", triple]);
        }
        let text = common::output_text(&common::run_ok(&mut install));
        println!("{text}");
    }
    // The plugin, its OS and CPU in the editor, and the standalone player it is enabled for.
    for (plugin, os, cpu, player) in [
        ("x86_64/libtroupe.so", "Linux", "x86_64", "Linux64"),
        ("ARM64/libtroupe.so", "Linux", "ARM64", "Linux64"),
        ("x86_64/troupe.dll", "Windows", "x86_64", "Win64"),
    ] {
        let path = unity.join("Runtime/Plugins").join(plugin);
        assert!(path.is_file(), "the package lacks {plugin}");
        let meta = std::fs::read_to_string(path.with_file_name(format!(
            "{}.meta",
            path.file_name().unwrap().to_string_lossy()
        )))
        .unwrap();
        let editor =
            format!("        CPU: {cpu}\n        DefaultValueInitialized: true\n        OS: {os}");
        assert!(meta.contains(&editor), "{plugin}: {meta}");
        for other in ["Linux64", "Win64", "OSXUniversal"] {
            let on = other == player;
            let enabled = format!(
                "      Standalone: {other}\n    second:\n      enabled: {}\n      settings:\n        CPU: {}",
                u8::from(on),
                if on { cpu } else { "None" }
            );
            assert!(meta.contains(&enabled), "{plugin} for {other}: {meta}");
            let exclude = format!("Exclude {other}: {}", u8::from(!on));
            assert!(meta.contains(&exclude), "{plugin}: {meta}");
        }
    }
    let asmdef = std::fs::read_to_string(unity.join("Runtime/Troupe.Runtime.asmdef")).unwrap();
    let asmdef: serde_json::Value = serde_json::from_str(&asmdef).unwrap();
    assert_eq!(
        asmdef["includePlatforms"],
        serde_json::json!(["Editor", "LinuxStandalone64", "WindowsStandalone64"])
    );
    let mut guids = Vec::new();
    let mut stack = vec![unity.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "meta") {
                let text = std::fs::read_to_string(&path).unwrap();
                guids.push(text.lines().nth(1).unwrap().to_owned());
            }
        }
    }
    let unique: std::collections::BTreeSet<&String> = guids.iter().collect();
    assert_eq!(unique.len(), guids.len(), "a GUID is used twice: {guids:?}");
    // package.json, README.md, Runtime/ with Troupe.cs and the asmdef, Plugins/ with its two
    // folders and three plugins.
    assert_eq!(guids.len(), 11, "{guids:?}");
}
