//! The context cache troupe owns (`src/armflow/kv_cache.rs`): a bundle whose context step
//! returns only the new entries and one exported before, whose step returns the whole cache,
//! give the same streams alone and batched; a full cache keeps `<sos>` and the newest entries in
//! constant memory; and a cache past its first allocation still equals a full recompute. (A step
//! failing after its context step, alone or batched, is `src/armflow/session/tests.rs`.)

mod common;

use common::*;
use troupe::armflow::step_reactors;
use troupe::{Model, Reactor, ReactorOptions};

/// The tiny bundle with the context step it had before the runtime owned the cache
/// (`present_*` outputs, `[B, heads, P+S, head_dim]`; same weights), and its manifest as then.
fn whole_cache_bundle() -> tempfile::TempDir {
    let dir = bundle_copy();
    std::fs::copy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/legacy/armflow-tiny-context_step.onnx"),
        dir.path().join("context_step.onnx"),
    )
    .unwrap();
    edit_manifest(dir.path(), |v| {
        let context = v["context"].as_object_mut().unwrap();
        assert_eq!(context.remove("step_returns").unwrap(), "new_entries");
        for out in v["graphs"]["context_step"]["outputs"]
            .as_array_mut()
            .unwrap()
            .iter_mut()
            .skip(1)
        {
            let name = out["name"].as_str().unwrap().replace("new_", "present_");
            out["name"] = name.into();
            out["shape"][2] = "P+S".into();
        }
    });
    dir
}

fn options(seed: u64, capacity: Option<usize>) -> ReactorOptions {
    ReactorOptions {
        seed,
        context_capacity: capacity,
        ..Default::default()
    }
}

/// Frames and contexts of a stream over the golden actor clip, in chunks of 7 frames.
fn stream(session: &mut Reactor) -> (Vec<f32>, Vec<f32>) {
    let (frames, tokens) = run_chunked(session, &actor(), 7);
    (frames, tokens.into_iter().flat_map(|t| t.context).collect())
}

#[test]
fn bundles_whose_step_returns_the_whole_cache_stream_as_before() {
    let dir = whole_cache_bundle();
    let old = Model::load(dir.path()).unwrap();
    let new = model();
    // Unbounded, and small enough that the ring wraps many times over the clip's 48 tokens.
    for capacity in [None, Some(5), Some(2)] {
        let (a, b) = (
            stream(
                &mut old
                    .armflow()
                    .unwrap()
                    .reactor(options(3, capacity))
                    .unwrap(),
            ),
            stream(
                &mut new
                    .armflow()
                    .unwrap()
                    .reactor(options(3, capacity))
                    .unwrap(),
            ),
        );
        let (frames, contexts) = (max_abs_diff(&a.0, &b.0), max_abs_diff(&a.1, &b.1));
        println!("capacity {capacity:?}: frames {frames:.2e}, contexts {contexts:.2e}");
        assert!(frames <= 1e-5 && contexts <= 1e-5, "capacity {capacity:?}");
    }
    // Batched: caches of different sizes padded into one call, new entries taken from the end
    // of each padded row.
    let capacities = [Some(3), None, Some(7)];
    let mut old_sessions: Vec<Reactor> = capacities
        .iter()
        .map(|&c| old.armflow().unwrap().reactor(options(9, c)).unwrap())
        .collect();
    let actor = actor();
    let flat = actor.as_slice().unwrap();
    let chunk = 12 * new.frame_dim();
    let mut batched = vec![Vec::new(); capacities.len()];
    for part in flat.chunks(chunk) {
        let mut refs: Vec<&mut Reactor> = old_sessions.iter_mut().collect();
        let outs = step_reactors(&mut refs, &vec![part; capacities.len()]).unwrap();
        for (all, out) in batched.iter_mut().zip(outs) {
            all.extend(out.frames.iter().copied());
        }
    }
    for (i, &c) in capacities.iter().enumerate() {
        let alone = run_chunked(
            &mut new.armflow().unwrap().reactor(options(9, c)).unwrap(),
            &actor,
            12,
        )
        .0;
        let diff = max_abs_diff(&batched[i], &alone);
        assert!(diff <= 1e-5, "session {i}: {diff}");
    }
}

#[test]
fn a_full_cache_keeps_its_capacity_in_constant_memory() {
    let mut s = model()
        .armflow()
        .unwrap()
        .reactor(options(1, Some(6)))
        .unwrap();
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
    // 160 tokens with every one kept: the cache allocates 16 slots and doubles up to 256.
    let m = model();
    let mut s = m
        .armflow()
        .unwrap()
        .reactor(options(2, Some(1000)))
        .unwrap();
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
