//! One ONNX graph of a bundle: loaded, checked against the manifest, optimised once, and run by
//! any number of sessions at the same time (a tract plan is `Send + Sync`; each call runs in a
//! state of its own, an idle one left by an earlier call where the plan allows: [`PlanRunner`]).
//!
//! A graph few sessions need (the VAE windows, when a bundle also has per-token steps) may be
//! *deferred*: it is read and checked at load like any other, so a bad file still fails the load,
//! but tract's optimisation, most of a graph's load time, waits for its first call.
//!
//! A graph troupe always runs with one row (CLIP's text tower: one prompt per call) is
//! optimised for that row count: with `B` unknown tract cannot size its matrix products and
//! falls back to a default tile; knowing them, it picks one that ran the official text tower
//! 15 % faster.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::{EvalContext, OpState};

use crate::shared::bundle::BundleFiles;
use crate::shared::clock::Stopwatch;
use crate::shared::error::{Error, Result};
use crate::shared::graph_spec::{DType, Dim, GraphSpec, TensorSpec, Weights};
use crate::shared::half_products;
use crate::shared::limits::LIMITS;
use crate::shared::logging::{log, Level};
use crate::shared::onnx_guard;
use crate::shared::panics;
use crate::shared::progress;
use crate::shared::threads::load_threads;
use crate::shared::unit_axes;
use crate::shared::vector_state;

/// A loaded graph whose inputs and outputs are addressed in manifest order.
#[derive(Debug)]
pub(crate) struct Graph {
    role: &'static str,
    file: std::path::PathBuf,
    /// The optimised plan and its idle run states: set at load, or at the first call of a
    /// deferred graph.
    plan: OnceLock<PlanRunner>,
    /// A deferred graph's checked model until its first call optimises it.
    deferred: Mutex<Option<TypedModel>>,
    /// For each manifest input, its position among the graph's inputs.
    input_order: Vec<usize>,
    /// For each manifest output, its position among the graph's outputs.
    output_order: Vec<usize>,
}

impl Graph {
    /// Loads `spec.file` from the bundle, checks it against `spec`, and optimises it as `plan`
    /// says.
    pub(crate) fn load(
        role: &'static str,
        files: &BundleFiles,
        spec: &GraphSpec,
        plan: PlanPolicy,
    ) -> Result<Self> {
        let file = files.path_of(&spec.file);
        let started = Stopwatch::start();
        let mut phases = Phases::new();
        let bytes = files.read(&spec.file, LIMITS.max_bundle_bytes)?;
        phases.mark("read");
        let bad = |message: String| Error::Graph {
            file: file.clone(),
            message,
        };
        let onnx = tract_onnx::onnx();
        // Decoded from the bytes in hand: every weight is copied out once, here, and the file's
        // bytes are freed before tract builds the graph.
        let proto = <tract_onnx::pb::ModelProto as prost::Message>::decode(&bytes[..])
            .map_err(|e| bad(format!("not a loadable ONNX model: {e:#}")))?;
        drop(bytes);
        onnx_guard::check_model(&proto).map_err(&bad)?;
        onnx_guard::check_weights(&proto, spec.weights).map_err(&bad)?;
        phases.mark("parsed");
        let model = onnx
            .model_for_proto_model(&proto)
            .map_err(|e| bad(format!("not a loadable ONNX model: {e:#}")))?;
        drop(proto);
        phases.mark("built");
        let mut model = model
            .into_typed()
            .map_err(|e| bad(format!("shapes cannot be resolved: {e:#}")))?;
        assert_row_counts(&model).map_err(&bad)?;
        if spec.weights == Weights::Float16 {
            keep_float16_weights(&mut model).map_err(&bad)?;
            half_products::use_half_products(&mut model)
                .map_err(|e| bad(format!("its float16 products: {e:#}")))?;
        }
        phases.mark("typed");
        let (input_order, output_order) = check_interface(&model, spec).map_err(&bad)?;
        if plan.one_row {
            model = with_one_row(&model).map_err(&bad)?;
        }
        let defer = plan.deferred;
        let graph = Self {
            role,
            file: file.clone(),
            plan: OnceLock::new(),
            deferred: Mutex::new(Some(model)),
            input_order,
            output_order,
        };
        if !defer {
            graph.plan()?;
            phases.mark("optimised");
        }
        log(Level::Debug, "troupe::load", || {
            format!(
                "{}: loaded{} in {:.0} ms ({})",
                file.display(),
                if defer {
                    " (optimised on first use)"
                } else {
                    " and optimised"
                },
                started.elapsed_ms(),
                phases.summary()
            )
        });
        Ok(graph)
    }

    /// The optimised plan, optimising a deferred graph once (other callers wait for it).
    fn plan(&self) -> Result<&PlanRunner> {
        if let Some(plan) = self.plan.get() {
            return Ok(plan);
        }
        let bad = |message: String| Error::Graph {
            file: self.file.clone(),
            message,
        };
        // A panic while optimising poisons nothing we rely on: the model was taken out first.
        let mut deferred = self.deferred.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(plan) = self.plan.get() {
            return Ok(plan); // optimised by the caller we waited for
        }
        let model = deferred
            .take()
            .ok_or_else(|| bad("its optimisation failed on an earlier call".into()))?;
        let quiet = panics::is_quiet();
        let plan = panics::catch(quiet, || {
            optimised_plan(model)
                .and_then(PlanRunner::new)
                .map_err(|e| bad(format!("cannot be optimised: {e:#}")))
        })
        .unwrap_or_else(|reason| Err(bad(format!("optimising the graph panicked: {reason}"))))?;
        Ok(self.plan.get_or_init(|| plan))
    }

    /// The graph's role in the bundle (`prior`, `context_layers`, ...), for messages.
    pub(crate) fn role(&self) -> &'static str {
        self.role
    }

    /// Runs the graph on inputs given in manifest order; returns outputs in manifest order.
    pub(crate) fn run(&self, inputs: Vec<TValue>) -> Result<Vec<TValue>> {
        debug_assert_eq!(inputs.len(), self.input_order.len(), "{}", self.role);
        let mut ordered: Vec<Option<TValue>> = vec![None; inputs.len()];
        for (value, &slot) in inputs.into_iter().zip(&self.input_order) {
            ordered[slot] = Some(value);
        }
        let ordered: TVec<TValue> = ordered.into_iter().flatten().collect();
        let mut outputs = self.plan()?.run(ordered).map_err(|e| Error::Inference {
            graph: self.role,
            message: format!("{e:#}"),
        })?;
        Ok(self
            .output_order
            .iter()
            .map(|&slot| std::mem::replace(&mut outputs[slot], Tensor::default().into_tvalue()))
            .collect())
    }
}

/// Durations of a graph load's phases, for the debug log.
struct Phases {
    last: Stopwatch,
    marks: Vec<(&'static str, f64)>,
}

impl Phases {
    fn new() -> Self {
        Self {
            last: Stopwatch::start(),
            marks: Vec::new(),
        }
    }

    fn mark(&mut self, phase: &'static str) {
        self.marks.push((phase, self.last.elapsed_ms()));
        self.last = Stopwatch::start();
    }

    fn summary(&self) -> String {
        let parts: Vec<String> = self
            .marks
            .iter()
            .map(|(phase, ms)| format!("{phase} {ms:.0} ms"))
            .collect();
        parts.join(", ")
    }
}

/// An optimised plan and the run states of its earlier calls, run as troupe runs every graph:
/// operation by operation, each through [`evaluate_operation`]. Public for benchmarks that run
/// graphs by hand as troupe runs them (`benches/graph_rows.rs`).
///
/// A fresh tract run state costs a value slot per node and an inter-call state per operation,
/// allocated and dropped again on every call: about 3 % of the demo model's token. So a call
/// takes an idle state instead, of any earlier caller, and puts it back when the call succeeded;
/// one that failed part-way is dropped, so no call sees another's leftovers. Only plans whose
/// operations keep nothing between calls reuse states (tract's `Scan`, for one, keeps its
/// position): troupe's graphs all do, and any other plan spawns a fresh state every call.
#[doc(hidden)]
#[derive(Debug)]
pub struct PlanRunner {
    plan: Arc<TypedRunnableModel>,
    /// Whether states may be reused: no operation of the plan keeps an inter-call state.
    reusable: bool,
    /// States of finished calls, at most [`PlanRunner::IDLE_STATES`].
    idle: Mutex<Vec<TypedSimpleState>>,
}

impl PlanRunner {
    /// Idle states kept: one per caller running the plan at the same time, up to this many
    /// (more concurrent callers than this spawn and drop states as before).
    const IDLE_STATES: usize = 16;

    /// A runner of `plan`.
    pub fn new(plan: Arc<TypedRunnableModel>) -> TractResult<Self> {
        let first = plan.spawn()?;
        let reusable = first.op_states.iter().all(Option::is_none);
        Ok(Self {
            plan,
            reusable,
            idle: Mutex::new(if reusable { vec![first] } else { Vec::new() }),
        })
    }

    /// The optimised plan.
    pub fn plan(&self) -> &Arc<TypedRunnableModel> {
        &self.plan
    }

    /// Runs the plan on `inputs` (in the plan's input order).
    pub fn run(&self, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        // A panic while the lock was held left the list whole: a push or a pop is one step.
        let idle = || self.idle.lock().unwrap_or_else(|p| p.into_inner());
        let taken = if self.reusable { idle().pop() } else { None };
        let mut state = match taken {
            Some(state) => state,
            None => self.plan.spawn()?,
        };
        let outputs = state.run_plan_with_eval(inputs, evaluate_operation)?;
        if self.reusable {
            let mut idle = idle();
            if idle.len() < Self::IDLE_STATES {
                idle.push(state);
            }
        }
        Ok(outputs)
    }
}

/// Evaluates one operation of a plan as troupe does, for `SimpleState::run_plan_with_eval`:
/// tract's own evaluation, then the vector registers' upper halves cleared, since tract's matrix
/// kernels leave them dirty and that slows the SSE code after them on Intel CPUs
/// (`shared/vector_state.rs`). Public for benchmarks that run graphs by hand as troupe runs them
/// (`benches/graph_rows.rs`).
#[doc(hidden)]
pub fn evaluate_operation(
    context: &EvalContext,
    op_state: Option<&mut (dyn OpState + 'static)>,
    node: &TypedNode,
    inputs: TVec<TValue>,
) -> TractResult<TVec<TValue>> {
    let outputs = tract_onnx::tract_core::plan::eval(context, op_state, node, inputs);
    vector_state::clear_upper_halves();
    outputs
}

/// A typed graph optimised and made runnable as troupe does it: tract's optimiser, then troupe's
/// own pass over the optimised graph (`shared/unit_axes.rs`). Public for benchmarks that load
/// graphs by hand as troupe loads them (`benches/graph_rows.rs`).
#[doc(hidden)]
pub fn optimised_plan(model: TypedModel) -> TractResult<Arc<TypedRunnableModel>> {
    let mut model = model.into_optimized()?;
    unit_axes::natural_unit_axes(&mut model);
    model.into_runnable()
}

/// Loads `onnx` as a bundle's graph is loaded (the protobuf guard, tract's typing, the
/// interface check against an ARMFlow `velocity` graph's, optimisation) and runs it once on
/// zeros: the graph loader without a bundle around it, for the `onnx_graph` fuzz target (a
/// whole bundle's other graphs made each execution a quarter of a second).
#[doc(hidden)]
pub fn load_graph_for_fuzzing(onnx: &[u8]) -> Result<()> {
    const SPEC: &str = r#"{"file": "velocity.onnx", "inputs": [
        {"name": "actor", "dtype": "float32", "shape": ["B", 16]},
        {"name": "noisy", "dtype": "float32", "shape": ["B", 16]},
        {"name": "context", "dtype": "float32", "shape": ["B", 32]},
        {"name": "r", "dtype": "float32", "shape": ["B"]},
        {"name": "t", "dtype": "float32", "shape": ["B"]}],
        "outputs": [{"name": "velocity", "dtype": "float32", "shape": ["B", 16]}]}"#;
    let spec: GraphSpec = serde_json::from_str(SPEC).expect("a valid graph declaration");
    let files = BundleFiles::Archive {
        label: std::path::PathBuf::from("fuzz.troupe"),
        files: std::collections::HashMap::from([("velocity.onnx".to_string(), onnx.to_vec())]),
        digests: Default::default(),
    };
    let quiet = panics::is_quiet();
    let graph = panics::catch(quiet, || {
        Graph::load("velocity", &files, &spec, PlanPolicy::default())
    })
    .unwrap_or_else(|reason| Err(Error::InvalidInput(format!("loading panicked: {reason}"))))?;
    let zeros = |shape: &[usize]| f32_tensor(shape, &vec![0.0; shape.iter().product()]);
    // A panic while running is caught as every C entry point catches it.
    panics::catch(quiet, || {
        let outputs = graph.run(vec![
            zeros(&[1, 16]),
            zeros(&[1, 16]),
            zeros(&[1, 32]),
            zeros(&[1]),
            zeros(&[1]),
        ])?;
        read_f32("velocity", "velocity", &outputs[0], &[1, 16]).map(|_| ())
    })
    .unwrap_or_else(|reason| Err(Error::InvalidInput(format!("running panicked: {reason}"))))
}

/// When and for which row counts a graph's plan is made.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PlanPolicy {
    /// Checked at load, optimised on its first call.
    pub deferred: bool,
    /// Only ever run with one row (`B = 1`): planned for exactly that.
    pub one_row: bool,
}

/// Loads and optimises `wanted` graphs (role and declaration) on up to [`load_threads`] scoped
/// threads (optimisation dominates load time and each graph is independent; every thread is
/// joined before this returns), each as `policy` says for its role; returns them in order, or
/// the first error in that order. A
/// panic while loading a graph (tract on a hostile graph) becomes that graph's error, with its
/// reason. Progress (graphs loaded) goes to the calling thread's progress callback, which may
/// cancel the load.
pub(crate) fn load_graphs(
    files: &BundleFiles,
    wanted: &[(&'static str, &GraphSpec)],
    policy: impl Fn(&str) -> PlanPolicy + Sync,
) -> Result<Vec<Graph>> {
    let workers = load_threads().min(wanted.len()).max(1);
    let quiet = panics::is_quiet();
    let load = |role: &'static str, spec: &GraphSpec| {
        let plan = policy(role);
        panics::catch(quiet, || Graph::load(role, files, spec, plan)).unwrap_or_else(|reason| {
            Err(Error::Graph {
                file: files.path_of(&spec.file),
                message: format!("loading the graph panicked: {reason}"),
            })
        })
    };
    let total = wanted.len() as u64;
    if workers == 1 {
        let mut graphs = Vec::with_capacity(wanted.len());
        for (i, &(role, spec)) in wanted.iter().enumerate() {
            graphs.push(load(role, spec)?);
            progress::report("loading the bundle", i as u64 + 1, total)?;
        }
        return Ok(graphs);
    }
    // Workers take graphs in order and send them back; this thread reports progress (so the
    // callback runs on the caller's thread) and, when it is cancelled, stops the workers taking
    // more.
    // Largest graphs first, deferred ones (read and checked only) last: the load ends when its
    // longest graph does, so starting that one first keeps the threads evenly busy.
    let mut order: Vec<usize> = (0..wanted.len()).collect();
    order.sort_by_key(|&i| {
        let (role, spec) = wanted[i];
        (
            policy(role).deferred,
            std::cmp::Reverse(files.size_hint(&spec.file)),
        )
    });
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (done_tx, done_rx) = std::sync::mpsc::channel();
    let mut slots: Vec<Option<Result<Graph>>> = (0..wanted.len()).map(|_| None).collect();
    let mut cancelled = Ok(());
    std::thread::scope(|scope| {
        let mut handles = Vec::with_capacity(workers);
        for _ in 0..workers {
            let done_tx = done_tx.clone();
            let (next, stop, load, order) = (&next, &stop, &load, &order);
            handles.push(scope.spawn(move || loop {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) else {
                    break;
                };
                let (role, spec) = wanted[i];
                if done_tx.send((i, load(role, spec))).is_err() {
                    break;
                }
            }));
        }
        drop(done_tx);
        for (finished, (i, graph)) in done_rx.iter().enumerate() {
            slots[i] = Some(graph);
            if cancelled.is_ok() {
                cancelled = progress::report("loading the bundle", finished as u64 + 1, total);
                if cancelled.is_err() {
                    stop.store(true, Ordering::Relaxed);
                }
            }
        }
        // Join each thread itself: the scope alone returns once the closures are done, while
        // the threads may still be exiting (running their thread-local destructors).
        for handle in handles {
            let _ = handle.join();
        }
    });
    cancelled?;
    slots
        .into_iter()
        .map(|slot| slot.expect("every graph was attempted"))
        .collect()
}

type Positions = (Vec<usize>, Vec<usize>);

/// Matches the graph's inputs and outputs with the manifest's, by name, element type and shape.
fn check_interface(model: &TypedModel, spec: &GraphSpec) -> std::result::Result<Positions, String> {
    let input_names: Vec<String> = model
        .input_outlets()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|o| model.node(o.node).name.clone())
        .collect();
    let output_names: Vec<String> = model
        .output_outlets()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|o| {
            model
                .outlet_label(*o)
                .map(str::to_owned)
                .unwrap_or_else(|| model.node(o.node).name.clone())
        })
        .collect();
    let input_facts: Vec<TypedFact> = (0..input_names.len())
        .map(|i| model.input_fact(i).cloned())
        .collect::<TractResult<_>>()
        .map_err(|e| e.to_string())?;
    let output_facts: Vec<TypedFact> = (0..output_names.len())
        .map(|i| model.output_fact(i).cloned())
        .collect::<TractResult<_>>()
        .map_err(|e| e.to_string())?;
    let inputs = match_tensors("input", &spec.inputs, &input_names, &input_facts)?;
    let outputs = match_tensors("output", &spec.outputs, &output_names, &output_facts)?;
    Ok((inputs, outputs))
}

fn match_tensors(
    kind: &str,
    declared: &[TensorSpec],
    names: &[String],
    facts: &[TypedFact],
) -> std::result::Result<Vec<usize>, String> {
    if let Some(extra) = names
        .iter()
        .find(|n| !declared.iter().any(|d| &d.name == *n))
    {
        return Err(format!(
            "graph {kind} `{extra}` is not declared in the manifest"
        ));
    }
    declared
        .iter()
        .map(|d| {
            let at = names.iter().position(|n| *n == d.name).ok_or_else(|| {
                format!(
                    "graph has no {kind} `{}` (its {kind}s are: {})",
                    d.name,
                    names.join(", ")
                )
            })?;
            let fact = &facts[at];
            let dtype_ok = matches!(
                (d.dtype, fact.datum_type),
                (DType::Float32, DatumType::F32) | (DType::Int64, DatumType::I64)
            );
            let dims_ok = fact.rank() == d.shape.len()
                && d.shape
                    .iter()
                    .zip(fact.shape.iter())
                    .all(|(want, got)| match want {
                        Dim::Fixed(n) => got.to_i64().ok() == Some(*n as i64),
                        Dim::Symbol(_) => got.to_i64().is_err(),
                    });
            if dtype_ok && dims_ok {
                Ok(at)
            } else {
                let dims: Vec<String> = fact.shape.iter().map(|d| d.to_string()).collect();
                Err(format!(
                    "{kind} `{}` is {:?} [{}] in the graph, the manifest declares {d}",
                    d.name,
                    fact.datum_type,
                    dims.join(", ")
                ))
            }
        })
        .collect()
}

/// Builds a float tensor from a shape and row-major data.
pub(crate) fn f32_tensor(shape: &[usize], data: &[f32]) -> TValue {
    // The caller always passes matching sizes; `from_shape` only fails on a mismatch.
    Tensor::from_shape(shape, data)
        .expect("shape matches data")
        .into_tvalue()
}

/// Tells tract that the row counts of a call (the symbols `B`, batch, and `N`, rows or tokens,
/// as every exporter names them) are at least 1. With an unbounded symbol tract cannot prove an
/// element-wise op long enough for its vectorised kernels and runs it one element at a time.
pub(crate) fn assert_row_counts(model: &TypedModel) -> std::result::Result<(), String> {
    for name in ["B", "N"] {
        if model.symbols.get(name).is_some() {
            model
                .symbols
                .add_assertion(format!("{name} >= 1"))
                .map_err(|e| format!("symbol {name}: {e:#}"))?;
        }
    }
    Ok(())
}

/// The model with its row count `B` fixed at 1 (a graph without `B` is returned as it is).
fn with_one_row(model: &TypedModel) -> std::result::Result<TypedModel, String> {
    let Some(rows) = model.symbols.get("B") else {
        return Ok(model.clone());
    };
    let one = std::collections::HashMap::from([(rows, TDim::Val(1))]);
    model
        .set_symbols(&one)
        .map_err(|e| format!("cannot be planned for one row: {e:#}"))
}

/// Gives back to a `float16` graph's matrix products the weights its file stores in 16 bits.
/// Building the graph folds each `Cast` of a float16 initializer into a float32 constant; every
/// matrix-product constant whose values are all float16 values (those, and no float32 weight,
/// since a float32 weight rounded to 16 bits would not be) becomes float16 again, for troupe's
/// float16 products (`shared/half_products.rs`) or, for the products those do not take,
/// tract's float16 × float32 kernels. The values are unchanged.
pub(crate) fn keep_float16_weights(model: &mut TypedModel) -> std::result::Result<(), String> {
    use half::slice::HalfFloatSliceExt;
    use tract_onnx::prelude::f16;
    use tract_onnx::tract_core::ops::einsum::EinSum;
    use tract_onnx::tract_core::ops::konst::Const;
    let mut kept = 0;
    for id in 0..model.nodes.len() {
        let node = &model.nodes[id];
        let Some(konst) = node.op_as::<Const>() else {
            continue;
        };
        let value = konst.val();
        let successors = &node.outputs[0].successors;
        if value.datum_type() != DatumType::F32
            || value.rank() < 2
            || successors.is_empty()
            || !successors
                .iter()
                .all(|s| model.nodes[s.node].op_is::<EinSum>())
        {
            continue;
        }
        let view = value
            .to_plain_array_view::<f32>()
            .map_err(|e| format!("a weight's values: {e:#}"))?;
        let Some(floats) = view.as_slice() else {
            continue;
        };
        // Both conversions run on whole slices (F16C where the CPU has it).
        let mut halves = vec![f16::ZERO; floats.len()];
        halves.convert_from_f32_slice(floats);
        let mut back = vec![0f32; floats.len()];
        halves.convert_to_f32_slice(&mut back);
        if back
            .iter()
            .zip(floats)
            .any(|(a, b)| a.to_bits() != b.to_bits())
        {
            continue;
        }
        let half = Tensor::from_shape(value.shape(), &halves)
            .map_err(|e| format!("a weight in float16: {e:#}"))?
            .into_arc_tensor();
        let fact = TypedFact::try_from(half.clone()).map_err(|e| format!("{e:#}"))?;
        let node = &mut model.nodes[id];
        node.op = Box::new(Const::new(half).map_err(|e| format!("{e:#}"))?);
        node.outputs[0].fact = fact;
        kept += 1;
    }
    if kept == 0 {
        return Err("is declared with float16 weights, but no matrix product uses one".into());
    }
    Ok(())
}

/// Builds a float tensor that takes ownership of row-major `data` (no copy).
pub(crate) fn f32_tensor_owned(shape: &[usize], data: Vec<f32>) -> TValue {
    tract_ndarray::ArrayD::from_shape_vec(shape, data)
        .expect("shape matches data")
        .into_tvalue()
}

/// Stacks float tensors of shape `[1, ...]` (one per stream, all the same shape) into one
/// `[B, ...]` batch; a single row is passed through without copying.
pub(crate) fn stack_rows(role: &'static str, rows: &[&TValue]) -> Result<TValue> {
    let first = rows
        .first()
        .ok_or_else(|| Error::InvalidInput("an empty batch".into()))?;
    if rows.len() == 1 {
        return Ok((*first).clone());
    }
    let shape = first.shape().to_vec();
    let mut data = Vec::with_capacity(rows.len() * first.len());
    for row in rows {
        data.extend_from_slice(read_f32(role, "batch row", row, &shape)?);
    }
    let mut batched = shape;
    batched[0] = rows.len();
    Ok(f32_tensor_owned(&batched, data))
}

/// Splits a `[B, ...]` float tensor into `B` tensors of shape `[1, ...]`; the inverse of
/// [`stack_rows`].
pub(crate) fn split_rows(role: &'static str, batch: TValue, rows: usize) -> Result<Vec<TValue>> {
    if rows == 1 {
        return Ok(vec![batch]);
    }
    let mut shape = batch.shape().to_vec();
    let all = read_f32(role, "batch", &batch, &shape)?;
    let per_row = all.len() / rows.max(1);
    shape[0] = 1;
    Ok(all
        .chunks(per_row)
        .map(|row| f32_tensor(&shape, row))
        .collect())
}

impl Graph {
    /// Runs the graph and returns its first output, named `output` in messages, checked to have
    /// `shape` and finite values.
    pub(crate) fn run_checked(
        &self,
        output: &str,
        inputs: Vec<TValue>,
        shape: &[usize],
    ) -> Result<Vec<f32>> {
        let out = self.run(inputs)?;
        let values = read_f32(self.role(), output, &out[0], shape)?;
        crate::shared::checks::check_output(self.role(), output, values)?;
        Ok(values.to_vec())
    }
}

/// Reads a float tensor's contents, checking its shape.
pub(crate) fn read_f32<'a>(
    role: &'static str,
    what: &str,
    value: &'a TValue,
    shape: &[usize],
) -> Result<&'a [f32]> {
    let fail = |message: String| Error::Inference {
        graph: role,
        message,
    };
    if value.shape() != shape {
        return Err(fail(format!(
            "output `{what}` has shape {:?}, expected {shape:?}",
            value.shape()
        )));
    }
    value
        .try_as_plain_ram()
        .and_then(|v| v.as_slice::<f32>())
        .map_err(|e| fail(format!("output `{what}`: {e:#}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The committed tiny bundle's velocity graph, loaded as troupe loads it.
    fn tiny_velocity() -> PlanRunner {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/onnx/bundles/armflow-tiny/velocity.onnx"
        );
        let plan = tract_onnx::onnx()
            .model_for_path(path)
            .and_then(|m| m.into_typed())
            .and_then(optimised_plan)
            .expect("the tiny velocity graph loads");
        PlanRunner::new(plan).expect("a runner")
    }

    /// Inputs for every input of the plan, `rows` rows, values from `seed`.
    fn inputs(runner: &PlanRunner, rows: usize, seed: f32) -> TVec<TValue> {
        let model = runner.plan().model();
        model
            .input_outlets()
            .expect("inputs")
            .iter()
            .map(|outlet| {
                let fact = model.outlet_fact(*outlet).expect("a fact");
                let shape: Vec<usize> = fact
                    .shape
                    .iter()
                    .map(|d| d.as_i64().map_or(rows, |n| n as usize))
                    .collect();
                let values: Vec<f32> = (0..shape.iter().product::<usize>())
                    .map(|i| (i as f32 * 0.37 + seed).sin())
                    .collect();
                f32_tensor(&shape, &values)
            })
            .collect()
    }

    fn fresh(runner: &PlanRunner, inputs: TVec<TValue>) -> TVec<TValue> {
        let mut state = runner.plan().spawn().expect("a state");
        state
            .run_plan_with_eval(inputs, evaluate_operation)
            .expect("the graph runs")
    }

    fn floats(value: &TValue) -> &[f32] {
        read_f32("test", "output", value, value.shape()).expect("f32")
    }

    fn idle(runner: &PlanRunner) -> usize {
        runner.idle.lock().expect("not poisoned").len()
    }

    #[test]
    fn a_reused_state_gives_what_a_fresh_one_gives() {
        let runner = tiny_velocity();
        assert!(
            runner.reusable,
            "troupe's graphs keep no state between calls"
        );
        for (rows, seed) in [(2, 0.0), (3, 1.0), (2, 0.0), (1, 2.5)] {
            let reused = runner.run(inputs(&runner, rows, seed)).expect("runs");
            let expected = fresh(&runner, inputs(&runner, rows, seed));
            assert_eq!(reused.len(), expected.len());
            for (a, b) in reused.iter().zip(&expected) {
                assert_eq!(a.shape(), b.shape());
                assert_eq!(floats(a), floats(b), "{rows} rows, seed {seed}");
            }
            assert_eq!(idle(&runner), 1, "one caller at a time reuses one state");
        }
    }

    #[test]
    fn a_failed_call_drops_its_state_and_the_next_call_is_unaffected() {
        let runner = tiny_velocity();
        let mut wrong = inputs(&runner, 2, 0.0);
        wrong[0] = f32_tensor(&[2, 3], &[0.0; 6]);
        assert!(runner.run(wrong).is_err(), "a wrong width is refused");
        assert_eq!(idle(&runner), 0, "the failed call's state is not kept");
        let after = runner.run(inputs(&runner, 2, 0.5)).expect("runs");
        let expected = fresh(&runner, inputs(&runner, 2, 0.5));
        assert_eq!(floats(&after[0]), floats(&expected[0]));
        assert_eq!(idle(&runner), 1);
    }
}
