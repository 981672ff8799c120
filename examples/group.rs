//! Text-to-group demo: generate a group's motion with a `umf` bundle, write it to `.npy`
//! (`[people, frames, frame_dim]`), and report the time per generation.
//!
//! ```text
//! cargo run --release --example group -- [options]
//!   --bundle DIR           umf bundle (default: onnx/bundles/umf-tiny)
//!   --people N             people in the group (default: 2)
//!   --condition FILE.npy   condition vector, float32 [condition_dim] (default: the null condition)
//!   --prior M:S,M:S        solver per pyramid stage, M = euler | rk4 (default: the bundle's)
//!   --reaction M:S         solver of each further person (default: the bundle's)
//!   --cfg X --seed S       guidance scale, seed
//!   --runs N               timed generations after one warm-up (default: 1)
//!   --out FILE.npy         where to write the motion (default: group.npy)
//! ```

use std::time::Instant;

use ndarray::Array1;
use ndarray_npy::{read_npy, write_npy};
use troupe::{GroupOptions, Method, Model, Solver};

struct Args {
    bundle: String,
    people: usize,
    condition: Option<String>,
    options: GroupOptions,
    runs: usize,
    out: String,
}

fn parse_solver(text: &str) -> Result<Solver, String> {
    let (method, steps) = text
        .split_once(':')
        .ok_or(format!("solver `{text}` is not METHOD:STEPS"))?;
    let method = match method {
        "euler" => Method::Euler,
        "rk4" => Method::Rk4,
        other => return Err(format!("unknown solver method `{other}` (euler or rk4)")),
    };
    let steps = steps
        .parse()
        .map_err(|e| format!("steps of `{text}`: {e}"))?;
    Ok(Solver { method, steps })
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        bundle: concat!(env!("CARGO_MANIFEST_DIR"), "/onnx/bundles/umf-tiny").into(),
        people: 2,
        condition: None,
        options: GroupOptions::default(),
        runs: 1,
        out: "group.npy".into(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let num = |v: String| v.parse::<f64>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--bundle" => a.bundle = value()?,
            "--people" => a.people = num(value()?)? as usize,
            "--condition" => a.condition = Some(value()?),
            "--prior" => {
                a.options.prior = Some(
                    value()?
                        .split(',')
                        .map(parse_solver)
                        .collect::<Result<_, _>>()?,
                )
            }
            "--reaction" => a.options.reaction = Some(parse_solver(&value()?)?),
            "--cfg" => a.options.cfg_scale = Some(num(value()?)? as f32),
            "--seed" => a.options.seed = num(value()?)? as u64,
            "--runs" => a.runs = (num(value()?)? as usize).max(1),
            "--out" => a.out = value()?,
            "-h" | "--help" => {
                println!("see the top of examples/group.rs for the options");
                std::process::exit(0);
            }
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok(a)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let started = Instant::now();
    let model = Model::load(&args.bundle)?;
    let load_ms = started.elapsed().as_secs_f64() * 1e3;
    let condition: Option<Array1<f32>> = match &args.condition {
        Some(path) => Some(read_npy(path)?),
        None => None,
    };
    let condition = condition.as_ref().map(|c| c.to_vec());
    // An `armflow` or `magnet` bundle is refused here, naming the family it is.
    let umf = model.umf()?;
    let spec = umf.spec();
    let prior = args
        .options
        .prior
        .clone()
        .unwrap_or_else(|| spec.sampler.prior.clone());
    let reaction = args.options.reaction.unwrap_or(spec.sampler.reaction);
    println!(
        "bundle `{}` loaded in {load_ms:.0} ms; {} people, prior {:?}, reaction {:?}",
        model.manifest().name,
        args.people,
        prior
            .iter()
            .map(|s| format!("{:?}:{}", s.method, s.steps))
            .collect::<Vec<_>>(),
        format!("{:?}:{}", reaction.method, reaction.steps),
    );

    // One untimed generation (first-call allocations), then the timed runs.
    let mut group = umf.generate_group(condition.as_deref(), args.people, &args.options)?;
    let mut times = Vec::with_capacity(args.runs);
    for _ in 0..args.runs {
        let t = Instant::now();
        group = umf.generate_group(condition.as_deref(), args.people, &args.options)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let (people, frames, dim) = group.motion.dim();
    write_npy(&args.out, &group.motion)?;
    println!(
        "{people} people x {frames} frames x {dim} features -> {}",
        args.out
    );
    println!(
        "generation over {} runs: median {median:.2} ms, min {:.2} ms, max {:.2} ms ({:.1} s of motion per person)",
        times.len(),
        times[0],
        times[times.len() - 1],
        frames as f64 / f64::from(model.fps())
    );
    Ok(())
}
