//! The committed bundles are exactly what their exporters produce:
//! `onnx/cli.py armflow export --preset tiny` (and `tiny-interhuman`, `tiny-interx`, the
//! official-layout parity bundles) and `onnx/cli.py umf export --preset tiny | tiny-temporal`,
//! goldens included.
//!
//! Needs Python with torch and onnx. CI does not install torch (about 4 GB); where it is missing
//! this test prints why it did not run and passes.
//!
//! torch's CPU kernels are pinned to AVX2, the instruction set the goldens were exported with: on
//! an AVX-512 machine the default kernels round differently and the goldens drift by up to 5e-6
//! (the ONNX files stay identical).

mod common;

use std::process::Command;

use common::{python_command, run_python};

/// Selects torch's AVX2 kernels on any x86 machine (ignored elsewhere).
const AVX2_KERNELS: [(&str, &str); 3] = [
    ("ATEN_CPU_CAPABILITY", "avx2"),
    ("MKL_ENABLE_INSTRUCTIONS", "AVX2"),
    ("ONEDNN_MAX_CPU_ISA", "AVX2"),
];

/// Whether python can import torch and onnx; prints why a test is skipped when not.
fn torch_available(test: &str) -> bool {
    let probe = Command::new(python_command())
        .args(["-c", "import torch, onnx"])
        .output();
    let ok = matches!(probe, Ok(out) if out.status.success());
    if !ok {
        println!("SKIPPED {test}: python with torch and onnx is not installed");
    }
    ok
}

/// Runs `onnx/cli.py family export --preset preset --check dir` and asserts the re-export is
/// byte-identical.
fn check(family: &str, preset: &str, dir: &str) {
    let (ok, text) = run_python(
        &[
            "onnx/cli.py",
            family,
            "export",
            "--preset",
            preset,
            "--check",
            dir,
        ],
        &AVX2_KERNELS,
    );
    assert!(
        ok,
        "re-export differs from the committed bundle {dir}:\n{text}"
    );
    assert!(text.contains("reproducible"), "{text}");
}

#[test]
fn committed_tiny_bundle_is_reproducible_from_the_exporter() {
    if torch_available("committed_tiny_bundle_is_reproducible_from_the_exporter") {
        check("armflow", "tiny", "onnx/bundles/armflow-tiny");
    }
}

#[test]
fn committed_umf_bundles_are_reproducible_from_the_exporter() {
    if torch_available("committed_umf_bundles_are_reproducible_from_the_exporter") {
        check("umf", "tiny", "onnx/bundles/umf-tiny");
        check("umf", "tiny-temporal", "onnx/bundles/umf-tiny-temporal");
    }
}

#[test]
fn committed_official_layout_bundles_are_reproducible_from_the_exporter() {
    if torch_available("committed_official_layout_bundles_are_reproducible_from_the_exporter") {
        check(
            "armflow",
            "tiny-interhuman",
            "onnx/bundles/armflow-tiny-interhuman",
        );
        check("armflow", "tiny-interx", "onnx/bundles/armflow-tiny-interx");
    }
}

/// The official-checkpoint path of ARMFlow and UMF (`onnx/tests/test_official.py`): a checkpoint
/// in the official layout exports to exactly the committed parity bundles; missing, unexpected,
/// mis-shaped, inconsistent and non-finite tensors are rejected by name; the text branches
/// equal torch's encoder; UMF's null condition is the empty prompt through CLIP.
#[test]
fn official_checkpoints_load_strictly() {
    if torch_available("official_checkpoints_load_strictly") {
        let (ok, text) = run_python(
            &["-m", "pytest", "-q", "onnx/tests/test_official.py"],
            &AVX2_KERNELS,
        );
        assert!(ok, "{text}");
        assert!(text.contains("15 passed"), "{text}");
    }
}
