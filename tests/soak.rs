//! Endurance: one session streaming for a long time, and models and sessions created and freed
//! over and over, with the process's resident memory sampled (Linux `/proc/self/statm`). After
//! warm-up, resident memory must stay flat within 1 MiB: a stream runs in bounded memory and a
//! freed handle gives its memory back.
//!
//! "Flat" is judged on medians, since the allocator returns freed memory to the system in its own
//! time (a sample taken just after a model load can sit a megabyte or more above the rest): the
//! median sample of the second half after warm-up may not exceed that of the first half by more
//! than 1 MiB. A leak moves every later sample, so it moves the median; a spike does not.
//!
//! CI runs a bounded form (20,000 tokens and 2,000 session cycles, under a minute; the model
//! cycles are then a counted skip); `TROUPE_SLOW_TESTS=1` runs the long form of
//! docs/RELIABILITY.md (1,000,000 tokens, 10,000 cycles of each). One test, so that nothing else
//! runs in the process while it measures.

mod common;

use common::*;
use ndarray::Array2;
use troupe::{Model, ReactorOptions};

const FLAT_BYTES: i64 = 1 << 20;

/// Resident bytes of this process.
fn rss_bytes() -> i64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("Linux /proc");
    let pages: i64 = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

fn long_form() -> bool {
    std::env::var_os("TROUPE_SLOW_TESTS").is_some_and(|v| v == "1")
}

/// Runs `round` `rounds` times, sampling resident memory every `every` rounds; asserts the
/// median of the samples after `warmup` rounds stays within [`FLAT_BYTES`] from the first half
/// to the second.
fn flat(what: &str, rounds: usize, every: usize, warmup: usize, mut round: impl FnMut(usize)) {
    let mut samples = Vec::new();
    for i in 0..rounds {
        round(i);
        if (i + 1) % every == 0 {
            samples.push((i + 1, rss_bytes()));
        }
    }
    let after: Vec<i64> = samples
        .iter()
        .filter(|(i, _)| *i > warmup)
        .map(|&(_, rss)| rss)
        .collect();
    let (first, second) = after.split_at(after.len() / 2);
    let median = |s: &[i64]| {
        let mut s = s.to_vec();
        s.sort_unstable();
        s.get(s.len() / 2).copied().unwrap_or(0)
    };
    let mib = |b: i64| b as f64 / (1 << 20) as f64;
    println!(
        "{what}: {rounds} rounds; median RSS {:.2} MiB in the first half after warm-up, {:.2} \
         MiB in the second; samples (MiB): {}",
        mib(median(first)),
        mib(median(second)),
        samples
            .iter()
            .map(|&(_, rss)| format!("{:.2}", mib(rss)))
            .collect::<Vec<_>>()
            .join(" ")
    );
    assert!(
        first.len() >= 2 && median(second) - median(first) <= FLAT_BYTES,
        "{what}: resident memory grew from a median of {} to {} bytes",
        median(first),
        median(second)
    );
}

#[test]
fn memory_stays_flat_over_long_streams_and_many_handles() {
    let long = long_form();
    let model = model();
    let d = model.frame_dim();

    // 1. One session, one token (4 frames) per call.
    let tokens = if long { 1_000_000 } else { 20_000 };
    let mut session = model
        .session(ReactorOptions {
            context_capacity: Some(16),
            ..default_options()
        })
        .unwrap();
    let actor = actor();
    let mut chunk = Array2::<f32>::zeros((4, d));
    flat("stream", tokens, tokens / 20, tokens / 10, |i| {
        for r in 0..4 {
            chunk
                .row_mut(r)
                .assign(&actor.row((4 * i + r) % actor.nrows()));
        }
        let out = session.step(chunk.view()).unwrap();
        assert!(out.iter().all(|v| v.is_finite()));
    });

    // 2. Sessions created, stepped and freed.
    let cycles = if long { 10_000 } else { 2_000 };
    let first = actor.slice(ndarray::s![..8, ..]).to_owned();
    flat("session cycles", cycles, cycles / 20, cycles / 10, |i| {
        let mut s = model
            .session(ReactorOptions {
                seed: i as u64,
                ..default_options()
            })
            .unwrap();
        s.step(first.view()).unwrap();
    });

    // 3. Models loaded and freed (the bundle's graphs optimised each time). Long form only: in
    // 60 loads the median moved by 1.1 MiB in one fresh-clone run and by 0.02 MiB in another,
    // so the bounded form cannot tell a slow leak from allocator noise (issue 16's note).
    if !long {
        skip(
            "memory_stays_flat_over_long_streams_and_many_handles (model cycles)",
            "long form only: set TROUPE_SLOW_TESTS=1",
        );
        return;
    }
    let loads = 10_000;
    flat("model cycles", loads, loads / 20, loads / 5, |_| {
        let m = Model::load(bundle_dir()).unwrap();
        drop(m);
    });
}
