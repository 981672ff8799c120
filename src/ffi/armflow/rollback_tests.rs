//! A step that fails after its context step has written the caches (here: the caller's output
//! room, which the C ABI's `troupe_session_step` and `troupe_sessions_step` pass and troupe
//! checks last) leaves every session exactly as it was, alone or batched, with full rings whose
//! oldest entries the failed step overwrote.

use std::path::Path;

use crate::family::session::step_sessions_bounded;
use crate::{Model, SessionOptions};

fn tiny() -> Model {
    Model::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-tiny")).unwrap()
}

/// Smooth actor frames `[from, to)`, row-major.
fn frames(from: usize, to: usize, dim: usize) -> Vec<f32> {
    (from * dim..to * dim)
        .map(|i| ((i % dim) as f32 * 0.3 + (i / dim) as f32 * 0.05).sin())
        .collect()
}

#[test]
fn a_step_failing_after_its_context_step_leaves_full_caches_as_they_were() {
    let m = tiny();
    let d = m.frame_dim();
    let session = |seed, capacity| {
        m.session(SessionOptions {
            seed,
            context_capacity: capacity,
            ..Default::default()
        })
        .unwrap()
    };
    let (mut a, mut b) = (session(4, Some(4)), session(5, None));
    let (mut twin_a, mut twin_b) = (session(4, Some(4)), session(5, None));
    for s in [&mut a, &mut b, &mut twin_a, &mut twin_b] {
        s.step_flat(&frames(0, 48, d)).unwrap();
    }
    let next = frames(48, 52, d);
    let err = step_sessions_bounded(&mut [&mut a, &mut b], &[&next, &next], &[4, 0]).unwrap_err();
    assert!(err.to_string().contains("session 1"), "{err}");
    let err = a.step_bounded(&next, 0).unwrap_err();
    assert!(err.to_string().contains("output holds 0"), "{err}");
    assert_eq!((a.tokens_generated(), a.context_len()), (12, 4));
    assert_eq!(b.context_len(), 12);
    let rest = frames(48, 120, d);
    for (s, twin) in [(&mut a, &mut twin_a), (&mut b, &mut twin_b)] {
        let (got, want) = (s.step_flat(&rest).unwrap(), twin.step_flat(&rest).unwrap());
        assert_eq!(
            got.frames, want.frames,
            "bit for bit after the failed steps"
        );
    }
}
