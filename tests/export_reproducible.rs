//! The committed tiny bundle is exactly what `onnx/export.py --preset tiny --golden` produces.
//!
//! Needs Python with torch and onnx. CI does not install torch (about 4 GB); where it is missing
//! this test prints why it did not run and passes.

use std::path::Path;
use std::process::Command;

fn python() -> &'static str {
    if Command::new("python3").arg("--version").output().is_ok() {
        "python3"
    } else {
        "python"
    }
}

#[test]
fn committed_tiny_bundle_is_reproducible_from_the_exporter() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let probe = Command::new(python())
        .args(["-c", "import torch, onnx"])
        .output();
    match probe {
        Ok(out) if out.status.success() => {}
        _ => {
            println!("SKIPPED committed_tiny_bundle_is_reproducible_from_the_exporter: python with torch and onnx is not installed");
            return;
        }
    }
    let out = Command::new(python())
        .current_dir(root)
        .args([
            "onnx/export.py",
            "--preset",
            "tiny",
            "--check",
            "onnx/armflow-tiny",
        ])
        .output()
        .expect("run the exporter");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "re-export differs from the committed bundle:\n{text}"
    );
    assert!(text.contains("reproducible"), "{text}");
}
