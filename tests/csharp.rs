//! The C# binding (`bindings/csharp/Troupe.cs`) through the real shared library under Mono:
//! `bindings/csharp/tests/TroupeTests.cs` streams the CMU clip through the demo model and checks
//! every misuse it can think of (each refused with its exception, the session left as it was);
//! here its stream is compared with the same stream run through the Rust API. (The Unity
//! package that `scripts/install.sh --unity-package` writes is checked by `tests/install.rs`.)
//!
//! `scripts/test.sh` installs Mono (`mono-mcs`, `mono-runtime`); without it this test fails
//! under CI and is a counted skip elsewhere.

mod common;

use std::path::Path;
use std::process::Command;

use ndarray::{s, Array3};
use troupe::motion::{JointsFormat, Units, UpAxis};
use troupe::{Model, ReactorOptions};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The demo model's `mirror` partner for the CMU clip, seed 7, one frame per call: what the C#
/// program must reproduce.
fn rust_stream(clip: &Array3<f32>) -> Vec<f32> {
    let model = Model::load(root().join("onnx/bundles/armflow-demo")).unwrap();
    let mut session = model
        .session(ReactorOptions {
            seed: 7,
            condition: Some(model.condition_for("mirror").unwrap()),
            ..Default::default()
        })
        .unwrap();
    session
        .set_joints_format(JointsFormat {
            units: Units::Meters,
            up: UpAxis::Z,
            fps: 120.0,
            ..Default::default()
        })
        .unwrap();
    let mut out = Vec::new();
    for t in 0..clip.dim().0 {
        for pose in session
            .step_joints(clip.slice(s![t..t + 1, .., ..]))
            .unwrap()
        {
            out.extend(pose.positions.iter().flatten());
        }
    }
    out
}

#[test]
fn csharp_binding_streams_like_rust_and_refuses_misuse() {
    if !common::tools_or_skip(
        "csharp_binding_streams_like_rust_and_refuses_misuse",
        &["mcs", "mono"],
        "mono-mcs mono-runtime",
    ) {
        return;
    }
    let libs = common::c_libraries();
    let scratch = tempfile::tempdir().unwrap();
    let exe = scratch.path().join("troupe-tests.exe");
    common::run_ok(
        Command::new("mcs")
            .arg("-warnaserror")
            .arg(format!("-out:{}", exe.display()))
            .arg(root().join("bindings/csharp/Troupe.cs"))
            .arg(root().join("bindings/csharp/tests/TroupeTests.cs"))
            .arg(root().join("bindings/csharp/tests/Npy.cs")),
    );
    let clip_path = root().join("tests/data/mocap/cmu-playground-120fps.npy");
    let out_path = scratch.path().join("partner.f32");
    let text = common::output_text(&common::run_ok(
        Command::new("mono")
            .arg(&exe)
            .arg(root().join("onnx/bundles/armflow-demo"))
            .arg(&clip_path)
            .arg(&out_path)
            .arg(root().join("onnx/bundles/armflow-tiny-interx"))
            .env("LD_LIBRARY_PATH", libs),
    ));
    assert!(text.contains("ALL PASSED"), "{text}");
    println!("{text}");

    let bytes = std::fs::read(&out_path).unwrap();
    let csharp: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let clip: Array3<f32> = ndarray_npy::read_npy(&clip_path).unwrap();
    let rust = rust_stream(&clip);
    assert_eq!(csharp.len(), rust.len(), "poses streamed");
    assert!(!rust.is_empty());
    let worst = csharp
        .iter()
        .zip(&rust)
        .map(|(a, b)| (a - b).abs())
        .fold(0f32, f32::max);
    println!(
        "C# against Rust: {} poses, largest difference {worst:e} m",
        rust.len() / 66
    );
    assert!(worst <= 1e-5, "C# and Rust differ by {worst}");
}

/// The Unity sample (`unity/Samples~/AnimatorPartner/TroupePartner.cs`) compiled against a stub
/// UnityEngine (`bindings/csharp/tests/UnityStub.cs`) and run under Mono by
/// `bindings/csharp/tests/UnitySampleTests.cs`: the demo model on the engine's clock at 20, 60 and
/// 144 jittered frames a second for 60 s each, the poses held bounded, the playback keeping pace
/// with the actor, the partner shown; and `PosePlayback`'s contract.
#[test]
fn unity_sample_plays_the_partner_on_the_engine_clock_at_20_60_and_144_fps() {
    let test = "unity_sample_plays_the_partner_on_the_engine_clock_at_20_60_and_144_fps";
    if !common::tools_or_skip(test, &["mcs", "mono"], "mono-mcs mono-runtime") {
        return;
    }
    let libs = common::c_libraries();
    let scratch = tempfile::tempdir().unwrap();
    let exe = scratch.path().join("unity-sample-tests.exe");
    common::run_ok(
        Command::new("mcs")
            .arg("-warnaserror")
            .arg(format!("-out:{}", exe.display()))
            .arg(root().join("bindings/csharp/Troupe.cs"))
            .arg(root().join("bindings/csharp/tests/UnityStub.cs"))
            .arg(root().join("unity/Samples~/AnimatorPartner/TroupePartner.cs"))
            .arg(root().join("bindings/csharp/tests/UnitySampleTests.cs"))
            .arg(root().join("bindings/csharp/tests/Npy.cs")),
    );
    // An Android APK's StreamingAssets, unpacked: the demo bundle as the one archive the sample
    // reads there (and, as a TextAsset, on every platform).
    let apk = scratch.path().join("apk");
    std::fs::create_dir_all(apk.join("assets")).unwrap();
    common::run_ok(
        Command::new("bash")
            .arg(root().join("scripts/bundle-tar.sh"))
            .arg(root().join("onnx/bundles/armflow-demo"))
            .arg(apk.join("assets/armflow-demo.tar")),
    );
    let text = common::output_text(&common::run_ok(
        Command::new("mono")
            .arg(&exe)
            .arg(root().join("onnx/bundles"))
            .arg(root().join("tests/data/mocap/cmu-playground-120fps.npy"))
            .arg(&apk)
            .env("LD_LIBRARY_PATH", libs),
    ));
    println!("{text}");
    assert!(text.contains("ALL PASSED"), "{text}");
    for fps in ["20 fps", "60 fps", "144 fps"] {
        assert!(text.contains(&format!("{fps}: ")), "{text}");
    }
}

/// Every C# sample of the README and the docs compiles with the binding (warnings as errors) and
/// runs under Mono against the library (`tests/common/samples.rs`: its setup and the sample as
/// `Main`'s body), from the repository root, where its paths lead.
#[test]
fn csharp_samples_of_the_docs_run() {
    if !common::tools_or_skip(
        "csharp_samples_of_the_docs_run",
        &["mcs", "mono"],
        "mono-mcs mono-runtime",
    ) {
        return;
    }
    let samples = common::samples::samples(root(), "csharp");
    assert!(samples.len() >= 2, "{samples:?}");
    let scratch = tempfile::tempdir().unwrap();
    for (i, sample) in samples.iter().enumerate() {
        assert!(sample.skip.is_none(), "{sample:?}: a C# sample is run");
        let source = scratch.path().join(format!("Sample{i}.cs"));
        std::fs::write(
            &source,
            format!(
                "static class Sample {{\n    static void Main() {{\n{}{}    }}\n}}\n",
                sample.setup, sample.code
            ),
        )
        .unwrap();
        let exe = scratch.path().join(format!("sample{i}.exe"));
        common::run_ok(
            Command::new("mcs")
                .arg("-warnaserror")
                // A sample shows what a call returns without using it.
                .arg("-nowarn:219")
                .arg(format!("-out:{}", exe.display()))
                .arg(root().join("bindings/csharp/Troupe.cs"))
                .arg(&source),
        );
        let out = Command::new("mono")
            .arg(&exe)
            .current_dir(root())
            .env("LD_LIBRARY_PATH", common::c_libraries())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "C# sample {}:{}: {}{}",
            sample.file,
            sample.line,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
