//! MAGNet's sampling reference (`onnx/troupe_onnx/magnet`), the ground truth the Rust sampler
//! will be held to, checked on its own without torch (`onnx/tests/test_magnet.py`): the
//! schedule's test vector, the level tables, the released matrices' shapes, every released
//! configuration's network calls per run, and each task's invariants, against the numbers of
//! `docs/spec/magnet.md`.

mod common;

#[test]
fn the_magnet_reference_sampler_matches_its_specification() {
    let (ok, text) = common::run_python(&["-m", "pytest", "-q", "onnx/tests/test_magnet.py"], &[]);
    assert!(
        ok && text.contains("34 passed") && !text.contains("skipped"),
        "{text}"
    );
}
