//! What each streaming graph of a bundle costs per row (per stream) as the batch grows: the
//! crowd path graph by graph, outside troupe's session code. Each graph is loaded and optimised
//! by tract as troupe loads it, fed deterministic inputs of the manifest's shapes (`B` and `N` the
//! batch: one token row per stream), and timed over repeated calls on one thread. A role of
//! several graphs (`context_layers`) is timed as the sum of its graphs; the attention troupe runs
//! between them is not a graph, and is in `examples/crowd` and `benches/peers.py`.
//!
//!     cargo bench --bench graph_rows                                    # the committed tiny bundle
//!     TROUPE_BENCH_BUNDLE=onnx/bundles/paper TROUPE_BENCH_BATCHES=1,16,64 \
//!         TROUPE_BENCH_HISTORY=100 cargo bench --bench graph_rows       # paper size
//!
//! `TROUPE_BENCH_GRAPHS=context_layers` times only the graphs named (to profile one under `perf`);
//! it may name any role of the manifest, so other families' graphs are timed the same way, with
//! their other dimensions from `TROUPE_BENCH_SYMBOLS` (MAGNet at released size: the denoiser's
//! `B` is samples, the guidance's `N` one person of one sample a row):
//!
//!     TROUPE_BENCH_BUNDLE=onnx/bundles/magnet-dd100 TROUPE_BENCH_GRAPHS=denoiser,guidance \
//!         TROUPE_BENCH_BATCHES=1,10 cargo bench --bench graph_rows
//!
//! `TROUPE_BENCH_CONCRETE=1` plans each graph for each batch with every dimension known, as troupe
//! plans the graphs it always runs with one row (the text tower: `shared/graph.rs`); the
//! difference to the default shows what knowing the sizes is worth to tract's kernel choice:
//!
//!     TROUPE_BENCH_CONCRETE=1 TROUPE_BENCH_BUNDLE=onnx/bundles/paper-interhuman \
//!         TROUPE_BENCH_GRAPHS=text_encoder TROUPE_BENCH_BATCHES=1 cargo bench --bench graph_rows
//!
//! Each call runs as troupe runs its graphs: a run state reused, operation by operation, the vector
//! registers' upper halves cleared after each (`troupe::PlanRunner`, `shared/vector_state.rs`).
//! `TROUPE_BENCH_NODES=1` also prints, per graph and batch, where a call's time goes: the
//! operations run, the time inside them, and the costliest kinds of operation.
//!
//! `cargo test --bench graph_rows` (the suite's smoke run) runs every graph once at batch 2.
//! Prints one line per graph and batch: median ms per call and per row, and the ratio of the
//! per-row cost to batch 1's (how much a crowd saves by batching that graph).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use serde_json::Value;
use tract_onnx::prelude::*;

/// The graphs a streaming token runs, in the order a step runs them.
const STEP_GRAPHS: [&str; 4] = [
    "vae_encoder_step",
    "context_layers",
    "velocity",
    "vae_decoder_step",
];

fn env_or(name: &str, default: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| default.to_owned())
}

/// Deterministic inputs of the declared shapes: floats in [-0.5, 0.5), integers 0.
fn inputs(spec: &Value, symbols: &BTreeMap<&str, usize>) -> TVec<TValue> {
    spec["inputs"]
        .as_array()
        .expect("inputs")
        .iter()
        .map(|input| {
            let shape: Vec<usize> = input["shape"]
                .as_array()
                .expect("shape")
                .iter()
                .map(|d| match d {
                    Value::String(s) => symbols[s.as_str()],
                    n => n.as_u64().expect("a dimension") as usize,
                })
                .collect();
            let len: usize = shape.iter().product();
            let tensor = if input["dtype"] == "int64" {
                Tensor::from_shape(&shape, &vec![0i64; len])
            } else {
                let data: Vec<f32> = (0..len)
                    .map(|i| ((i * 7919) % 1000) as f32 / 1000.0 - 0.5)
                    .collect();
                Tensor::from_shape(&shape, &data)
            };
            tensor.expect("shape matches data").into_tvalue()
        })
        .collect()
}

fn median_ms(call: impl Fn(), calls: usize) -> f64 {
    let mut times: Vec<f64> = (0..calls)
        .map(|_| {
            let started = Instant::now();
            call();
            started.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn main() {
    // `cargo test --bench graph_rows` runs the binary without `--bench`: one call each.
    let smoke = !std::env::args().any(|a| a == "--bench");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let bundle = std::env::var_os("TROUPE_BENCH_BUNDLE")
        .map_or_else(|| root.join("onnx/bundles/armflow-tiny"), PathBuf::from);
    let batches: Vec<usize> = if smoke {
        vec![2]
    } else {
        env_or("TROUPE_BENCH_BATCHES", "1,16,64")
            .split(',')
            .map(|b| {
                b.trim()
                    .parse()
                    .expect("TROUPE_BENCH_BATCHES: sizes like 1,16,64")
            })
            .collect()
    };
    let (warmup, calls) = if smoke { (0, 1) } else { (3, 15) };
    let manifest: Value = serde_json::from_slice(
        &std::fs::read(bundle.join("troupe.json")).expect("the bundle's troupe.json"),
    )
    .expect("a JSON manifest");
    println!(
        "{}: {calls} timed calls after {warmup} on one thread",
        bundle.display()
    );
    let only = std::env::var("TROUPE_BENCH_GRAPHS").ok();
    let roles: Vec<&str> = only
        .as_deref()
        .map_or_else(|| STEP_GRAPHS.to_vec(), |only| only.split(',').collect());
    let mut fixed = BTreeMap::new();
    for pair in env_or("TROUPE_BENCH_SYMBOLS", "").split(',') {
        if let Some((name, value)) = pair.split_once('=') {
            let value = value
                .trim()
                .parse()
                .expect("TROUPE_BENCH_SYMBOLS: like T=64,Z=16");
            fixed.insert(name.trim().to_owned(), value);
        }
    }
    for role in roles {
        let Some(spec) = manifest["graphs"].get(role) else {
            println!("{role}: not in this bundle");
            continue;
        };
        let specs = spec
            .as_array()
            .map_or_else(|| vec![spec], |all| all.iter().collect());
        // `TROUPE_BENCH_CONCRETE=1`: every symbol fixed before optimising (a plan per batch
        // size), so tract's kernel choice sees the real row counts.
        let concrete = std::env::var_os("TROUPE_BENCH_CONCRETE").is_some();
        let load = |values: Option<&BTreeMap<&str, usize>>| -> Vec<_> {
            specs
                .iter()
                .map(|spec| {
                    let file = bundle.join(spec["file"].as_str().expect("file"));
                    tract_onnx::onnx()
                        .model_for_path(&file)
                        .and_then(|mut m| {
                            if let Some(values) = values {
                                for (ix, tensor) in inputs(spec, values).iter().enumerate() {
                                    let fact = InferenceFact::dt_shape(
                                        tensor.datum_type(),
                                        tensor.shape(),
                                    );
                                    m.set_input_fact(ix, fact)?;
                                }
                            }
                            m.into_typed()
                        })
                        .and_then(|m| {
                            // As troupe's loader: row counts are at least 1 (`shared/graph.rs`).
                            for name in ["B", "N"] {
                                if m.symbols.get(name).is_some() {
                                    m.symbols.add_assertion(format!("{name} >= 1"))?;
                                }
                            }
                            troupe::optimised_plan(m)
                        })
                        .unwrap_or_else(|e| panic!("{}: {e:#}", file.display()))
                })
                .collect()
        };
        let symbolic_plans = if concrete { Vec::new() } else { load(None) };
        let mut batch_one = None;
        for &batch in &batches {
            let mut symbols: BTreeMap<&str, usize> =
                fixed.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            symbols.extend([("B", batch), ("N", batch)]);
            let inputs: Vec<_> = specs.iter().map(|s| inputs(s, &symbols)).collect();
            let concrete_plans = if concrete {
                load(Some(&symbols))
            } else {
                Vec::new()
            };
            let plans = if concrete {
                &concrete_plans
            } else {
                &symbolic_plans
            };
            let runners: Vec<_> = plans
                .iter()
                .map(|plan| troupe::PlanRunner::new(plan.clone()).expect("a plan state"))
                .collect();
            let run = || {
                for (runner, inputs) in runners.iter().zip(&inputs) {
                    runner.run(inputs.clone()).expect("the graph runs");
                }
            };
            (0..warmup).for_each(|_| run());
            if std::env::var_os("TROUPE_BENCH_NODES").is_some() {
                node_profile(role, plans, &inputs, calls.max(50));
            }
            let call = median_ms(run, calls);
            let row = call / batch as f64;
            let one = *batch_one.get_or_insert(row);
            println!(
                "{role:>16} B = {batch:>3}: {call:9.3} ms per call, {row:7.4} ms per row, {:.2}x the first batch's row",
                row / one
            );
        }
    }
}

/// Where one call's time goes, by kind of operation, averaged over `calls` calls of each plan.
fn node_profile(
    role: &str,
    plans: &[Arc<TypedRunnableModel>],
    inputs: &[TVec<TValue>],
    calls: usize,
) {
    let mut by_kind: BTreeMap<String, (f64, usize)> = BTreeMap::new();
    let mut nodes = 0;
    for (plan, inputs) in plans.iter().zip(inputs) {
        nodes += plan.order_without_consts().len();
        for _ in 0..calls {
            let mut state = plan.spawn().expect("a plan state");
            state
                .run_plan_with_eval(inputs.clone(), |context, op_state, node, input| {
                    let started = Instant::now();
                    let outputs = troupe::evaluate_operation(context, op_state, node, input);
                    let kind = by_kind.entry(node.op().name().to_string()).or_default();
                    kind.0 += started.elapsed().as_secs_f64() * 1e3 / calls as f64;
                    kind.1 += 1;
                    outputs
                })
                .expect("the graph runs");
        }
    }
    let total: f64 = by_kind.values().map(|(ms, _)| ms).sum();
    let mut kinds: Vec<_> = by_kind.into_iter().collect();
    kinds.sort_by(|a, b| b.1 .0.total_cmp(&a.1 .0));
    println!("{role:>16}: {nodes} operations a call, {total:.3} ms inside them; the costliest:");
    for (kind, (ms, count)) in kinds.iter().take(8) {
        println!("{kind:>40}: {ms:8.3} ms ({} a call)", count / calls);
    }
}
