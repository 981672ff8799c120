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
//!   --html FILE.html      also the first sample as an HTML player (people posed on the t2m-22
//!                         skeleton: troupe's neutral bone lengths, not the SMPL-X betas)
//!   --live                stream the clip instead: person 0 is the user, person 1's first
//!                         frames the partner's opening, through a live partner session
//!                         (`--steps`, `--seed` and `--no-x0-guidance` apply; `--early` sends
//!                         each chunk as it is generated)
//!   --compute-threads N   threads the matrix products may split over (default 1: this thread)
//! ```

use std::path::Path;
use std::time::Instant;

use ndarray::{s, Array2, Array3, Axis};
use ndarray_npy::{read_npy, write_npy};
use troupe::motion::{smplx145_positions, Skeleton};
use troupe::viewer::Scene;
use troupe::{MagnetOptions, Model, PartnerOptions};

struct Args {
    bundle: String,
    config: String,
    frames: Option<String>,
    options: MagnetOptions,
    list: bool,
    out: String,
    html: Option<String>,
    live: bool,
    early: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        bundle: concat!(env!("CARGO_MANIFEST_DIR"), "/onnx/bundles/magnet-tiny").into(),
        config: "dd100".into(),
        frames: None,
        options: MagnetOptions::default(),
        list: false,
        out: "magnet.npy".into(),
        html: None,
        live: false,
        early: false,
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
            "--compute-threads" => {
                troupe::set_compute_threads(num(value()?)? as usize).map_err(|e| e.to_string())?
            }
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
            "--html" => a.html = Some(value()?),
            "--live" => a.live = true,
            "--early" => a.early = true,
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
    // Another family's bundle is refused here, naming the family it is.
    let magnet = model.magnet()?;
    let spec = magnet.spec();
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
    if args.live {
        return live(&model, &args, frames);
    }
    let shape = magnet.output_shape(&args.config, frames.shape()[0], &args.options)?;
    println!(
        "running `{}` on {} input frames: {} samples x {} frames x {} people",
        args.config,
        frames.shape()[0],
        shape[0],
        shape[1],
        shape[2]
    );
    let t = Instant::now();
    let out = magnet.generate(&args.config, frames.view(), None, &args.options)?;
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
    if let Some(html) = &args.html {
        let first = out.frames.index_axis(Axis(0), 0);
        let people: Vec<(String, Array2<f32>)> = (0..shape[2])
            .map(|p| (format!("person {p}"), first.slice(s![.., p, ..]).to_owned()))
            .collect();
        write_player(html, &args.config, &people)?;
    }
    Ok(())
}

/// The live partner: the clip's person 0 streams in as the user, frame by frame, as an engine
/// would feed it; the partner's frames come out chunk by chunk.
fn live(model: &Model, args: &Args, frames: Array3<f32>) -> Result<(), Box<dyn std::error::Error>> {
    let magnet = model.magnet()?;
    let mut options = PartnerOptions {
        seed: args.options.seed.unwrap_or(1111),
        steps: args.options.steps.map(|s| s as u32),
        early_emission: args.early,
        ..Default::default()
    };
    if args.options.without_x0_guidance {
        let mut cfg = magnet.live_configuration()?;
        cfg.guidance.smoothing = None;
        cfg.guidance.foot_skating = None;
        options.live_config = Some(serde_json::to_string(&cfg)?);
    }
    let context = magnet.live_configuration()?.context_len;
    options.opening = Some(frames.slice(s![..context, 1, ..]).iter().copied().collect());
    let mut session = model.session(options)?;
    println!(
        "live partner: {} user frames in, algorithmic latency {} frames",
        frames.shape()[0],
        session.latency_frames()
    );
    let mut partner = Vec::new();
    for t in 0..frames.shape()[0] {
        let started = Instant::now();
        let out = session.step(frames.slice(s![t..t + 1, 0, ..]))?;
        if out.nrows() > 0 {
            println!(
                "  user frame {t}: {} partner frames in {:.0} ms",
                out.nrows(),
                started.elapsed().as_secs_f64() * 1e3
            );
            partner.extend(out.iter().copied());
        }
    }
    let partner = Array2::from_shape_vec((partner.len() / 145, 145), partner)?;
    write_npy(&args.out, &partner)?;
    println!("wrote {} {:?}", args.out, partner.shape());
    if let Some(html) = &args.html {
        let n = partner.nrows();
        let user = frames.slice(s![..n, 0, ..]).to_owned();
        write_player(
            html,
            "live partner",
            &[("user".into(), user), ("partner".into(), partner)],
        )?;
    }
    Ok(())
}

/// Poses each person's frames `[F, 145]` on the t2m-22 skeleton and writes the HTML player.
fn write_player(
    path: &str,
    title: &str,
    people: &[(String, Array2<f32>)],
) -> Result<(), Box<dyn std::error::Error>> {
    let skeleton = Skeleton::t2m22();
    let mut scene = Scene::new(30.0, format!("MAGNet: {title}"))?;
    for (name, frames) in people {
        let flat = frames.as_standard_layout();
        let joints = smplx145_positions(flat.as_slice().expect("standard layout"), &skeleton)?;
        let values: Vec<f32> = joints
            .iter()
            .flatten()
            .flatten()
            .map(|v| *v as f32)
            .collect();
        let positions = Array3::from_shape_vec((joints.len(), 22, 3), values)?;
        scene.add_person(name.as_str(), positions.view())?;
    }
    scene.write_html(path)?;
    println!("wrote {path} (open it in a browser)");
    Ok(())
}
