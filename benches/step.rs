//! The Rust-side benchmark of troupe's streaming step (criterion). The peer comparison
//! (onnxruntime, torch) is `benches/peers.py`; many streams at once is `examples/crowd.rs`;
//! `docs/PERFORMANCE.md` has the numbers and the commands.
//!
//!     cargo bench --bench step                                   # the committed tiny bundle
//!     TROUPE_BENCH_BUNDLE=onnx/bundles/paper cargo bench --bench step    # paper size (export it first)
//!     cargo bench --bench step -- --test                         # run each once (CI smoke)
//!
//! - `load`: `Model::load` plus a first session.
//! - `step/history_H`: one full token (4 new actor frames in, 4 reactor frames out) with `H`
//!   tokens in the context cache (capacity `H + 1`, so the cache stays at H as the stream runs).
//! - `sessions_step/N`: one round of `step_sessions` over N sessions at history 10, one token
//!   each; compare with N times `step/history_10`.
//! - `snapshot/history_H`, `restore/history_H`: `Session::snapshot` and `Model::restore` of a
//!   session whose cache is full at `H` tokens (its size in bytes is printed).

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use troupe::{Model, ReactorOptions, Session};

#[path = "../examples/common/mod.rs"]
mod common;
use common::synthetic_actor;

fn bundle() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    std::env::var_os("TROUPE_BENCH_BUNDLE")
        .map_or_else(|| root.join("onnx/bundles/armflow-tiny"), PathBuf::from)
}

/// A session warmed to `history` tokens with capacity `history + 1`.
fn warm_session(model: &Model, history: usize, seed: u64) -> Session {
    warm_with_capacity(model, history, history + 1, seed)
}

/// A session warmed to `tokens` tokens with capacity `capacity`.
fn warm_with_capacity(model: &Model, tokens: usize, capacity: usize, seed: u64) -> Session {
    let mut session = model
        .session(ReactorOptions {
            seed,
            context_capacity: Some(capacity),
            ..Default::default()
        })
        .expect("session");
    let frames = synthetic_actor(tokens * model.frames_per_token(), model.frame_dim());
    session.step(frames.view()).expect("warm-up");
    session
}

fn benches(c: &mut Criterion) {
    let path = bundle();
    let model = Model::load(&path).expect("the benchmark bundle loads");
    let (dim, fpt) = (model.frame_dim(), model.frames_per_token());
    let token = synthetic_actor(fpt, dim);
    let token = token.as_slice().expect("standard layout");

    c.bench_function("load", |b| {
        b.iter(|| {
            let m = Model::load(&path).expect("load");
            black_box(m.session(ReactorOptions::default()).expect("session"))
        })
    });

    let mut group = c.benchmark_group("step");
    for history in [10, 100, 1000, 2000] {
        let mut session = warm_session(&model, history, 1);
        group.bench_function(
            BenchmarkId::from_parameter(format!("history_{history}")),
            |b| b.iter(|| black_box(session.step_flat(token).expect("step"))),
        );
    }
    group.finish();

    let mut group = c.benchmark_group("sessions_step");
    for n in [1, 8, 32] {
        let mut sessions: Vec<Session> = (0..n).map(|i| warm_session(&model, 10, i)).collect();
        let chunks = vec![token; n as usize];
        group.throughput(Throughput::Elements(n));
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter(|| {
                let mut refs: Vec<&mut Session> = sessions.iter_mut().collect();
                black_box(troupe::step_sessions(&mut refs, &chunks).expect("batched step"))
            })
        });
    }
    group.finish();

    let mut saves = c.benchmark_group("snapshot");
    let mut snapshots = Vec::new();
    // 128: the paper bundle's default capacity.
    for history in [10, 128, 1000, 2000] {
        // One token past the capacity: the cache is full and has wrapped.
        let session = warm_with_capacity(&model, history + 1, history, 2);
        let bytes = session.snapshot().expect("snapshot");
        println!("snapshot at history {history}: {} bytes", bytes.len());
        saves.bench_function(
            BenchmarkId::from_parameter(format!("history_{history}")),
            |b| b.iter(|| black_box(session.snapshot().expect("snapshot"))),
        );
        snapshots.push((history, bytes));
    }
    saves.finish();
    let mut restores = c.benchmark_group("restore");
    for (history, bytes) in &snapshots {
        restores.bench_function(
            BenchmarkId::from_parameter(format!("history_{history}")),
            |b| b.iter(|| black_box(model.restore(bytes).expect("restore"))),
        );
    }
    restores.finish();
}

criterion_group! {
    name = step;
    config = Criterion::default().sample_size(20);
    targets = benches
}
criterion_main!(step);
