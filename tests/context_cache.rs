//! The paged context cache troupe owns (`src/armflow/kv_cache.rs`) and the attention it runs
//! over it (`src/armflow/context.rs`): streams at very different history lengths stepped in one
//! round equal the same streams stepped alone; a full cache keeps `<sos>` and the newest entries
//! in constant memory; a cache grown over many pages still equals a full recompute; and a bundle
//! of the one-graph context contract is refused with the command that re-exports it. (A step
//! failing after its context step, alone or batched, is `src/ffi/armflow/rollback_tests.rs`.)

mod common;

use common::*;
use troupe::{Model, ReactorOptions, Session};

fn options(seed: u64, capacity: Option<usize>) -> ReactorOptions {
    ReactorOptions {
        seed,
        context_capacity: capacity,
        ..Default::default()
    }
}

#[test]
fn streams_at_mixed_history_lengths_step_together_as_they_do_alone() {
    let m = model();
    let actor = actor();
    let d = m.frame_dim();
    let flat = actor.as_slice().unwrap();
    // Warm each pair of twins to its own length (1, 9, 30 and 44 tokens; capacity 5 wraps
    // its ring), then step all of them in one round per token, against their twins alone.
    let warm = [4usize, 36, 120, 176];
    let capacities = [None, Some(5), None, Some(1000)];
    let make = |c| m.session(options(11, c)).unwrap();
    let mut together: Vec<Session> = capacities.iter().map(|&c| make(c)).collect();
    let mut alone: Vec<Session> = capacities.iter().map(|&c| make(c)).collect();
    for ((a, b), &w) in together.iter_mut().zip(&mut alone).zip(&warm) {
        a.step_flat(&flat[..w * d]).unwrap();
        b.step_flat(&flat[..w * d]).unwrap();
    }
    let lengths: Vec<usize> = together.iter().map(|s| s.context_len()).collect();
    assert_eq!(lengths, [1, 5, 30, 44], "every stream at its own length");
    let mut worst = 0f32;
    for token in 0..4 {
        let part = &flat[(token * 4) * d..(token * 4 + 4) * d];
        let mut refs: Vec<&mut Session> = together.iter_mut().collect();
        let parts = vec![part; refs.len()];
        let batched = troupe::step_sessions(&mut refs, &parts).unwrap();
        for (out, s) in batched.iter().zip(&mut alone) {
            let own = s.step_flat(part).unwrap();
            let (x, y) = (
                out.frames.as_slice().unwrap(),
                own.frames.as_slice().unwrap(),
            );
            worst = worst.max(max_abs_diff(x, y));
            for (x, y) in out.tokens.iter().zip(&own.tokens) {
                worst = worst.max(max_abs_diff(&x.context, &y.context));
            }
        }
    }
    println!("mixed lengths, batched vs alone: {worst:.2e}");
    assert!(worst <= 1e-5, "{worst}");
}

#[test]
fn a_bundle_of_the_one_graph_context_contract_is_refused_with_the_command_that_re_exports_it() {
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        let graphs = v["graphs"].as_object_mut().unwrap();
        graphs.remove("context_layers").unwrap();
        graphs.insert(
            "context_step".into(),
            serde_json::json!({"file": "context_step.onnx", "inputs": [], "outputs": []}),
        );
    });
    let err = Model::load(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("context_step") && err.contains("python3 onnx/cli.py armflow export"),
        "{err}"
    );
}

#[test]
fn a_full_cache_keeps_its_capacity_in_constant_memory() {
    let mut s = model().session(options(1, Some(6))).unwrap();
    let actor = actor();
    run_chunked(&mut s, &actor, 4);
    let (len, bytes) = (s.context_len(), s.memory_bytes());
    assert_eq!(len, 6);
    // A cache that grew with the stream would add 768 bytes per token (3 layers, keys and
    // values, 32 floats); buffered frames move by a few hundred bytes between calls.
    for _ in 0..3 {
        run_chunked(&mut s, &actor, 4);
        assert_eq!(s.context_len(), 6);
        assert!(
            s.memory_bytes().abs_diff(bytes) < 4096,
            "{} vs {bytes}",
            s.memory_bytes()
        );
    }
    assert!(s.tokens_generated() >= 4 * 48);
}

#[test]
fn a_cache_grown_past_its_first_slots_equals_a_full_recompute() {
    // 160 tokens with every one kept: the cache holds them in 10 pages.
    let m = model();
    let mut s = m.session(options(2, Some(1000))).unwrap();
    let actor = actor();
    let mut tokens = Vec::new();
    let mut small = 0;
    for round in 0..4 {
        let (_, t) = run_chunked(&mut s, &actor, 8);
        tokens.extend(t);
        if round == 1 {
            small = s.memory_bytes();
        }
    }
    let tokens = &tokens[..160.min(tokens.len())];
    assert!(s.context_len() >= 160 && s.memory_bytes() > small);
    // The context of token j sees <sos> and the pairs of tokens 0..j.
    let last = tokens.len() - 1;
    let pairs: Vec<f32> = tokens[..last]
        .iter()
        .flat_map(|t| t.actor_latent.iter().chain(&t.reactor_latent).copied())
        .collect();
    let full = m
        .armflow()
        .unwrap()
        .recompute_context(None, &pairs)
        .unwrap();
    let diff = max_abs_diff(&full, &tokens[last].context);
    println!("token {last}: cached vs recomputed context {diff:.2e}");
    assert!(diff <= 1e-5, "{diff}");
}
