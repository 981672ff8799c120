//! The C ABI as users meet it: the header compiled alone (C99 and C++17), the C smoke test
//! (`tests/c/smoke.c`) compiled as C99 and as C++17 with `-Wall -Wextra -Werror -pedantic` and
//! linked against the real cdylib and the staticlib, the C++ wrapper compiled with
//! `-fno-exceptions`, and the C smoke test under valgrind (which `scripts/test.sh` installs; CI
//! fails without it, elsewhere it is a counted skip).
//!
//! The libraries come from `common::c_libraries` (`cargo build --lib --features testing`, which
//! adds the `troupe_testing_panic` hook used to check panic -> PANIC -> POISONED -> reset -> OK).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::c_libraries as libs;
use common::c_programs::{
    arflow_args, c_programs, clip_args, compile, group_args, magnet_args, motion_args, rig_args,
    root, run, scratch, slow_tests, smoke_args, threads_args,
};

fn shared_link() -> Vec<String> {
    let dir = libs().display().to_string();
    vec![
        format!("-L{dir}"),
        "-ltroupe".into(),
        format!("-Wl,-rpath,{dir}"),
        "-lm".into(),
    ]
}

fn static_link() -> Vec<String> {
    // The system libraries Rust's std needs on Linux (`--print native-static-libs`).
    let lib = libs().join("libtroupe.a").display().to_string();
    [
        lib.as_str(),
        "-lgcc_s",
        "-lutil",
        "-lrt",
        "-lpthread",
        "-lm",
        "-ldl",
        "-lc",
    ]
    .map(String::from)
    .to_vec()
}

#[test]
fn header_compiles_alone_as_c99_and_cpp17() {
    let src = root().join("tests/c/header_alone.c");
    compile("cc", &["-std=c99"], &[&src], &shared_link(), "header_c");
    compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "header_cpp",
    );
}

#[test]
fn c_smoke_against_the_cdylib_as_c99() {
    let bin = compile(
        "cc",
        &["-std=c99", "-DTROUPE_TESTING"],
        &[&root().join("tests/c/smoke.c")],
        &shared_link(),
        "smoke_c",
    );
    let [dir, archive] = smoke_args();
    println!("{}", run(&[], &bin, &[&dir, &archive]));
}

#[test]
fn c_smoke_against_the_cdylib_as_cpp17() {
    let bin = compile(
        "c++",
        &["-std=c++17", "-x", "c++", "-DTROUPE_TESTING"],
        &[&root().join("tests/c/smoke.c")],
        &shared_link(),
        "smoke_cpp",
    );
    let [dir, archive] = smoke_args();
    run(&[], &bin, &[&dir, &archive]);
}

#[test]
fn c_smoke_against_the_staticlib() {
    let bin = compile(
        "cc",
        &["-std=c99", "-DTROUPE_TESTING"],
        &[&root().join("tests/c/smoke.c")],
        &static_link(),
        "smoke_static",
    );
    let [dir, archive] = smoke_args();
    run(&[], &bin, &[&dir, &archive]);
}

/// `tests/cpp/wrapper.cpp`'s arguments: armflow, umf, a scratch folder, the demo model and its
/// int8 copy, magnet, arflow, and an ARMFlow bundle with the official clip.
fn wrapper_args() -> Vec<PathBuf> {
    let [umf, armflow] = group_args();
    let mut args = vec![armflow, umf, scratch().to_path_buf()];
    args.extend(
        [
            "armflow-demo",
            "armflow-demo-int8",
            "magnet-tiny",
            "arflow-tiny",
            "armflow-tiny-interhuman",
        ]
        .map(|b| root().join("onnx/bundles").join(b)),
    );
    args
}

#[test]
fn cpp_wrapper_without_exceptions() {
    let bin = compile(
        "c++",
        &["-std=c++17", "-fno-exceptions"],
        &[&root().join("tests/cpp/wrapper.cpp")],
        &shared_link(),
        "wrapper_cpp",
    );
    let args = wrapper_args();
    let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
    println!("{}", run(&[], &bin, &args));
}

#[test]
fn cpp_wrapper_with_its_exception_helpers() {
    let bin = compile(
        "c++",
        &["-std=c++17", "-DTROUPE_CPP_EXCEPTIONS"],
        &[&root().join("tests/cpp/wrapper.cpp")],
        &shared_link(),
        "wrapper_cpp_exceptions",
    );
    let args = wrapper_args();
    let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
    run(&[], &bin, &args);
}

/// No leak and no invalid access under valgrind: the smoke test always (about a minute on 2
/// cores), every C test with `TROUPE_SLOW_TESTS=1` (seven more). `scripts/test.sh` installs
/// valgrind; without it this test fails under CI (`CI` set) and elsewhere records a skip that
/// the suite's summary counts. `tests/c/valgrind.supp` suppresses only tract's
/// uninitialised-padding comparisons at model load (explained there).
#[test]
fn c_tests_under_valgrind() {
    if !common::tools_or_skip("c_tests_under_valgrind", &["valgrind"], "valgrind") {
        return;
    }
    let supp = format!(
        "--suppressions={}",
        root().join("tests/c/valgrind.supp").display()
    );
    let valgrind = [
        "valgrind",
        &supp,
        "--error-exitcode=3",
        "--leak-check=full",
        "--errors-for-leak-kinds=definite,indirect",
        "--show-leak-kinds=definite,indirect",
    ];
    let programs = c_programs();
    let chosen = if slow_tests() {
        &programs[..]
    } else {
        &programs[..1]
    };
    for (name, args, flags) in chosen {
        let bin = compile_program(name, &[&["-g"], &flags[..]].concat(), "valgrind");
        let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
        let text = run(&valgrind, &bin, &args);
        assert!(text.contains("ERROR SUMMARY: 0 errors"), "{name}: {text}");
    }
}

/// `tests/c/NAME.c` compiled as C99 with `flags` into `NAME_SUFFIX`, linked to the cdylib.
fn compile_program(name: &str, flags: &[&str], suffix: &str) -> PathBuf {
    compile(
        "cc",
        &[&["-std=c99"], flags].concat(),
        &[&root().join(format!("tests/c/{name}.c"))],
        &shared_link(),
        &format!("{name}_{suffix}"),
    )
}

/// Every C test built with AddressSanitizer (LeakSanitizer included) and
/// UndefinedBehaviorSanitizer, any report fatal. The programs print the sanitizer they were
/// built with, so the log shows it ran.
#[test]
fn c_tests_under_address_and_undefined_behaviour_sanitizers() {
    std::fs::create_dir_all(scratch().join("viewer-sanitized")).unwrap();
    let sanitizers = [
        "-g",
        "-fsanitize=address,undefined",
        "-fno-sanitize-recover=all",
        "-fno-omit-frame-pointer",
    ];
    let env = [
        "env",
        "ASAN_OPTIONS=detect_leaks=1:exitcode=23",
        "UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1",
    ];
    for (name, args, flags) in c_programs() {
        let bin = compile_program(name, &[&sanitizers[..], flags].concat(), "asan");
        let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
        let text = run(&env, &bin, &args);
        assert!(
            text.contains("sanitizer: address"),
            "{name} was not instrumented:\n{text}"
        );
        println!(
            "{name} under ASan + UBSan: {}",
            text.lines().last().unwrap_or("")
        );
    }
}

/// One model shared by 8 threads x 8 sessions (bit-identical to each alone), two threads racing
/// on one session, a batched call and a joint stream (TROUPE_ERR_BUSY, never a race), and the
/// limits at the C boundary.
#[test]
fn c_threads_share_a_model_and_racing_calls_are_refused() {
    let bin = compile(
        "cc",
        &["-std=c99", "-pthread"],
        &[&root().join("tests/c/threads.c")],
        &shared_link(),
        "threads_c",
    );
    let [dir] = threads_args();
    println!("{}", run(&[], &bin, &[&dir]));
}

/// The same program under ThreadSanitizer, long form only (`TROUPE_SLOW_TESTS=1`): the library
/// and every dependency, std included, rebuilt with `-Zsanitizer=thread` (nightly toolchain with
/// `rust-src`, about 7 minutes on 2 cores, in `target/tsan`), the program compiled with gcc's
/// `-fsanitize=thread` and linked to the runtime Rust ships (gcc 12's lacks entry points rustc's
/// instrumentation calls). A deliberately racy control program must be reported first, so a
/// clean run means the sanitizer was watching.
#[test]
fn c_threads_under_thread_sanitizer() {
    if !slow_tests() {
        common::skip(
            "c_threads_under_thread_sanitizer",
            "runs in the long form (TROUPE_SLOW_TESTS=1; needs the nightly toolchain)",
        );
        return;
    }
    let rustc = |args: &[&str]| {
        let out = Command::new("rustc")
            .arg("+nightly")
            .args(args)
            .output()
            .expect("run rustc +nightly");
        assert!(
            out.status.success(),
            "the ThreadSanitizer test needs the nightly toolchain (rustup toolchain install \
             nightly --component rust-src): {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    let host = rustc(&["-vV"])
        .lines()
        .find_map(|l| l.strip_prefix("host: ").map(str::to_owned))
        .unwrap();
    let sysroot = PathBuf::from(rustc(&["--print", "sysroot"]).trim());
    let runtime = sysroot.join(format!("lib/rustlib/{host}/lib/librustc-nightly_rt.tsan.a"));
    assert!(
        runtime.is_file(),
        "no ThreadSanitizer runtime at {}",
        runtime.display()
    );

    let target_dir = root().join("target/tsan");
    let status = Command::new("cargo")
        .current_dir(root())
        .args(["+nightly", "build", "-Zbuild-std", "--release", "--lib"])
        .args(["--target", &host, "--target-dir"])
        .arg(&target_dir)
        .env(
            "RUSTFLAGS",
            "-Zsanitizer=thread -Cdebuginfo=line-tables-only",
        )
        .env_remove("RUSTC")
        .env_remove("RUSTUP_TOOLCHAIN")
        // rustc links the sanitizer's runtime itself: the test command's glibc 2.28 linker
        // (scripts/zig-cc.sh) is for the shipped library, not this build.
        .env_remove("CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_LINKER")
        .status()
        .expect("run cargo +nightly");
    assert!(
        status.success(),
        "the ThreadSanitizer build of the library failed"
    );
    let lib_dir = target_dir.join(&host).join("release");

    // Compile instrumented, then link Rust's runtime whole (the program has no Rust code to pull
    // it in) and the instrumented library.
    let build = |name: &str| {
        let object = compile(
            "cc",
            &["-std=c99", "-pthread", "-g", "-fsanitize=thread", "-c"],
            &[&root().join(format!("tests/c/{name}.c"))],
            &[],
            &format!("{name}_tsan.o"),
        );
        let binary = scratch().join(format!("{name}_tsan"));
        let status = Command::new("cc")
            .arg(&object)
            .arg("-o")
            .arg(&binary)
            .arg("-Wl,--whole-archive")
            .arg(&runtime)
            .args(["-Wl,--no-whole-archive", "-rdynamic"])
            .arg(format!("-L{}", lib_dir.display()))
            .arg(format!("-Wl,-rpath,{}", lib_dir.display()))
            .args(["-ltroupe", "-lm", "-lpthread", "-ldl", "-lstdc++"])
            .status()
            .unwrap();
        assert!(
            status.success(),
            "linking {name} with ThreadSanitizer failed"
        );
        binary
    };
    // Any report ends the program with status 66.
    let options = "halt_on_error=1:exitcode=66";

    let control = Command::new(build("data_race"))
        .env("TSAN_OPTIONS", options)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&control.stderr);
    assert!(
        control.status.code() == Some(66) && report.contains("ThreadSanitizer: data race"),
        "the control race was not reported: {report}"
    );

    let text = run(
        // The library path first: cargo's LD_LIBRARY_PATH would otherwise load the ordinary,
        // uninstrumented library, whose synchronisation the sanitizer cannot see.
        &[
            "env",
            &format!("LD_LIBRARY_PATH={}", lib_dir.display()),
            &format!("TSAN_OPTIONS={options}"),
        ],
        &build("threads"),
        &[&threads_args()[0]],
    );
    assert!(
        text.contains("sanitizer: thread"),
        "not instrumented:\n{text}"
    );
    assert!(!text.contains("ThreadSanitizer"), "{text}");
    println!("threads under ThreadSanitizer:\n{text}");
}

/// Skeleton, joint positions to features and back, and streams through the header: round
/// trips, every bad input, as C99 and as C++17.
#[test]
fn c_motion_as_c99_and_cpp17() {
    let src = root().join("tests/c/motion.c");
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "motion_c");
    let [interhuman, interx, dir] = motion_args();
    println!("{}", run(&[], &c, &[&interhuman, &interx, &dir]));
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "motion_cpp",
    );
    run(&[], &cpp, &[&interhuman, &interx, &dir]);
}

/// Rigs from BVH and JSON, the streaming retargeter (bad input refused, state kept), glTF and
/// BVH files on a rig, through the header, as C99 and C++17.
#[test]
fn c_rig_as_c99_and_cpp17() {
    let src = root().join("tests/c/rig.c");
    let args = rig_args();
    let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "rig_c");
    println!("{}", run(&[], &c, &args));
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "rig_cpp",
    );
    run(&[], &cpp, &args);
}

/// Named conditions (the demo model's partner rules) and reduced-precision graphs through the
/// header, as C99 and C++17.
#[test]
fn c_condition_labels_as_c99_and_cpp17() {
    let src = root().join("tests/c/labels.c");
    let args = [
        root().join("onnx/bundles/armflow-demo"),
        root().join("onnx/bundles/armflow-tiny"),
        root().join("onnx/bundles/armflow-demo-int8"),
    ];
    let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "labels_c");
    println!("{}", run(&[], &c, &args));
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "labels_cpp",
    );
    run(&[], &cpp, &args);
}

/// The official clip loop and text branch through the header: parity with the reference,
/// seeded determinism, every bad input, as C99 and as C++17.
#[test]
fn c_clip_generation_as_c99_and_cpp17() {
    let src = root().join("tests/c/clip.c");
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "clip_c");
    let [official, streaming] = clip_args();
    println!("{}", run(&[], &c, &[&official, &streaming]));
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "clip_cpp",
    );
    run(&[], &cpp, &[&official, &streaming]);
}

/// UMF group generation through the header: seeded parity with the reference, injected noise,
/// every bad input, as C99 and as C++17.
#[test]
fn c_group_generation_as_c99_and_cpp17() {
    let src = root().join("tests/c/group.c");
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "group_c");
    let [umf, armflow] = group_args();
    println!("{}", run(&[], &c, &[&umf, &armflow]));
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "group_cpp",
    );
    run(&[], &cpp, &[&umf, &armflow]);
}

/// MAGNet generation through the header: the golden joint case (configuration as JSON) equals
/// the reference, a released configuration runs with options, every bad input is refused with
/// the output untouched; the live partner streams through `troupe_session_*` as the reference
/// stream does; as C99 and as C++17.
#[test]
fn c_magnet_generation_as_c99_and_cpp17() {
    println!("{}", c_and_cpp("magnet", &magnet_args()));
}

/// Session snapshots across processes: a stream saved by one process (C99) is restored by
/// another (C++17) and continues bit for bit, and the other way round; every bad input refused.
#[test]
fn c_snapshot_restored_in_another_process() {
    let src = root().join("tests/c/snapshot.c");
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "snapshot_c");
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "snapshot_cpp",
    );
    for (saver, resumer) in [(&c, &cpp), (&cpp, &c)] {
        let args = |run: &str| common::c_programs::snapshot_args(run);
        let save = args("save");
        let resume = args("resume");
        println!(
            "{}",
            run(
                &[],
                saver,
                &save.iter().map(PathBuf::as_path).collect::<Vec<_>>()
            )
        );
        let text = run(
            &[],
            resumer,
            &resume.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        );
        assert!(text.contains("equal the uninterrupted stream's"), "{text}");
        println!("{text}");
    }
}

/// Compiles `tests/c/<name>.c` as C99 and as C++17 against the cdylib and runs both with `args`;
/// the C run's output.
fn c_and_cpp(name: &str, args: &[PathBuf]) -> String {
    let src = root().join(format!("tests/c/{name}.c"));
    let args: Vec<&Path> = args.iter().map(PathBuf::as_path).collect();
    let c = compile(
        "cc",
        &["-std=c99"],
        &[&src],
        &shared_link(),
        &format!("{name}_c"),
    );
    let out = run(&[], &c, &args);
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        &format!("{name}_cpp"),
    );
    run(&[], &cpp, &args);
    out
}

/// ARFlow generation, its stream and the penetration metrics through the header: the golden
/// Euler and guided cases equal the reference, the online variant streams through
/// `troupe_session_*` as the whole clip, the ARMFlow guard's settings, every bad input refused
/// with the output untouched; as C99 and as C++17.
#[test]
fn c_arflow_generation_as_c99_and_cpp17() {
    println!("{}", c_and_cpp("arflow", &arflow_args()));
}

/// The C MAGNet example compiles with the strict flags and runs a released configuration on the
/// tiny bundle's golden clip.
#[test]
fn c_magnet_example_runs() {
    let bin = compile(
        "cc",
        &["-std=c99", "-O2"],
        &[&root().join("examples/c/magnet.c")],
        &shared_link(),
        "magnet_example_c",
    );
    let dir = root().join("onnx/bundles/magnet-tiny");
    let out = Command::new(&bin)
        .arg(&dir)
        .arg("dd100")
        .arg(dir.join("golden/frames.npy"))
        .args(["1", "2"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("1 samples x 208 frames x 2 people") && text.contains("non-finite values: 0"),
        "{text}"
    );
}

/// The C streaming demo compiles with the strict flags and runs on the tiny bundle.
#[test]
fn c_streaming_demo_runs() {
    let bin = compile(
        "cc",
        &["-std=c99", "-O2"],
        &[&root().join("examples/c/stream.c")],
        &shared_link(),
        "stream_c",
    );
    // Runs the demo from the repository root; its stdout.
    let demo = |args: &[&str]| -> String {
        let out = Command::new(&bin)
            .current_dir(root())
            .args(args)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{text}{stderr}");
        text
    };
    let npy = scratch().join("reactor_c.npy");
    let text = demo(&[
        "onnx/bundles/armflow-tiny",
        "200",
        "3",
        npy.to_str().unwrap(),
        "tests/data/mocap/cmu-playground-120fps.npy",
    ]);
    // 200 frames at 120 fps: 50 at 30 fps, 49 feature frames, 12 tokens of 4 reactor frames.
    assert!(
        text.contains("200 actor frames") && text.contains("48 reactor frames"),
        "{text}"
    );
    assert!(text.contains("real-time factor"), "{text}");
    let frames: ndarray::Array3<f32> = ndarray_npy::read_npy(&npy).unwrap();
    assert_eq!(frames.dim(), (48, 22, 3));
    let html = std::fs::read_to_string(npy.with_extension("html")).unwrap();
    assert!(html.contains("reactor") && html.contains("actor"));
    let gif = std::fs::read(npy.with_extension("gif")).unwrap();
    assert_eq!(&gif[..3], b"GIF");

    // The trained demo model with its defaults (its first rule, the whole default clip, from the
    // repository root), and the error against the rule's partner.
    let out = scratch().join("demo_c.npy");
    let text = demo(&["onnx/bundles/armflow-demo", "0", "1", out.to_str().unwrap()]);
    assert!(
        text.contains("bundle onnx/bundles/armflow-demo") && text.contains("960 actor frames"),
        "{text}"
    );
    assert!(
        text.contains("the mirror rule's partner vs the reactor: "),
        "{text}"
    );
}

/// The viewer through the header: both pictures written, every bad input refused with nothing
/// written, as C99 and as C++17.
#[test]
fn c_viewer_as_c99_and_cpp17() {
    let src = root().join("tests/c/viewer.c");
    let dir = scratch().join("viewer");
    std::fs::create_dir_all(&dir).unwrap();
    let c = compile("cc", &["-std=c99"], &[&src], &shared_link(), "viewer_c");
    println!("{}", run(&[], &c, &[&dir]));
    let cpp = compile(
        "c++",
        &["-std=c++17", "-x", "c++"],
        &[&src],
        &shared_link(),
        "viewer_cpp",
    );
    run(&[], &cpp, &[&dir]);
}

/// Every C sample of the README and the docs compiles as C99 with every warning an error and
/// runs against the library (`tests/common/samples.rs`: its setup at file scope, the sample as
/// `main`'s body), from the repository root, where its paths lead.
#[test]
fn c_samples_of_the_docs_run() {
    let samples = common::samples::samples(root(), "c");
    assert!(!samples.is_empty());
    for (i, sample) in samples.iter().enumerate() {
        assert!(sample.skip.is_none(), "{sample:?}: a C sample is run");
        let source = scratch().join(format!("sample_{i}.c"));
        std::fs::write(
            &source,
            format!(
                "{}int main(void) {{\n{}    return 0;\n}}\n",
                sample.setup, sample.code
            ),
        )
        .unwrap();
        let bin = compile(
            "cc",
            &["-std=c99"],
            &[&source],
            &shared_link(),
            &format!("sample_{i}"),
        );
        let out = Command::new(&bin).current_dir(root()).output().unwrap();
        assert!(
            out.status.success() && out.stderr.is_empty(),
            "C sample {}:{}: {}",
            sample.file,
            sample.line,
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
