//! A crowd: many reactor streams of one model, each fed a 30 fps actor, and whether the machine
//! keeps them all in real time. Runs the sessions batched (`step_sessions`: one network call per
//! graph for all of them) or one by one (`Session::step` each), on one or more threads.
//!
//!     cargo run --release --example crowd -- --bundle onnx/bundles/paper --sessions 8,32,64 --history 100
//!
//! For each crowd size N: N sessions (seeds 0..N, the bundle's context capacity) are warmed to
//! `--history` tokens, then the modes take turns timing blocks of `--rounds` rounds, `--repeats`
//! blocks each (5 by default), the order flipping every repetition (A B B A ...) so that a slow
//! phase of the machine falls on both alike; a round gives every session one token's worth of
//! new actor frames (4 frames, 133 ms of motion at 30 fps) and collects its reactor frames. Each
//! mode is reported as the median of its blocks' p50 [their lowest and highest] and the median of
//! their p99. The crowd is in real time when that p99 fits in the 133 ms. The kernels troupe
//! runs are named in the first line (`TRACT_CPU_ISA=-avx512f,...` forces the AVX2 ones; see
//! `benches/peers.py --isa`). With `--threads T`
//! the crowd is split into T equal parts stepped on T threads. Also reported: the memory a
//! session holds (`Session::memory_bytes`, the largest in the crowd) and the RSS growth from
//! creating and warming the crowd divided by N (Linux; it includes allocator slack and what the
//! warm-up's batched calls left behind, so it is an upper bound).
//!
//! `--history 10..2000` gives the crowd mixed histories: session `i` of N is warmed to
//! `10 + (2000 - 10) * i / (N - 1)` tokens and keeps every token (its capacity covers its
//! history and the timed rounds), so one round attends over very different cache lengths.

use std::time::Instant;

use troupe::{Model, ReactorOptions, Session};

mod common;
use common::{percentile, synthetic_actor};

struct Args {
    bundle: String,
    sessions: Vec<usize>,
    /// The least and the most history of the crowd's sessions (equal unless mixed).
    history: (usize, usize),
    rounds: usize,
    /// Blocks of `rounds` rounds per mode, the modes taking turns (A B B A ...).
    repeats: usize,
    threads: usize,
    modes: Vec<Mode>,
}

#[derive(Clone, Copy, PartialEq)]
enum Mode {
    Batched,
    Alone,
}

impl Mode {
    fn name(self) -> &'static str {
        match self {
            Mode::Batched => "batched",
            Mode::Alone => "one by one",
        }
    }
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        bundle: concat!(env!("CARGO_MANIFEST_DIR"), "/onnx/bundles/armflow-tiny").into(),
        sessions: vec![1, 8, 32],
        history: (100, 100),
        rounds: 20,
        repeats: 5,
        threads: 1,
        modes: vec![Mode::Batched, Mode::Alone],
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let number = |v: String| v.parse::<usize>().map_err(|e| format!("{flag} {v}: {e}"));
        match flag.as_str() {
            "--bundle" => args.bundle = value()?,
            "--sessions" => {
                args.sessions = value()?
                    .split(',')
                    .map(|v| number(v.to_string()))
                    .collect::<Result<_, _>>()?
            }
            "--history" => {
                let v = value()?;
                args.history = match v.split_once("..") {
                    Some((lo, hi)) => (number(lo.into())?, number(hi.into())?),
                    None => (number(v.clone())?, number(v.clone())?),
                };
                if args.history.0 > args.history.1 {
                    return Err(format!("--history {v}: LO..HI with LO <= HI"));
                }
            }
            "--rounds" => args.rounds = number(value()?)?,
            "--repeats" => args.repeats = number(value()?)?,
            "--threads" => args.threads = number(value()?)?.max(1),
            "--compute-threads" => troupe::set_compute_threads(number(value()?)?)
                .map_err(|e| format!("--compute-threads: {e}"))?,
            "--mode" => {
                args.modes = match value()?.as_str() {
                    "batched" => vec![Mode::Batched],
                    "alone" => vec![Mode::Alone],
                    "both" => vec![Mode::Batched, Mode::Alone],
                    other => return Err(format!("--mode {other}: batched, alone or both")),
                }
            }
            "-h" | "--help" => {
                println!(
                    "crowd [--bundle DIR] [--sessions 1,8,32] [--history 100 | LO..HI] [--rounds 20] \
                     [--repeats 5] [--threads 1] [--mode batched|alone|both]"
                );
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if args.sessions.contains(&0) || args.rounds == 0 || args.repeats == 0 {
        return Err("--sessions, --rounds and --repeats must be >= 1".into());
    }
    Ok(args)
}

/// Resident set size of this process in bytes (0 where /proc is missing).
fn rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4096)
}

/// One round: every session gets `chunk`; the crowd is split over `threads` threads.
fn round(sessions: &mut [Session], chunk: &[f32], mode: Mode, threads: usize) {
    let part = sessions.len().div_ceil(threads);
    std::thread::scope(|scope| {
        for group in sessions.chunks_mut(part) {
            scope.spawn(move || match mode {
                Mode::Batched => {
                    let mut refs: Vec<&mut Session> = group.iter_mut().collect();
                    let chunks = vec![chunk; refs.len()];
                    troupe::step_sessions(&mut refs, &chunks).expect("batched step");
                }
                Mode::Alone => {
                    for s in group {
                        s.step_flat(chunk).expect("step");
                    }
                }
            });
        }
    });
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let model = Model::load(&args.bundle)?;
    let (dim, fpt) = (model.frame_dim(), model.frames_per_token());
    let budget_ms = 1e3 * fpt as f64 / f64::from(model.fps());
    let (least, most) = args.history;
    let timed = args.modes.len() * args.rounds * args.repeats;
    let clip = synthetic_actor((most + timed + 1) * fpt, dim);
    let clip = clip.as_slice().expect("standard layout");
    println!(
        "bundle {} ({}): history {} tokens, {} x {} timed rounds of {fpt} frames ({budget_ms:.1} ms of motion) per mode, {} thread(s), kernels: {}",
        args.bundle,
        model.manifest().name,
        if least == most { format!("{most}") } else { format!("{least} to {most} (every token kept)") },
        args.repeats,
        args.rounds,
        args.threads,
        troupe::kernels()
    );
    println!("| sessions | mode | round p50 ms [spread] | round p99 ms | per session-token ms | real time | held per session MB | RSS per session MB |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut best = vec![0usize; args.modes.len()];
    for &n in &args.sessions {
        let before = rss_bytes();
        let history = |i: usize| least + (most - least) * i / (n - 1).max(1);
        let mut sessions: Vec<Session> = (0..n)
            .map(|i| {
                model.session(ReactorOptions {
                    seed: i as u64,
                    // Mixed histories keep every token, so that each cache has its own length.
                    context_capacity: (least != most).then(|| history(i) + timed + 2),
                    ..Default::default()
                })
            })
            .collect::<Result<_, _>>()?;
        // Warm-up: each session is fed up to its history; the timed rounds then start where the
        // longest ended, so every session gets the same frames in each round.
        for (g, group) in sessions.chunks_mut(64).enumerate() {
            let chunks: Vec<&[f32]> = (0..group.len())
                .map(|i| &clip[(most - history(g * 64 + i)) * fpt * dim..most * fpt * dim])
                .collect();
            let mut refs: Vec<&mut Session> = group.iter_mut().collect();
            troupe::step_sessions(&mut refs, &chunks)?;
        }
        let per_session_mb = (rss_bytes().saturating_sub(before)) as f64 / n as f64 / 1e6;
        let held_mb = sessions
            .iter()
            .map(Session::memory_bytes)
            .max()
            .unwrap_or(0) as f64
            / 1e6;
        // The modes continue the same streams, each round advancing every stream by a token. They
        // take turns in blocks of `rounds` rounds, the order flipping every repetition (A B B A
        // ...), so that a slow phase of the machine falls on every mode alike; each mode's block
        // medians give its median and spread, its block p99s its p99.
        let mut fed = most;
        let mut blocks: Vec<Vec<(f64, f64)>> = vec![Vec::new(); args.modes.len()];
        for r in 0..args.repeats {
            let order: Vec<usize> = if r % 2 == 0 {
                (0..args.modes.len()).collect()
            } else {
                (0..args.modes.len()).rev().collect()
            };
            for m in order {
                let mut times = Vec::with_capacity(args.rounds);
                for _ in 0..args.rounds {
                    let at = fed * fpt * dim;
                    let chunk = &clip[at..at + fpt * dim];
                    let t = Instant::now();
                    round(&mut sessions, chunk, args.modes[m], args.threads);
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                    fed += 1;
                }
                times.sort_by(f64::total_cmp);
                blocks[m].push((percentile(&times, 0.5), percentile(&times, 0.99)));
            }
        }
        for (m, &mode) in args.modes.iter().enumerate() {
            let mut p50s: Vec<f64> = blocks[m].iter().map(|b| b.0).collect();
            let mut p99s: Vec<f64> = blocks[m].iter().map(|b| b.1).collect();
            p50s.sort_by(f64::total_cmp);
            p99s.sort_by(f64::total_cmp);
            let (p50, p99) = (percentile(&p50s, 0.5), percentile(&p99s, 0.5));
            let real_time = p99 <= budget_ms;
            if real_time {
                best[m] = best[m].max(n);
            }
            println!(
                "| {n} | {} | {p50:.2} [{:.2}-{:.2}] | {p99:.2} | {:.3} | {} | {held_mb:.2} | {per_session_mb:.2} |",
                mode.name(),
                p50s[0],
                p50s[p50s.len() - 1],
                p50 / n as f64,
                if real_time { "yes" } else { "no" }
            );
        }
    }
    for (m, mode) in args.modes.iter().enumerate() {
        println!(
            "largest crowd in real time, {}: {} of the sizes tried",
            mode.name(),
            best[m]
        );
    }
    Ok(())
}
