//! MAGNet demo: run one of a `magnet` bundle's sampling configurations on a clip of troupe
//! frames (`[frames, people, 145]`: betas, the 21 body joints' 6-D rotations, the root's pose in
//! the world), write what it generates to `.npy` (`[samples, frames, people, 145]`), and report
//! the time.
//!
//! ```text
//! cargo run --release --example magnet -- [options]
//!   --bundle DIR          magnet bundle (default: onnx/bundles/magnet-tiny)
//!   --config NAME         a released configuration (default: dd100); --list prints them
//!   --frames FILE.npy     the input clip, float32 [frames, people, 145] (default: the bundle's
//!                         golden clip if it has one, else people walking)
//!   --samples S --steps N --seq-len F --seed X --eta E
//!                         change the configuration for this run
//!   --no-x0-guidance      the decoder-space corrections off (not the released behaviour)
//!   --keyframes A,B       in-betweening's key frames
//!   --out FILE.npy        where to write the frames (default: magnet.npy)
//! ```

use std::path::Path;
use std::time::Instant;

use ndarray::Array3;
use ndarray_npy::{read_npy, write_npy};
use troupe::{MagnetOptions, Model};

struct Args {
    bundle: String,
    config: String,
    frames: Option<String>,
    options: MagnetOptions,
    list: bool,
    out: String,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        bundle: concat!(env!("CARGO_MANIFEST_DIR"), "/onnx/bundles/magnet-tiny").into(),
        config: "dd100".into(),
        frames: None,
        options: MagnetOptions::default(),
        list: false,
        out: "magnet.npy".into(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let num = |v: String| v.parse::<f64>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--bundle" => a.bundle = value()?,
            "--config" => a.config = value()?,
            "--frames" => a.frames = Some(value()?),
            "--samples" => a.options.samples = Some(num(value()?)? as usize),
            "--steps" => a.options.steps = Some(num(value()?)? as usize),
            "--seq-len" => a.options.seq_len = Some(num(value()?)? as usize),
            "--seed" => a.options.seed = Some(num(value()?)? as u64),
            "--eta" => a.options.eta = Some(num(value()?)? as f32),
            "--no-x0-guidance" => a.options.without_x0_guidance = true,
            "--keyframes" => {
                a.options.keyframes = Some(
                    value()?
                        .split(',')
                        .map(|k| k.parse().map_err(|e| format!("--keyframes: {e}")))
                        .collect::<Result<_, _>>()?,
                )
            }
            "--list" => a.list = true,
            "--out" => a.out = value()?,
            "-h" | "--help" => {
                println!("see the top of examples/magnet.rs for the options");
                std::process::exit(0);
            }
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok(a)
}

/// People walking side by side, a metre and a half apart, turning slowly, arms swinging: troupe
/// frames `[frames, people, 145]`.
fn walking(frames: usize, people: usize) -> Array3<f32> {
    let mut out = Array3::zeros((frames, people, 145));
    for t in 0..frames {
        let time = t as f32 / 30.0;
        for p in 0..people {
            let heading = 0.2 * time + p as f32 * 0.1;
            let (s, c) = heading.sin_cos();
            let mut row = out.slice_mut(ndarray::s![t, p, ..]);
            for j in 0..21 {
                // A small swing about x per joint: the 6-D of [[1,0,0],[0,cos,-sin],[0,sin,cos]].
                let a = 0.3 * (2.0 * time + j as f32).sin();
                let at = 10 + j * 6;
                let six = [1.0, 0.0, 0.0, 0.0, a.cos(), a.sin()];
                for (i, v) in six.iter().enumerate() {
                    row[at + i] = *v;
                }
            }
            // Root: heading about y, walking forward along its x axis.
            let rot = [c, 0.0, -s, 0.0, 1.0, 0.0];
            for (i, v) in rot.iter().enumerate() {
                row[136 + i] = *v;
            }
            let side = 1.5 * p as f32;
            row[142] = 0.8 * time * c - side * s;
            row[143] = 0.9;
            row[144] = -0.8 * time * s - side * c;
        }
    }
    out
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let started = Instant::now();
    let model = Model::load(&args.bundle)?;
    let load_ms = started.elapsed().as_secs_f64() * 1e3;
    let spec = model
        .magnet_spec()
        .ok_or("this demo needs a `magnet` bundle (see onnx/README.md)")?;
    let people = spec.model.persons;
    println!(
        "bundle `{}` loaded in {load_ms:.0} ms: {people} people, configurations {}",
        model.manifest().name,
        spec.sampling.keys().cloned().collect::<Vec<_>>().join(", ")
    );
    if args.list {
        for (name, cfg) in &spec.sampling {
            println!(
                "  {name}: {} with {} steps, {} samples, {} frames",
                cfg.task.name(),
                cfg.steps,
                cfg.samples,
                cfg.seq_len
            );
        }
        return Ok(());
    }
    let golden = Path::new(&args.bundle).join("golden/frames.npy");
    let frames: Array3<f32> = match &args.frames {
        Some(path) => read_npy(path)?,
        None if golden.exists() => read_npy(&golden)?,
        None => walking(256, people),
    };
    let shape = model.magnet_output_shape(&args.config, frames.shape()[0], &args.options)?;
    println!(
        "running `{}` on {} input frames: {} samples x {} frames x {} people",
        args.config,
        frames.shape()[0],
        shape[0],
        shape[1],
        shape[2]
    );
    let t = Instant::now();
    let out = model.magnet_generate(&args.config, frames.view(), None, &args.options)?;
    let seconds = t.elapsed().as_secs_f64();
    let finite = out.frames.iter().all(|v| v.is_finite());
    println!(
        "generated in {seconds:.2} s ({} draws): {:.1} ms per output frame and sample; every value finite: {finite}",
        out.draws,
        seconds * 1e3 / (shape[0] * shape[1]) as f64
    );
    write_npy(&args.out, &out.frames)?;
    println!("wrote {} {:?}", args.out, out.frames.shape());
    if !finite {
        return Err("the output holds non-finite values".into());
    }
    Ok(())
}
