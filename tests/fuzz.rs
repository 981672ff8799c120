//! The fuzz targets (`fuzz/targets/mod.rs`) on the stable toolchain: every committed corpus input
//! and every regression input (a crash once found) is replayed, then the corpus is mutated for a
//! bounded time per target (`TROUPE_FUZZ_SECONDS`, default 6; `TROUPE_SLOW_TESTS=1`: 120) with a
//! seeded generator (`TROUPE_FUZZ_SEED`, default 1, so that CI is repeatable; any other seed
//! explores new inputs, and a failure is replayed from its seed). The targets run side by side,
//! one per core.
//! A target may return errors; a panic (or an abort, which ends the process) fails the test, and
//! the input is written to `target/fuzz-failures/` to be added to `fuzz/regressions/`.
//!
//! The coverage-guided long runs use cargo-fuzz on nightly (`fuzz/Cargo.toml`); their figures
//! are in docs/RELIABILITY.md.

#[path = "../fuzz/targets/mod.rs"]
mod targets;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// The files of `fuzz/<kind>/<target>/`, sorted.
fn inputs(kind: &str, target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = fuzz_dir().join(kind).join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    files.sort();
    files
        .into_iter()
        .filter(|p| p.is_file())
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect()
}

/// splitmix64: a small seeded generator, enough to pick mutations reproducibly.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Values that break size arithmetic and float code, as little-endian bytes.
const INTERESTING: [u64; 10] = [
    0,
    1,
    0x7f,
    0xff,
    0x7fff_ffff,
    0xffff_ffff,
    1 << 50,
    u64::MAX,
    0x7f80_0000, // +inf as f32 bits
    0x7f7f_ffff, // f32::MAX
];

/// One mutant of `input`: a few byte-level edits, sometimes a splice with `other`.
fn mutate(rng: &mut Rng, input: &[u8], other: &[u8]) -> Vec<u8> {
    let mut data = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(data.len() + 1);
        match rng.below(7) {
            0 if !data.is_empty() => {
                let i = at.min(data.len() - 1);
                data[i] ^= 1 << rng.below(8);
            }
            1 if !data.is_empty() => {
                let i = at.min(data.len() - 1);
                data[i] = rng.next() as u8;
            }
            2 => {
                let value = INTERESTING[rng.below(INTERESTING.len())].to_le_bytes();
                let width = [1, 2, 4, 8][rng.below(4)];
                let end = (at + width).min(data.len());
                data.splice(at..end, value[..width].iter().copied());
            }
            3 if !data.is_empty() => {
                let len = 1 + rng.below(64.min(data.len()));
                let from = rng.below(data.len() - len + 1);
                data.drain(from..from + len);
            }
            4 => {
                let len = 1 + rng.below(64);
                let fill: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
                data.splice(at..at, fill);
            }
            5 if !other.is_empty() => {
                let from = rng.below(other.len());
                let len = 1 + rng.below((other.len() - from).min(256));
                data.splice(at..at, other[from..from + len].iter().copied());
            }
            _ => {
                // Text-aware: rewrite a run of ASCII digits (sizes in manifests, tar octal fields).
                if let Some(start) = (at..data.len()).find(|&i| data[i].is_ascii_digit()) {
                    let end = (start..data.len())
                        .find(|&i| !data[i].is_ascii_digit())
                        .unwrap_or(data.len());
                    let digits = INTERESTING[rng.below(INTERESTING.len())].to_string();
                    data.splice(start..end, digits.into_bytes());
                }
            }
        }
    }
    data
}

/// Runs `input` through `run`; on a panic, saves the input and fails naming it.
fn run_one(target: &str, run: fn(&[u8]), input: &[u8], origin: &str) {
    if catch_unwind(AssertUnwindSafe(|| run(input))).is_err() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-failures");
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!(
            "{target}-{:016x}",
            Rng(input.len() as u64 ^ 0x51).next()
        ));
        std::fs::write(&path, input).unwrap();
        panic!(
            "fuzz target `{target}` panicked on {origin}; the input is in {}",
            path.display()
        );
    }
}

#[test]
fn fuzz_targets_replay_their_corpus_and_survive_mutation() {
    let seconds: u64 = std::env::var("TROUPE_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(
            if std::env::var_os("TROUPE_SLOW_TESTS").is_some_and(|v| v == "1") {
                120
            } else {
                6
            },
        );
    let seed = std::env::var("TROUPE_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    println!("mutation seed {seed} (TROUPE_FUZZ_SEED={seed} replays this run)");
    // The targets are independent: one worker per core takes the next target until none is
    // left, so the bounded run takes its seconds per target divided by the cores. A panic in
    // one worker fails the test when the scope ends, after the message naming its input.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let workers = std::thread::available_parallelism()
        .map_or(1, usize::from)
        .min(targets::TARGETS.len());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&(target, run)) = targets::TARGETS.get(i) else {
                    break;
                };
                fuzz_one(target, run, seed, seconds);
            });
        }
    });
}

/// Replays `target`'s corpus and regressions, then mutates its corpus for `seconds`.
fn fuzz_one(target: &str, run: fn(&[u8]), seed: u64, seconds: u64) {
    let corpus = inputs("corpus", target);
    let regressions = inputs("regressions", target);
    assert!(!corpus.is_empty(), "fuzz/corpus/{target} is empty");
    for (path, bytes) in corpus.iter().chain(&regressions) {
        run_one(target, run, bytes, &path.display().to_string());
    }
    let mut rng = Rng(seed ^ target.len() as u64);
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let mut executions = 0u64;
    while Instant::now() < deadline {
        let a = &corpus[rng.below(corpus.len())].1;
        let b = &corpus[rng.below(corpus.len())].1;
        let mutant = mutate(&mut rng, a, b);
        run_one(
            target,
            run,
            &mutant,
            &format!("mutant {executions} of seed {seed}"),
        );
        executions += 1;
    }
    println!(
        "{target}: {} corpus and {} regression inputs replayed, {executions} mutants in {seconds} s",
        corpus.len(),
        regressions.len()
    );
}
