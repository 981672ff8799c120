//! ARFlow through the Rust API against the PyTorch reference (`onnx/troupe_onnx/arflow`): each
//! golden case of the committed tiny bundles (offline and online variants; plain Euler, guided,
//! stochastic with a squared hinge), the same seeded draws, reactor features within 1e-5 of the
//! reference's largest value without guidance; with guidance (λ = 2) within 1e-4: the guidance
//! direction is ill-conditioned near a capsule's axis and five network calls amplify float
//! rounding, so that two references (torch, and onnxruntime on the same graph) already differ by
//! up to 5.2e-5 there (`docs/ARFLOW.md`). The penetration loss's analytic gradient against the reference's
//! autograd, the online variant's causality and its stream (frame by frame through a
//! `Session`, alone and in a crowd), and bad input.

mod common;

use std::path::PathBuf;

use ndarray::{s, Array2, Array3};
use ndarray_npy::read_npy;
use troupe::arflow::sampler::guidance_gradient;
use troupe::arflow::spec::Mixing;
use troupe::motion::{BodyModel, Hinge, PenetrationLoss};
use troupe::{ArflowOptions, Error, Model, SessionOptions};

fn bundle(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("onnx/bundles")
        .join(name)
}

fn cases(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(bundle(name).join("golden/cases.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn options(case: &serde_json::Value) -> ArflowOptions {
    let f = |k: &str| case[k].as_f64().unwrap() as f32;
    ArflowOptions {
        steps: Some(case["steps"].as_u64().unwrap() as usize),
        guidance: Some(f("guidance")),
        weight: Some(f("weight")),
        eta: Some(f("eta")),
        d_safe: Some(f("d_safe")),
        squared: Some(case["squared"].as_bool().unwrap()),
        guided_backprojection: Some(case["guided_backprojection"].as_bool().unwrap()),
        mixing: Some(match case["mixing"].as_str().unwrap() {
            "linear" => Mixing::Linear,
            _ => Mixing::VariancePreserving,
        }),
        sigma: Some(f("sigma")),
        seed: case["seed"].as_u64().unwrap(),
    }
}

fn relative_error(got: &[f32], want: &[f32]) -> f32 {
    let scale = want.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-6);
    common::max_abs_diff(got, want) / scale
}

#[test]
fn every_case_matches_the_reference_offline_and_online() {
    for name in ["arflow-tiny", "arflow-tiny-online"] {
        let model = Model::load(bundle(name)).unwrap();
        let golden = bundle(name).join("golden");
        let actor: Array2<f32> = read_npy(golden.join("actor.npy")).unwrap();
        for case in ["euler", "guided", "stochastic"] {
            let spec = &cases(name)[case];
            let got = model
                .arflow()
                .unwrap()
                .generate(actor.view(), &options(spec))
                .unwrap();
            let want: Array2<f32> = read_npy(golden.join(format!("{case}_reactor.npy"))).unwrap();
            assert_eq!(got.dim(), want.dim());
            let (got, want) = (got.as_slice().unwrap(), want.as_slice().unwrap());
            let err = relative_error(got, want);
            println!(
                "{name} {case}: {:.2e} max-abs, {err:.2e} relative",
                common::max_abs_diff(got, want)
            );
            let bound = if spec["guidance"].as_f64().unwrap() > 0.0 {
                1e-4
            } else {
                1e-5
            };
            assert!(err <= bound, "{name} {case}: {err:.2e}");
        }
    }
}

#[test]
fn the_penetration_gradient_equals_the_references_autograd() {
    let golden = bundle("arflow-tiny").join("golden");
    let actor: Array2<f32> = read_npy(golden.join("actor.npy")).unwrap();
    let reactor: Array3<f64> = read_npy(golden.join("penetration_reactor.npy")).unwrap();
    let joints = |a: &Array3<f64>| -> Vec<Vec<[f64; 3]>> {
        a.outer_iter()
            .map(|f| f.outer_iter().map(|p| [p[0], p[1], p[2]]).collect())
            .collect()
    };
    let actor_joints: Vec<Vec<[f64; 3]>> = actor
        .outer_iter()
        .map(|row| {
            (0..22)
                .map(|j| [0, 1, 2].map(|k| row[3 * j + k] as f64))
                .collect()
        })
        .collect();
    let body = BodyModel::t2m22();
    for (tag, hinge) in [("linear", Hinge::Linear), ("squared", Hinge::Squared)] {
        let case = &cases("arflow-tiny")[format!("penetration_{tag}")];
        let loss = PenetrationLoss {
            d_safe: case["d_safe"].as_f64().unwrap(),
            hinge,
        };
        let got = loss
            .evaluate(&body, &actor_joints, &joints(&reactor))
            .unwrap();
        let want: Array3<f64> =
            read_npy(golden.join(format!("penetration_{tag}_gradient.npy"))).unwrap();
        let want_loss = case["loss"].as_f64().unwrap();
        assert!(want_loss > 0.0, "the golden reactor should penetrate");
        assert!(
            (got.loss - want_loss).abs() <= 1e-9 * want_loss.max(1.0),
            "{tag} loss"
        );
        let mut worst = 0f64;
        for (n, frame) in got.gradient.iter().enumerate() {
            for (j, g) in frame.iter().enumerate() {
                for k in 0..3 {
                    worst = worst.max((g[k] - want[[n, j, k]]).abs());
                }
            }
        }
        println!(
            "penetration {tag}: loss {:.6}, gradient {worst:.2e} from autograd",
            got.loss
        );
        assert!(worst <= 1e-4, "{tag}: {worst:.2e}");
    }
    // The same in the sampler's normalised feature space.
    let model = Model::load(bundle("arflow-tiny")).unwrap();
    let norm = &model.arflow().unwrap().spec().normalizer;
    let x1: Array2<f32> = read_npy(golden.join("guidance_x1.npy")).unwrap();
    let want: Array2<f64> = read_npy(golden.join("guidance_gradient.npy")).unwrap();
    let loss = PenetrationLoss {
        d_safe: 0.02,
        hinge: Hinge::Linear,
    };
    let got = guidance_gradient(x1.view(), actor.view(), &norm.mean, &norm.std, &loss).unwrap();
    let worst = (&got - &want).iter().fold(0f64, |m, v| m.max(v.abs()));
    println!("guidance gradient in feature space: {worst:.2e} from autograd");
    assert!(worst <= 1e-4 && want.iter().any(|v| *v != 0.0));
}

#[test]
fn the_online_variant_is_causal_and_the_offline_one_is_not() {
    let golden = bundle("arflow-tiny").join("golden");
    let actor: Array2<f32> = read_npy(golden.join("actor.npy")).unwrap();
    let euler = ArflowOptions {
        guidance: Some(0.0),
        weight: Some(1.0),
        ..Default::default()
    };
    let guided = ArflowOptions {
        seed: 3,
        ..Default::default()
    };
    for (name, causal) in [("arflow-tiny-online", true), ("arflow-tiny", false)] {
        let model = Model::load(bundle(name)).unwrap();
        for (what, options, bound) in [("euler", &euler, 1e-5), ("guided", &guided, 1e-4)] {
            let full = model
                .arflow()
                .unwrap()
                .generate(actor.view(), options)
                .unwrap();
            let head = model
                .arflow()
                .unwrap()
                .generate(actor.slice(s![..25, ..]), options)
                .unwrap();
            let err = relative_error(
                head.as_standard_layout().as_slice().unwrap(),
                full.slice(s![..25, ..])
                    .as_standard_layout()
                    .as_slice()
                    .unwrap(),
            );
            println!("{name} {what}: the first 25 frames alone differ by {err:.2e}");
            if causal {
                assert!(err <= bound, "{name} {what}: {err:.2e}");
            } else {
                assert!(
                    err > 1e-3,
                    "{name}: the offline network should see later frames"
                );
            }
        }
    }
}

fn refused<T: std::fmt::Debug>(r: troupe::Result<T>, needle: &str) {
    match r {
        Err(Error::InvalidInput(m) | Error::InvalidOption(m) | Error::Unsupported(m)) => {
            assert!(m.contains(needle), "`{m}` should mention `{needle}`")
        }
        other => panic!("expected an error about {needle}, got {other:?}"),
    }
}

#[test]
fn bad_input_is_refused() {
    let model = Model::load(bundle("arflow-tiny")).unwrap();
    let actor: Array2<f32> = read_npy(bundle("arflow-tiny").join("golden/actor.npy")).unwrap();
    let o = ArflowOptions::default();
    refused(
        model
            .arflow()
            .unwrap()
            .generate(actor.slice(s![.., ..261]), &o),
        "262",
    );
    refused(
        model
            .arflow()
            .unwrap()
            .generate(actor.slice(s![..0, ..]), &o),
        "0 actor frames",
    );
    let long = Array2::<f32>::zeros((257, 262));
    refused(
        model.arflow().unwrap().generate(long.view(), &o),
        "1 to 256",
    );
    // A call budget below the sampler's steps refuses the reaction before it starts.
    let steps = ArflowOptions {
        steps: Some(20),
        ..ArflowOptions::default()
    };
    let budget = troupe::CallBudget {
        max_work: 19,
        max_seconds: 0.0,
    };
    refused(
        troupe::with_call_budget(budget, || {
            model.arflow().unwrap().generate(actor.view(), &steps)
        }),
        "the reaction would take 20 sampler steps, above this thread's call budget of 19",
    );
    let mut nan = actor.clone();
    nan[[3, 7]] = f32::NAN;
    refused(
        model.arflow().unwrap().generate(nan.view(), &o),
        "non-finite",
    );
    for (bad, needle) in [
        (
            ArflowOptions {
                guidance: Some(-1.0),
                ..o.clone()
            },
            "guidance strength",
        ),
        (
            ArflowOptions {
                weight: Some(1.5),
                ..o.clone()
            },
            "weight",
        ),
        (
            ArflowOptions {
                eta: Some(1.0),
                ..o.clone()
            },
            "η",
        ),
        (
            ArflowOptions {
                d_safe: Some(-0.1),
                ..o.clone()
            },
            "d_safe",
        ),
        (
            ArflowOptions {
                steps: Some(0),
                ..o.clone()
            },
            "steps",
        ),
        (
            ArflowOptions {
                sigma: Some(f32::NAN),
                ..o.clone()
            },
            "σ",
        ),
    ] {
        refused(model.arflow().unwrap().generate(actor.view(), &bad), needle);
    }
    let armflow = Model::load(bundle("armflow-tiny")).unwrap();
    refused(armflow.arflow(), "needs an `arflow` bundle");
    refused(model.session(SessionOptions::default()), "does not stream");
}

// ---- the online variant as a stream -------------------------------------------------------

fn stream_frames(session: &mut troupe::Session, actor: &Array2<f32>, chunk: usize) -> Array2<f32> {
    let mut out = Vec::new();
    for rows in actor.axis_chunks_iter(ndarray::Axis(0), chunk) {
        let n = rows.nrows();
        assert_eq!(session.frames_ready_after(n), n);
        let got = session.step(rows).unwrap();
        assert_eq!(got.nrows(), n, "a frame out for each frame in");
        out.extend(got.iter().copied());
    }
    Array2::from_shape_vec((out.len() / 262, 262), out).unwrap()
}

#[test]
fn the_online_stream_equals_the_whole_clip_frame_by_frame() {
    let name = "arflow-tiny-online";
    let model = Model::load(bundle(name)).unwrap();
    let golden = bundle(name).join("golden");
    let actor: Array2<f32> = read_npy(golden.join("actor.npy")).unwrap();
    for case in ["euler", "guided"] {
        let spec = &cases(name)[case];
        let options = options(spec);
        let mut session = model.session(options.clone()).unwrap();
        assert_eq!((session.family(), session.latency_frames()), ("arflow", 0));
        let want: Array2<f32> = read_npy(golden.join(format!("{case}_reactor.npy"))).unwrap();
        for chunk in [1, 7, 40] {
            session.reset();
            let got = stream_frames(&mut session, &actor, chunk);
            let err = relative_error(got.as_slice().unwrap(), want.as_slice().unwrap());
            println!(
                "{name} stream {case}, {chunk} frames a call: {err:.2e} relative to the reference"
            );
            let bound = if case == "guided" { 1e-4 } else { 1e-5 };
            assert!(err <= bound, "{case} {chunk}: {err:.2e}");
        }
    }
}

#[test]
fn a_crowd_of_arflow_streams_equals_each_alone() {
    let name = "arflow-tiny-online";
    let model = Model::load(bundle(name)).unwrap();
    let actor: Array2<f32> = read_npy(bundle(name).join("golden/actor.npy")).unwrap();
    let make = |seed: u64, eta: f32| {
        model
            .session(ArflowOptions {
                seed,
                eta: Some(eta),
                ..Default::default()
            })
            .unwrap()
    };
    let settings = [(1u64, 0.0f32), (2, 0.05), (3, 0.0)];
    let offsets = [0usize, 5, 12];
    let mut alone = Vec::new();
    for (&(seed, eta), &skip) in settings.iter().zip(&offsets) {
        let mut s = make(seed, eta);
        stream_frames(&mut s, &actor.slice(s![..skip, ..]).to_owned(), 4);
        alone.push(stream_frames(
            &mut s,
            &actor.slice(s![skip.., ..]).to_owned(),
            40,
        ));
    }
    let mut crowd: Vec<troupe::Session> = settings
        .iter()
        .map(|&(seed, eta)| make(seed, eta))
        .collect();
    for (s, &skip) in crowd.iter_mut().zip(&offsets) {
        stream_frames(s, &actor.slice(s![..skip, ..]).to_owned(), 4);
    }
    let chunks: Vec<Vec<f32>> = offsets
        .iter()
        .map(|&skip| actor.slice(s![skip.., ..]).iter().copied().collect())
        .collect();
    let views: Vec<&[f32]> = chunks.iter().map(Vec::as_slice).collect();
    let mut refs: Vec<&mut troupe::Session> = crowd.iter_mut().collect();
    let together = troupe::step_sessions(&mut refs, &views).unwrap();
    for (i, (out, want)) in together.iter().zip(&alone).enumerate() {
        let err = relative_error(out.frames.as_slice().unwrap(), want.as_slice().unwrap());
        println!("arflow crowd session {i}: {err:.2e} relative to stepping it alone");
        assert!(err <= 1e-4, "session {i}: {err:.2e}");
    }
}

#[test]
fn arflow_streams_refuse_what_they_cannot_do() {
    let offline = Model::load(bundle("arflow-tiny")).unwrap();
    refused(
        offline.session(SessionOptions::default()),
        "does not stream",
    );
    let model = Model::load(bundle("arflow-tiny-online")).unwrap();
    let actor: Array2<f32> =
        read_npy(bundle("arflow-tiny-online").join("golden/actor.npy")).unwrap();
    refused(
        model.session(troupe::ReactorOptions::default()),
        "needs an `armflow` bundle",
    );
    refused(
        model.session(ArflowOptions {
            weight: Some(3.0),
            ..Default::default()
        }),
        "weight",
    );
    let mut s = model.session(SessionOptions::default()).unwrap();
    s.step(actor.slice(s![..3, ..])).unwrap();
    let mut bad = actor.slice(s![3..5, ..]).to_owned();
    bad[[1, 9]] = f32::NAN;
    refused(s.step(bad.view()), "non-finite");
    refused(s.set_steps(3), "step count");
    refused(s.family_mut::<troupe::Reactor>(), "`arflow` model");
    assert_eq!(s.frames_received(), 3, "refused calls change nothing");
    // The position encoding's end (256 frames for the tiny bundle).
    let long = Array2::<f32>::from_shape_fn((254, 262), |(n, i)| actor[[n % 40, i]]);
    refused(s.step(long.view()), "reset it");
    assert_eq!(s.frames_received(), 3);
    s.step(long.slice(s![..253, ..])).unwrap();
    assert_eq!(s.frames_received(), 256);
    s.reset();
    assert_eq!(s.frames_received(), 0);
}

/// The run's normals given as one queue (what C and Python pass to replay another
/// implementation's draws): the seed's own normals, queued in the sampler's order (the start
/// noise when σ > 0, then one ε per step when η > 0), give the seeded run bit for bit; a queue
/// that runs short, or holds a NaN, is refused naming the draw.
#[test]
fn injected_normals_replay_a_seeded_run_exactly() {
    let golden = bundle("arflow-tiny").join("golden");
    let actor: Array2<f32> = read_npy(golden.join("actor.npy")).unwrap();
    let model = Model::load(bundle("arflow-tiny")).unwrap();
    let arflow = model.arflow().unwrap();
    let options = ArflowOptions {
        steps: Some(3),
        eta: Some(0.5),
        sigma: Some(0.1),
        seed: 7,
        ..Default::default()
    };
    let seeded = arflow.generate(actor.view(), &options).unwrap();
    let n = actor.len();
    let stream = troupe::arflow::spec::STREAM_ARFLOW;
    let mut queue = vec![0f32; 4 * n];
    for (draw, chunk) in queue.chunks_mut(n).enumerate() {
        troupe::noise::fill_normals(7, draw as u64, stream, chunk);
    }
    let (replayed, used) = arflow
        .generate_with_normals(actor.view(), &options, &queue)
        .unwrap();
    assert_eq!(used, 4 * n);
    assert_eq!(replayed, seeded);
    let err = arflow
        .generate_with_normals(actor.view(), &options, &queue[..3 * n + 5])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("draw 3 needs {n} normals, and 5 of the")),
        "{err}"
    );
    queue[n + 2] = f32::NAN;
    let err = arflow
        .generate_with_normals(actor.view(), &options, &queue)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("injected normal {} is not finite", n + 2)),
        "{err}"
    );
    // Deterministic settings draw nothing: an empty queue is all they need.
    let plain = ArflowOptions::default();
    let (out, used) = arflow
        .generate_with_normals(actor.view(), &plain, &[])
        .unwrap();
    assert_eq!(
        (out, used),
        (arflow.generate(actor.view(), &plain).unwrap(), 0)
    );
}

/// An online stream replays another's draws from queued normals: a stream seeded 99 given the
/// normals seed 5 would draw (per frame the start noise, then one ε per step) streams exactly
/// as the stream seeded 5; a draw the queue cannot fill fails with the stream as it was, and
/// then, the rest queued, goes on as if nothing had failed.
#[test]
fn an_online_stream_replays_queued_normals() {
    let name = "arflow-tiny-online";
    let model = Model::load(bundle(name)).unwrap();
    let actor: Array2<f32> = read_npy(bundle(name).join("golden/actor.npy")).unwrap();
    let actor = actor.slice(s![..12, ..]).to_owned();
    let make = |seed: u64| {
        model
            .session(ArflowOptions {
                seed,
                steps: Some(2),
                eta: Some(0.4),
                sigma: Some(0.1),
                ..Default::default()
            })
            .unwrap()
    };
    let want = stream_frames(&mut make(5), &actor, 4);
    let stream = troupe::arflow::spec::STREAM_ARFLOW;
    let mut normals = Vec::new();
    for frame in 0..12u64 {
        for k in 0..3 {
            let mut e = vec![0f32; 262];
            troupe::noise::fill_normals(5, frame * 3 + k, stream, &mut e);
            normals.extend(e);
        }
    }
    let mut replay = make(99);
    // One frame short by 10 normals: the fourth frame's last draw cannot be filled.
    replay.queue_normals(&normals[..4 * 3 * 262 - 10]).unwrap();
    let e = replay
        .step(actor.slice(s![..4, ..]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("needs 262 normals, and 252 of the"), "{e}");
    assert_eq!(replay.frames_received(), 0);
    replay.queue_normals(&normals[4 * 3 * 262 - 10..]).unwrap();
    let got = stream_frames(&mut replay, &actor, 4);
    assert_eq!(got, want);
    // Queued normals end: the seed goes on, and a reset drops what was queued.
    let mut tail = make(5);
    tail.queue_normals(&normals[..3 * 262]).unwrap();
    assert_eq!(stream_frames(&mut tail, &actor, 4), want);
    let mut dropped = make(5);
    dropped.queue_normals(&vec![0.0; 3 * 262]).unwrap();
    dropped.reset();
    assert_eq!(stream_frames(&mut dropped, &actor, 4), want);
    let e = dropped.queue_normals(&[f32::NAN]).unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    let mut armflow = Model::load(bundle("armflow-tiny"))
        .unwrap()
        .session(SessionOptions::default())
        .unwrap();
    // An ARMFlow stream takes whole tokens of normals: the actor's posterior noise, then the
    // reactor's start noise, as `Reactor::queue_noise` takes one token.
    let e = armflow.queue_normals(&[0.0]).unwrap_err();
    assert!(
        matches!(e, Error::InvalidInput(_)) && e.to_string().contains("whole tokens"),
        "{e}"
    );
    let lat = armflow.latent_dim();
    let token: Vec<f32> = (0..2 * lat).map(|i| (i as f32 * 0.3).sin()).collect();
    let mut by_token = Model::load(bundle("armflow-tiny"))
        .unwrap()
        .session(SessionOptions::default())
        .unwrap();
    armflow.queue_normals(&token).unwrap();
    by_token
        .family_mut::<troupe::Reactor>()
        .unwrap()
        .queue_noise(troupe::TokenNoise {
            actor: token[..lat].to_vec(),
            reactor: token[lat..].to_vec(),
        })
        .unwrap();
    let frames: Vec<f32> = (0..8 * armflow.frame_dim())
        .map(|i| (i as f32 * 0.11).cos())
        .collect();
    let a = armflow.step_flat(&frames).unwrap().frames;
    assert_eq!(a, by_token.step_flat(&frames).unwrap().frames);
    assert!(a.nrows() > 0);
}
