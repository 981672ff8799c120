//! The streaming demo: feed an actor's motion to troupe as a game engine would, tick by tick,
//! write the reactor's motion to `.npy`, and report per-step latency and the real-time factor.
//!
//! ```text
//! cargo run --release --example stream -- [options]
//!   --bundle DIR        model bundle (default: onnx/bundles/armflow-tiny)
//!   --actor FILE.npy    actor motion, float32 [T, frame_dim] (default: a synthetic actor)
//!   --frames N          length of the synthetic actor (default: 600 = 20 s at 30 fps)
//!   --tick N            actor frames per step() call (default: 1, i.e. every frame)
//!   --out FILE.npy      where to write the reactor motion (default: reactor.npy)
//!   --seed S --steps K --cfg X --capacity C     session options
//!   --warmup-tokens H   tokens streamed before timing starts (to time at a given history)
//!   --vae-windows       run the VAE over windows even when the bundle has per-token steps
//! ```

use std::time::Instant;

use ndarray::{s, Array2};
use ndarray_npy::{read_npy, write_npy};
use troupe::{Model, SessionOptions};

mod common;
use common::{percentile, synthetic_actor};

struct Args {
    bundle: String,
    actor: Option<String>,
    frames: usize,
    tick: usize,
    out: String,
    options: SessionOptions,
    warmup_tokens: u64,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        bundle: concat!(env!("CARGO_MANIFEST_DIR"), "/onnx/bundles/armflow-tiny").into(),
        actor: None,
        frames: 600,
        tick: 1,
        out: "reactor.npy".into(),
        options: SessionOptions::default(),
        warmup_tokens: 0,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let num = |v: String| v.parse::<f64>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--bundle" => a.bundle = value()?,
            "--actor" => a.actor = Some(value()?),
            "--frames" => a.frames = num(value()?)? as usize,
            "--tick" => a.tick = (num(value()?)? as usize).max(1),
            "--out" => a.out = value()?,
            "--seed" => a.options.seed = num(value()?)? as u64,
            "--steps" => a.options.steps = Some(num(value()?)? as u32),
            "--cfg" => a.options.cfg_scale = Some(num(value()?)? as f32),
            "--capacity" => a.options.context_capacity = Some(num(value()?)? as usize),
            "--warmup-tokens" => a.warmup_tokens = num(value()?)? as u64,
            "--vae-windows" => a.options.vae_windows = true,
            "-h" | "--help" => {
                println!("see the top of examples/stream.rs for the options");
                std::process::exit(0);
            }
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok(a)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let t0 = Instant::now();
    let model = Model::load(&args.bundle)?;
    let mut session = model.session(args.options.clone())?;
    let load_ms = t0.elapsed().as_secs_f64() * 1e3;
    let actor: Array2<f32> = match &args.actor {
        Some(path) => read_npy(path)?,
        None => synthetic_actor(args.frames, model.frame_dim()),
    };
    println!(
        "bundle {} ({}): {} features at {} fps, {} frames per token, latency {} frames; loaded in {load_ms:.0} ms",
        args.bundle,
        model.manifest().name,
        model.frame_dim(),
        model.fps(),
        model.frames_per_token(),
        model.latency_frames()
    );

    let mut reactor = Vec::with_capacity(actor.len());
    let (mut all_calls, mut token_calls) = (Vec::new(), Vec::new());
    let mut timed = 0.0f64;
    let mut start = 0;
    while start < actor.nrows() {
        let end = (start + args.tick).min(actor.nrows());
        let warm = session.tokens_generated() >= args.warmup_tokens;
        let t = Instant::now();
        let out = session.step(actor.slice(s![start..end, ..]))?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        if warm {
            timed += ms;
            all_calls.push(ms);
            if out.nrows() > 0 {
                token_calls.push(ms);
            }
        }
        reactor.extend(out.iter().copied());
        start = end;
    }
    let n = reactor.len() / model.frame_dim();
    write_npy(
        &args.out,
        &Array2::from_shape_vec((n, model.frame_dim()), reactor)?,
    )?;

    for v in [&mut all_calls, &mut token_calls] {
        v.sort_by(f64::total_cmp);
    }
    let timed_frames = all_calls.len() as f64 * args.tick as f64;
    println!(
        "streamed {} actor frames in ticks of {}, wrote {n} reactor frames to {}",
        actor.nrows(),
        args.tick,
        args.out
    );
    for (what, v) in [
        ("every call", &all_calls),
        ("calls that produced a token", &token_calls),
    ] {
        println!(
            "step latency, {what} ({} calls): p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms",
            v.len(),
            percentile(v, 0.5),
            percentile(v, 0.99),
            v.last().copied().unwrap_or(f64::NAN)
        );
    }
    let motion_ms = timed_frames / f64::from(model.fps()) * 1e3;
    println!(
        "real-time factor {:.1}x ({:.0} ms of motion computed in {timed:.0} ms; context holds {} tokens)",
        motion_ms / timed,
        motion_ms,
        session.context_len()
    );
    Ok(())
}
