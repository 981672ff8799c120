//! The streaming demo: feed an actor's motion to troupe as a game engine would, tick by tick,
//! get the reactor's motion back, write it to `.npy` with a picture beside it (an HTML player and
//! a GIF of actor and reactor), and report per-step latency and the real-time factor.
//!
//! By default the model is troupe's trained demo (`onnx/bundles/armflow-demo`: an ARMFlow trained
//! on real motion capture to be a rule-defined partner, docs/DEMO.md), the actor is 8 s of real
//! motion capture it never saw (a CMU subject, `tests/data/mocap/`) given as joint positions, and
//! the reactor comes back as joint positions in the same world. The demo then prints how far the
//! reactor is from what the rule says (mean per-joint error).
//!
//! ```text
//! cargo run --release --example stream -- [options]
//!   --bundle DIR        model bundle (default: onnx/bundles/armflow-demo)
//!   --rule NAME         a named condition of the bundle (the demo's partner rules: mirror,
//!                       follow, keep-away; default: mirror for bundles that have labels)
//!   --joints FILE       actor joint positions: a .bvh or .fbx file, or .npy float32 [T, 22, 3]
//!                       (t2m-22)
//!                       (default: tests/data/mocap/cmu-playground-120fps.npy, metres, z up, 120 fps)
//!   --units m|cm|mm|in --up y|z --fps N     how a .npy's positions are measured
//!   --actor FILE.npy    actor *features* instead, float32 [T, frame_dim]
//!   --synthetic         a synthetic actor in feature space (for timing at any --frames)
//!   --frames N          at most N actor frames (synthetic: exactly N; default 600)
//!   --tick N            actor frames per step call (default: 1, i.e. every frame)
//!   --out FILE.npy      the reactor's motion: joint positions [T, 22, 3] in the actor's world
//!                       (features [T, frame_dim] for --actor/--synthetic); FILE.html and
//!                       FILE.gif beside it (default: reactor.npy)
//!   --no-pictures       skip the HTML player and GIF
//!   --gltf FILE.glb     also write actor and reactor as glTF (skinned bodies, one animation),
//!                       on --rig or on troupe's own body (docs/RIGS.md)
//!   --fbx FILE.fbx      also write the reactor as FBX on --rig or on troupe's own body
//!                       (binary FBX 7.4, centimetres, Y up: Blender, Unity, Unreal, Maya)
//!   --rig FILE          your character: a .bvh or .fbx (its skeleton), a .glb/.gltf (its
//!                       first skin) or a rig .json; the reactor is
//!                       retargeted onto it as it streams (the time it takes is reported)
//!   --rig-rest-frame N  the rig .bvh's frame whose pose is its rest pose (default: all zeros)
//!   --joint-map FILE    which joint of your rigs (the actor .bvh, --rig) is which t2m-22 joint
//!                       (JSON; default: the built-in names)
//!   --no-guard          turn off the penetration guard (on by default: the reactor is kept out
//!                       of the actor's body, docs/DEMO.md)
//!   --no-foot-lock      turn off the foot lock (on by default: a foot whose contact label is on
//!                       stays put)
//!   --no-smoothing      turn off the root smoothing (on by default: 0.1 s, against jitter)
//!   --no-recentring     turn off recentring (on by default: the networks' frame follows the
//!                       actor once it is 1 m from its centre, so a long walk stays near where
//!                       the model was trained)
//!   --seed S --steps K --cfg X --capacity C     session options
//!   --warmup-tokens H   tokens streamed before timing starts (to time at a given history)
//!   --vae-windows       run the VAE over windows even when the bundle has per-token steps
//!                       (recentring, which needs the steps, is then off)
//!   --compute-threads N threads the matrix products may split over (default 1: this thread)
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use ndarray::{s, Array2, Array3, ArrayView3, Axis};
use ndarray_npy::{read_npy, write_npy};
use troupe::motion::fbx::{write_rig_fbx_file, FbxWriteOptions};
use troupe::motion::resample::Resampler;
use troupe::motion::{
    decode_frame, read_gltf_rig_file, read_motion_file, retarget_clip, write_glb_file, GltfOptions,
    GltfPerson, JointMap, JointsFormat, Placement, Pose, RetargetOptions, Retargeter, Rig, RigPose,
    Skeleton, SourceFrame, Units, UpAxis, T2M22_JOINTS,
};
use troupe::viewer::{GifOptions, Scene};
use troupe::{FootLockOptions, Model, PenetrationGuard, ReactorOptions, Recentring, RootSmoothing};

mod common;
use common::{percentile, synthetic_actor};

/// The guard as the demo runs it, tuned for the demo model on the held-out takes (docs/DEMO.md):
/// a 0.25 m margin and up to 10 m/s leave no frame with the bodies intersecting and the roots at
/// least 0.3 m apart at the least cost in error; the defaults (0.05 m, 2 m/s) cannot keep up
/// with a partner that jumps.
const DEMO_GUARD: PenetrationGuard = PenetrationGuard {
    d_safe: 0.25,
    max_speed: 10.0,
};

/// Where the actor comes from.
enum Source {
    Joints(PathBuf),
    Features(PathBuf),
    Synthetic,
}

struct Args {
    bundle: String,
    rule: Option<String>,
    source: Source,
    units: Option<Units>,
    up: Option<UpAxis>,
    fps: Option<f32>,
    frames: Option<usize>,
    tick: usize,
    out: PathBuf,
    pictures: bool,
    options: ReactorOptions,
    /// The session's clean-ups (every streaming family's).
    guard: Option<PenetrationGuard>,
    smoothing: Option<RootSmoothing>,
    foot_lock: Option<FootLockOptions>,
    warmup_tokens: u64,
    gltf: Option<PathBuf>,
    fbx: Option<PathBuf>,
    rig: Option<PathBuf>,
    rig_rest_frame: Option<usize>,
    joint_map: Option<PathBuf>,
}

const DEFAULT_CLIP: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/mocap/cmu-playground-120fps.npy"
);

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        bundle: concat!(env!("CARGO_MANIFEST_DIR"), "/onnx/bundles/armflow-demo").into(),
        rule: None,
        source: Source::Joints(DEFAULT_CLIP.into()),
        units: None,
        up: None,
        fps: None,
        frames: None,
        tick: 1,
        out: "reactor.npy".into(),
        pictures: true,
        // What a partner needs on screen: never through the actor, feet that stay put.
        options: ReactorOptions {
            recentring: Some(Recentring::default()),
            ..ReactorOptions::default()
        },
        guard: Some(DEMO_GUARD),
        smoothing: Some(RootSmoothing::default()),
        foot_lock: Some(FootLockOptions::default()),
        warmup_tokens: 0,
        gltf: None,
        fbx: None,
        rig: None,
        rig_rest_frame: None,
        joint_map: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let num = |v: String| v.parse::<f64>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--bundle" => a.bundle = value()?,
            "--rule" => a.rule = Some(value()?),
            "--joints" => a.source = Source::Joints(value()?.into()),
            "--actor" => a.source = Source::Features(value()?.into()),
            "--synthetic" => a.source = Source::Synthetic,
            "--units" => {
                a.units = Some(match value()?.as_str() {
                    "m" => Units::Meters,
                    "cm" => Units::Centimeters,
                    "mm" => Units::Millimeters,
                    "in" => Units::Inches,
                    other => return Err(format!("--units {other}: m, cm, mm or in")),
                })
            }
            "--up" => {
                a.up = Some(match value()?.as_str() {
                    "y" => UpAxis::Y,
                    "z" => UpAxis::Z,
                    other => return Err(format!("--up {other}: y or z")),
                })
            }
            "--fps" => a.fps = Some(num(value()?)? as f32),
            "--frames" => a.frames = Some(num(value()?)? as usize),
            "--tick" => a.tick = (num(value()?)? as usize).max(1),
            "--out" => a.out = value()?.into(),
            "--no-pictures" => a.pictures = false,
            "--gltf" => a.gltf = Some(value()?.into()),
            "--fbx" => a.fbx = Some(value()?.into()),
            "--rig" => a.rig = Some(value()?.into()),
            "--rig-rest-frame" => a.rig_rest_frame = Some(num(value()?)? as usize),
            "--joint-map" => a.joint_map = Some(value()?.into()),
            "--seed" => a.options.seed = num(value()?)? as u64,
            "--steps" => a.options.steps = Some(num(value()?)? as u32),
            "--cfg" => a.options.cfg_scale = Some(num(value()?)? as f32),
            "--capacity" => a.options.context_capacity = Some(num(value()?)? as usize),
            "--warmup-tokens" => a.warmup_tokens = num(value()?)? as u64,
            "--vae-windows" => {
                a.options.vae_windows = true;
                a.options.recentring = None;
            }
            "--no-guard" => a.guard = None,
            "--no-foot-lock" => a.foot_lock = None,
            "--no-smoothing" => a.smoothing = None,
            "--no-recentring" => a.options.recentring = None,
            "--compute-threads" => {
                troupe::set_compute_threads(num(value()?)? as usize).map_err(|e| e.to_string())?
            }
            "-h" | "--help" => {
                println!("see the top of examples/stream.rs for the options");
                std::process::exit(0);
            }
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok(a)
}

/// The actor's joint positions `[T, 22, 3]` and how they are measured.
fn load_joints(path: &Path, a: &Args) -> Result<(Array3<f32>, JointsFormat), troupe::Error> {
    let (positions, mut format) = if path.extension().is_some_and(|e| e == "bvh" || e == "fbx") {
        let label = path.display().to_string();
        let clip = read_motion_file(path, a.units)?;
        let joints = clip.to_t2m22(&joint_map(a)?, a.units, &label)?;
        (joints.positions, joints.format)
    } else {
        let positions: Array3<f32> = read_npy(path)
            .map_err(|e| troupe::Error::InvalidInput(format!("{}: {e}", path.display())))?;
        // The default clip is CMU's: metres, z up, 120 fps.
        let default_clip = path == Path::new(DEFAULT_CLIP);
        let format = JointsFormat {
            units: a.units.unwrap_or(Units::Meters),
            up: a
                .up
                .unwrap_or(if default_clip { UpAxis::Z } else { UpAxis::Y }),
            fps: a.fps.unwrap_or(if default_clip { 120.0 } else { 30.0 }),
            ..JointsFormat::default()
        };
        (positions, format)
    };
    if let Some(up) = a.up {
        format.up = up;
    }
    Ok((positions, format))
}

/// The joint map of `--joint-map`, or the built-in one.
fn joint_map(a: &Args) -> Result<JointMap, troupe::Error> {
    match &a.joint_map {
        Some(path) => JointMap::from_json(&std::fs::read_to_string(path).map_err(|e| {
            troupe::Error::InvalidInput(format!("--joint-map {}: {e}", path.display()))
        })?),
        None => Ok(JointMap::builtin()),
    }
}

/// The character of `--rig` (a .bvh or .fbx skeleton, a glTF file's first skin or a rig
/// .json), or troupe's own body.
fn load_rig(a: &Args) -> Result<Rig, troupe::Error> {
    let Some(path) = &a.rig else {
        return Ok(Rig::t2m22());
    };
    let label = path.display().to_string();
    if path.extension().is_some_and(|e| e == "glb" || e == "gltf") {
        read_gltf_rig_file(path, 0)
    } else if path.extension().is_some_and(|e| e == "bvh" || e == "fbx") {
        let bvh = read_motion_file(path, None)?;
        match a.rig_rest_frame {
            Some(frame) => bvh.rig_at_frame(frame, None, &label),
            None => bvh.rig(None, &label),
        }
    } else {
        Rig::from_json(
            &std::fs::read_to_string(path)
                .map_err(|e| troupe::Error::InvalidInput(format!("--rig {label}: {e}")))?,
        )
    }
}

/// A clip in the caller's world `[T, 22, 3]` in troupe's canonical axes.
fn canonical_clip(clip: ArrayView3<f32>, format: &JointsFormat) -> Vec<Vec<[f64; 3]>> {
    clip.outer_iter()
        .map(|f| {
            f.outer_iter()
                .map(|p| format.to_canonical_axes([p[0], p[1], p[2]]))
                .collect()
        })
        .collect()
}

/// Positions of poses `[T, 22, 3]`.
fn pose_positions(poses: &[Pose]) -> Array3<f32> {
    Array3::from_shape_fn((poses.len(), T2M22_JOINTS, 3), |(t, j, d)| {
        poses[t].positions[j][d]
    })
}

/// `clip` at `fps` frames per second (for the picture, which plays both people at one rate).
fn resampled(clip: ArrayView3<f32>, from: f32, to: f32) -> Array3<f32> {
    let mut resampler = Resampler::new(from, to);
    let mut out = Vec::new();
    for frame in clip.outer_iter() {
        let f = frame
            .outer_iter()
            .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
            .collect();
        resampler.push(f, &mut out);
    }
    Array3::from_shape_fn((out.len(), T2M22_JOINTS, 3), |(t, j, d)| {
        out[t][j][d] as f32
    })
}

struct Timing {
    all_calls: Vec<f64>,
    token_calls: Vec<f64>,
    timed_ms: f64,
    timed_frames: usize,
}

impl Timing {
    fn record(&mut self, ms: f64, frames_in: usize, produced: bool) {
        self.timed_ms += ms;
        self.timed_frames += frames_in;
        self.all_calls.push(ms);
        if produced {
            self.token_calls.push(ms);
        }
    }
}

/// The rule's partner of the default clip, when the demo streams it (`onnx/cli.py demo partners`).
fn rule_partner(path: &Path, rule: &str) -> Option<Array3<f32>> {
    if path != Path::new(DEFAULT_CLIP) {
        return None;
    }
    read_npy(path.with_file_name(format!("cmu-playground.{rule}.npy"))).ok()
}

/// Mean distance (cm) between the joints of `a` and `b` over their common frames.
fn mpjpe_cm(a: ArrayView3<f32>, b: ArrayView3<f32>) -> f64 {
    let n = a.shape()[0].min(b.shape()[0]);
    let mut sum = 0.0;
    for t in 0..n {
        for j in 0..T2M22_JOINTS {
            let d: f64 = (0..3)
                .map(|k| f64::from(a[[t, j, k]] - b[[t, j, k]]).powi(2))
                .sum();
            sum += d.sqrt();
        }
    }
    100.0 * sum / (n * T2M22_JOINTS).max(1) as f64
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = parse_args()?;
    let t0 = Instant::now();
    let model = Model::load(&args.bundle)?;
    let rule = args.rule.clone().or_else(|| {
        let labels = model.condition_labels();
        labels.first().map(|l| l.name.clone())
    });
    if let Some(rule) = &rule {
        args.options.condition = Some(model.condition_for(rule)?);
    }
    let mut session = model.session(args.options.clone())?;
    session.set_penetration_guard(args.guard)?;
    session.set_root_smoothing(args.smoothing)?;
    session.set_foot_lock(args.foot_lock)?;
    let load_ms = t0.elapsed().as_secs_f64() * 1e3;
    println!(
        "bundle {} ({}): {} features at {} fps, {} frames per token, latency {} frames ({} from joint positions); loaded in {load_ms:.0} ms",
        args.bundle,
        model.manifest().name,
        model.frame_dim(),
        model.fps(),
        model.frames_per_token(),
        model.latency_frames(),
        model.joints_latency_frames(),
    );
    println!("attention kernel: {}", troupe::attention_kernel());
    println!("kernels: {}", troupe::kernels());
    let on = |yes: bool| if yes { "on" } else { "off" };
    println!(
        "root smoothing {}, penetration guard {}, foot lock {}, recentring {}",
        on(args.smoothing.is_some()),
        on(args.guard.is_some()),
        on(args.foot_lock.is_some()),
        on(args.options.recentring.is_some())
    );
    let reduced = model.manifest().reduced_precision_graphs();
    if !reduced.is_empty() {
        let graphs: Vec<String> = reduced
            .iter()
            .map(|(role, w)| format!("{role} {}", w.name()))
            .collect();
        println!("reduced-precision weights: {}", graphs.join(", "));
    }
    let mut timing = Timing {
        all_calls: Vec::new(),
        token_calls: Vec::new(),
        timed_ms: 0.0,
        timed_frames: 0,
    };
    let html = args.out.with_extension("html");
    let gif = args.out.with_extension("gif");
    let scene_title = match &rule {
        Some(rule) => format!("troupe: {} ({rule}) reacting", model.manifest().name),
        None => format!("troupe: {} reacting", model.manifest().name),
    };

    let (input_frames, input_fps, scene) = match &args.source {
        Source::Joints(path) => {
            let (all, format) = load_joints(path, &args)?;
            let n = args.frames.unwrap_or(all.shape()[0]).min(all.shape()[0]);
            let actor = all.slice(s![..n, .., ..]);
            session.set_joints_format(format)?;
            // The reactor retargeted onto the character as it streams (with --gltf, --fbx or
            // --rig).
            let rig = load_rig(&args)?;
            let map = joint_map(&args)?;
            let mut retargeter = if args.gltf.is_some() || args.fbx.is_some() || args.rig.is_some()
            {
                let options = RetargetOptions {
                    fps: model.fps() as f32,
                    ..RetargetOptions::default()
                };
                Some(Retargeter::new(&rig, &map, &Skeleton::t2m22(), options)?)
            } else {
                None
            };
            let (mut rig_poses, mut retarget_ms): (Vec<RigPose>, f64) = (Vec::new(), 0.0);
            let mut reactor: Vec<Pose> = Vec::new();
            for chunk in actor.axis_chunks_iter(Axis(0), args.tick) {
                let warm = session.tokens_generated() >= args.warmup_tokens;
                let t = Instant::now();
                let poses = session.step_joints(chunk)?;
                let ms = t.elapsed().as_secs_f64() * 1e3;
                if warm {
                    timing.record(ms, chunk.shape()[0], !poses.is_empty());
                }
                if let Some(r) = retargeter.as_mut() {
                    let t = Instant::now();
                    for pose in &poses {
                        let p: Vec<[f64; 3]> = pose
                            .positions
                            .iter()
                            .map(|&p| format.to_canonical_axes(p))
                            .collect();
                        rig_poses.push(r.push(&SourceFrame {
                            positions: &p,
                            rotations: None,
                            contacts: None,
                        })?);
                    }
                    retarget_ms += t.elapsed().as_secs_f64() * 1e3;
                }
                reactor.extend(poses);
            }
            if !rig_poses.is_empty() {
                println!(
                    "reactor retargeted onto {} ({} joints) as it streamed: {:.1} µs per frame",
                    rig.name(),
                    rig.len(),
                    retarget_ms * 1e3 / rig_poses.len() as f64
                );
            }
            let reactor = pose_positions(&reactor);
            if let Some(gltf) = &args.gltf {
                if !rig_poses.is_empty() {
                    let fps = model.fps() as f32;
                    let actor_now = resampled(actor, format.fps, fps);
                    let actor_canonical = canonical_clip(actor_now.view(), &format);
                    let n = actor_canonical.len().min(rig_poses.len());
                    let options = RetargetOptions {
                        fps,
                        ..RetargetOptions::default()
                    };
                    let actor_poses =
                        retarget_clip(&rig, &map, &actor_canonical[..n], None, options)?;
                    let people = [
                        GltfPerson {
                            name: "actor",
                            rig: &rig,
                            poses: &actor_poses,
                            color: troupe::motion::gltf::PERSON_COLORS[0],
                        },
                        GltfPerson {
                            name: "reactor",
                            rig: &rig,
                            poses: &rig_poses[..n],
                            color: troupe::motion::gltf::PERSON_COLORS[1],
                        },
                    ];
                    let options = GltfOptions {
                        fps,
                        ..GltfOptions::default()
                    };
                    write_glb_file(gltf, &people, &options)?;
                    println!(
                        "glTF: {} ({n} frames of actor and reactor on {}; opens in Blender, three.js, Unity, Godot)",
                        gltf.display(),
                        rig.name()
                    );
                }
            }
            if let (Some(fbx), false) = (&args.fbx, rig_poses.is_empty()) {
                let options = FbxWriteOptions {
                    fps: model.fps() as f32,
                    ..FbxWriteOptions::default()
                };
                write_rig_fbx_file(fbx, &rig, &rig_poses, &options)?;
                println!(
                    "FBX: {} ({} frames of the reactor on {}; opens in Blender, Unity, Unreal, Maya)",
                    fbx.display(),
                    rig_poses.len(),
                    rig.name()
                );
            }
            write_npy(&args.out, &reactor)?;
            println!(
                "{} actor frames of joint positions ({}, {:?}, {:?} up, {} fps) -> {} reactor poses at {} fps -> {}",
                n,
                path.display(),
                format.units,
                format.up,
                format.fps,
                reactor.shape()[0],
                model.fps(),
                args.out.display()
            );
            if let Some(truth) = rule.as_deref().and_then(|r| rule_partner(path, r)) {
                // Over the frames the reactor has, for the reactor and the baseline alike.
                let n = reactor.shape()[0].min(truth.shape()[0]);
                let truth = truth.slice(s![..n, .., ..]);
                let still = truth
                    .slice(s![..1, .., ..])
                    .broadcast(truth.dim())
                    .unwrap()
                    .to_owned();
                println!(
                    "the {} rule's partner vs the reactor: {:.1} cm mean per-joint error (a partner standing still at the rule's first pose: {:.1} cm)",
                    rule.as_deref().unwrap_or_default(),
                    mpjpe_cm(reactor.view(), truth.view()),
                    mpjpe_cm(still.view(), truth.view()),
                );
            }
            let scene = if args.pictures && reactor.shape()[0] > 0 {
                let fps = model.fps() as f32;
                let view = JointsFormat { fps, ..format };
                let actor = resampled(actor, format.fps, fps);
                Some(Scene::from_world(
                    scene_title,
                    &view,
                    &[("actor", actor.view()), ("reactor", reactor.view())],
                )?)
            } else {
                None
            };
            (n, format.fps, scene)
        }
        Source::Features(_) | Source::Synthetic => {
            let actor: Array2<f32> = match &args.source {
                Source::Features(path) => read_npy(path)?,
                _ => synthetic_actor(args.frames.unwrap_or(600), model.frame_dim()),
            };
            let n = args.frames.unwrap_or(actor.nrows()).min(actor.nrows());
            let mut reactor = Vec::with_capacity(n * model.frame_dim());
            for chunk in actor
                .slice(s![..n, ..])
                .axis_chunks_iter(Axis(0), args.tick)
            {
                let warm = session.tokens_generated() >= args.warmup_tokens;
                let t = Instant::now();
                let out = session.step(chunk)?;
                let ms = t.elapsed().as_secs_f64() * 1e3;
                if warm {
                    timing.record(ms, chunk.nrows(), out.nrows() > 0);
                }
                reactor.extend(out.iter().copied());
            }
            let rows = reactor.len() / model.frame_dim();
            let reactor = Array2::from_shape_vec((rows, model.frame_dim()), reactor)?;
            write_npy(&args.out, &reactor)?;
            println!(
                "{n} actor feature frames -> {rows} reactor frames -> {}",
                args.out.display()
            );
            // Features are already in the canonical frame: show them there.
            let placement = Placement::identity(JointsFormat::default());
            let decode = |frames: ndarray::ArrayView2<f32>| -> Result<Array3<f32>, troupe::Error> {
                let poses = frames
                    .outer_iter()
                    .map(|r| decode_frame(r, &placement))
                    .collect::<Result<Vec<_>, _>>()?;
                Ok(pose_positions(&poses))
            };
            let scene = if args.pictures
                && rows > 0
                && troupe::motion::joints_layout(&model.manifest().motion).is_ok()
            {
                let mut scene = Scene::new(model.fps() as f32, scene_title)?;
                scene.add_person("actor", decode(actor.slice(s![..n, ..]))?.view())?;
                scene.add_person("reactor", decode(reactor.view())?.view())?;
                Some(scene)
            } else {
                None
            };
            (n, model.fps() as f32, scene)
        }
    };
    if let Some(scene) = scene {
        scene.write_pictures(Some(&html), Some(&gif), &GifOptions::default())?;
        println!(
            "pictures: {} (open it in a browser: play, pause, scrub, drag to orbit) and {}",
            html.display(),
            gif.display()
        );
    }

    // The slowest calls in the order they came, to tell a first-use cost (call 0) or a
    // periodic one (recentring, page growth) from the machine's noise.
    let mut slowest: Vec<(usize, f64)> = timing.all_calls.iter().copied().enumerate().collect();
    slowest.sort_by(|a, b| b.1.total_cmp(&a.1));
    slowest.truncate(5);
    slowest.sort_by_key(|&(i, _)| i);
    let slowest: Vec<String> = slowest
        .iter()
        .map(|(i, ms)| format!("#{i} {ms:.2} ms"))
        .collect();
    for v in [&mut timing.all_calls, &mut timing.token_calls] {
        v.sort_by(f64::total_cmp);
    }
    println!(
        "streamed {input_frames} actor frames in ticks of {}",
        args.tick
    );
    for (what, v) in [
        ("every call", &timing.all_calls),
        ("calls that produced a token", &timing.token_calls),
    ] {
        println!(
            "step latency, {what} ({} calls): p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms",
            v.len(),
            percentile(v, 0.5),
            percentile(v, 0.99),
            v.last().copied().unwrap_or(f64::NAN)
        );
    }
    println!("slowest calls: {}", slowest.join(", "));
    let motion_ms = timing.timed_frames as f64 / f64::from(input_fps) * 1e3;
    println!(
        "real-time factor {:.1}x ({:.0} ms of motion computed in {:.0} ms; context holds {} tokens)",
        motion_ms / timing.timed_ms,
        motion_ms,
        timing.timed_ms,
        session.context_len()
    );
    Ok(())
}
