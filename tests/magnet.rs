//! MAGNet through the Rust API against the PyTorch reference (`onnx/troupe_onnx/magnet`): every
//! task of the committed tiny bundles, from the golden clip's frames to the sampled tokens and
//! the frames they decode to, with the same seeded draws (troupe's generator in both). Tokens
//! within 1e-5 of the reference's largest value, frames within 1e-4 of theirs (absolute
//! differences are printed: with random weights the decoder's 6-D rotations are far from
//! orthonormal, and their Gram-Schmidt projection magnifies float rounding up to 2e-4 on a body
//! rotation); the draw counts equal.
//! Bad inputs and configurations are refused with a message, not a panic.

mod common;

use std::path::PathBuf;

use ndarray::{Array3, Array4};
use ndarray_npy::read_npy;
use troupe::magnet::spec::SamplingSpec;
use troupe::{MagnetOptions, Model};

fn bundle(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("onnx/bundles")
        .join(name)
}

fn relative_error(got: &[f32], want: &[f32]) -> f32 {
    let scale = want.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-6);
    common::max_abs_diff(got, want) / scale
}

fn check_bundle(name: &str) -> usize {
    let dir = bundle(name);
    let model = Model::load(&dir).expect("load");
    let golden = dir.join("golden");
    let frames: Array3<f32> = read_npy(golden.join("frames.npy")).expect("frames");
    let cases: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(golden.join("cases.json")).unwrap()).unwrap();
    let cases = cases.as_object().unwrap();
    // The live partner's streams are checked through a session (`tests/magnet_live.rs`).
    let cases: Vec<_> = cases
        .iter()
        .filter(|(case, _)| !case.starts_with("live_stream"))
        .collect();
    for (case, spec) in &cases {
        let sampling: SamplingSpec = serde_json::from_value(spec["sampling"].clone()).unwrap();
        let out = model
            .magnet()
            .unwrap()
            .generate_with(&sampling, frames.view(), None, None)
            .unwrap_or_else(|e| panic!("{name} {case}: {e}"));
        let tokens: Array4<f32> = read_npy(golden.join(format!("{case}_tokens.npy"))).unwrap();
        let want_frames: Array4<f32> = read_npy(golden.join(format!("{case}_frames.npy"))).unwrap();
        assert_eq!(out.tokens.shape(), tokens.shape(), "{name} {case}: tokens");
        assert_eq!(
            out.frames.shape(),
            want_frames.shape(),
            "{name} {case}: frames"
        );
        assert_eq!(
            out.draws as u64,
            spec["draws"].as_u64().unwrap(),
            "{name} {case}: draws"
        );
        let (got_t, want_t) = (out.tokens.as_slice().unwrap(), tokens.as_slice().unwrap());
        let (got_f, want_f) = (
            out.frames.as_slice().unwrap(),
            want_frames.as_slice().unwrap(),
        );
        let (t, f) = (relative_error(got_t, want_t), relative_error(got_f, want_f));
        let (ta, fa) = (
            common::max_abs_diff(got_t, want_t),
            common::max_abs_diff(got_f, want_f),
        );
        println!(
            "{name} {case}: tokens {ta:.2e} max-abs ({t:.2e} relative), frames {fa:.2e} max-abs \
             ({f:.2e} relative)"
        );
        assert!(t <= 1e-5, "{name} {case}: tokens differ by {t:.2e}");
        assert!(f <= 1e-4, "{name} {case}: frames differ by {f:.2e}");
    }
    cases.len()
}

#[test]
fn every_task_matches_the_reference_on_the_two_person_bundle() {
    assert_eq!(check_bundle("magnet-tiny"), 10);
}

#[test]
fn joint_generation_matches_the_reference_for_three_people() {
    assert_eq!(check_bundle("magnet-tiny-trio"), 2);
}

fn tiny() -> (Model, Array3<f32>) {
    let dir = bundle("magnet-tiny");
    let frames: Array3<f32> = read_npy(dir.join("golden/frames.npy")).unwrap();
    (Model::load(&dir).unwrap(), frames)
}

fn quick() -> MagnetOptions {
    MagnetOptions {
        samples: Some(1),
        steps: Some(2),
        seq_len: Some(64),
        without_x0_guidance: true,
        ..Default::default()
    }
}

#[test]
fn released_configurations_run_by_name() {
    let (model, frames) = tiny();
    let spec = model.magnet().expect("a magnet bundle").spec();
    let names: Vec<String> = spec.sampling.keys().cloned().collect();
    assert!(
        names.contains(&"dd100".to_string()) && names.len() == 8,
        "{names:?}"
    );
    for name in &names {
        let mut options = quick();
        if name == "dd100_inbetweening" {
            options.keyframes = Some(vec![0, 60]);
        }
        if name == "dd100_pp2joint" {
            options.seq_len = Some(40);
        }
        let out = model
            .magnet()
            .unwrap()
            .generate(name, frames.view(), None, &options)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(out.frames.iter().all(|v| v.is_finite()), "{name}");
        assert_eq!(out.frames.shape()[2], 2);
        assert_eq!(out.frames.shape()[3], 145);
    }
}

#[test]
fn bad_inputs_and_configurations_are_refused() {
    let (model, frames) = tiny();
    let err = |r: troupe::Result<troupe::MagnetOutput>| r.expect_err("refused").to_string();
    let e = err(model
        .magnet()
        .unwrap()
        .generate("nope", frames.view(), None, &quick()));
    assert!(
        e.contains("no sampling configuration `nope`") && e.contains("dd100"),
        "{e}"
    );
    let three = Array3::<f32>::zeros((64, 3, 145));
    let e = err(model
        .magnet()
        .unwrap()
        .generate("dd100", three.view(), None, &quick()));
    assert!(e.contains("takes [frames, 2, 145]"), "{e}");
    let mut nan = frames.clone();
    nan[[3, 1, 20]] = f32::NAN;
    let e = err(model
        .magnet()
        .unwrap()
        .generate("dd100", nan.view(), None, &quick()));
    assert!(e.contains("non-finite") || e.contains("NaN"), "{e}");
    let short = frames.slice(ndarray::s![..16, .., ..]).to_owned();
    let e = err(model
        .magnet()
        .unwrap()
        .generate("dd100", short.view(), None, &quick()));
    assert!(e.contains("needs at least 32 frames"), "{e}");
    let mut bad_keys = quick();
    bad_keys.keyframes = Some(vec![0, 64]);
    let e =
        err(model
            .magnet()
            .unwrap()
            .generate("dd100_inbetweening", frames.view(), None, &bad_keys));
    assert!(e.contains("key frame 64"), "{e}");
    let zero = MagnetOptions {
        samples: Some(0),
        ..quick()
    };
    let e = err(model
        .magnet()
        .unwrap()
        .generate("dd100", frames.view(), None, &zero));
    assert!(e.contains("samples must be at least 1"), "{e}");
    let draws = MagnetOptions {
        draws: Some(vec![vec![0.0; 3]]),
        ..quick()
    };
    let e = err(model
        .magnet()
        .unwrap()
        .generate("dd100", frames.view(), None, &draws));
    assert!(e.contains("injected draw 0 holds 3 normals"), "{e}");
    // A model of another family says what it is.
    let armflow = Model::load(bundle("armflow-tiny")).unwrap();
    let e = armflow.magnet().expect_err("refused");
    assert!(matches!(e, troupe::Error::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("needs a `magnet` bundle"), "{e}");
    // The trio model cannot run a two-person task it does not list, nor a two-person config.
    let trio = Model::load(bundle("magnet-tiny-trio")).unwrap();
    let e = err(trio
        .magnet()
        .unwrap()
        .generate("dd100", frames.view(), None, &quick()));
    assert!(e.contains("no sampling configuration `dd100`"), "{e}");
}

#[test]
fn injected_draws_reproduce_the_seeded_run() {
    let (model, frames) = tiny();
    let seeded = model
        .magnet()
        .unwrap()
        .generate("dd100", frames.view(), None, &quick())
        .unwrap();
    let spec = model.magnet().unwrap().spec();
    let d = spec.model.token_dim;
    // Regenerate the seeded draws with troupe's generator, then inject them.
    let mut sizes = Vec::new();
    let t = seeded.tokens.shape()[1];
    sizes.push(t * 2 * d); // initial noise [S=1, T, P, D]
    for _ in 1..seeded.draws {
        sizes.push(16 * 2 * d); // one DDIM draw per call [1, 16, 2, D]
    }
    let draws: Vec<Vec<f32>> = sizes
        .iter()
        .enumerate()
        .map(|(i, &n)| {
            let mut v = vec![0f32; n];
            troupe::noise::fill_normals(1111, i as u64, troupe::magnet::STREAM_MAGNET, &mut v);
            v
        })
        .collect();
    let injected = model
        .magnet()
        .unwrap()
        .generate(
            "dd100",
            frames.view(),
            None,
            &MagnetOptions {
                draws: Some(draws),
                ..quick()
            },
        )
        .unwrap();
    assert_eq!(injected.tokens, seeded.tokens);
    assert_eq!(injected.frames, seeded.frames);
}

#[test]
fn output_shapes_are_known_before_generating() {
    let (model, frames) = tiny();
    for name in [
        "dd100",
        "dd100_partner_prediction",
        "dd100_turn_taking",
        "dd100_pp2joint",
    ] {
        let options = MagnetOptions {
            seq_len: Some(if name == "dd100_pp2joint" { 40 } else { 64 }),
            ..quick()
        };
        let shape = model
            .magnet()
            .unwrap()
            .output_shape(name, frames.shape()[0], &options)
            .unwrap();
        let out = model
            .magnet()
            .unwrap()
            .generate(name, frames.view(), None, &options)
            .unwrap();
        assert_eq!(out.frames.shape(), &shape[..], "{name}");
    }
}

#[test]
fn sizes_beyond_troupes_limits_are_refused_before_allocating() {
    let (model, frames) = tiny();
    let huge = MagnetOptions {
        samples: Some(1 << 30),
        ..quick()
    };
    let e = model
        .magnet()
        .unwrap()
        .generate("dd100", frames.view(), None, &huge)
        .expect_err("refused")
        .to_string();
    assert!(e.contains("above troupe's limit"), "{e}");
    let long = MagnetOptions {
        seq_len: Some(1 << 24),
        ..quick()
    };
    let e = model
        .magnet()
        .unwrap()
        .output_shape("dd100", 128, &long)
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("seq_len is 16777216, above troupe's limit"),
        "{e}"
    );
}

#[test]
fn a_generation_reports_progress_and_can_be_cancelled() {
    let (model, frames) = tiny();
    let seen = std::rc::Rc::new(std::cell::RefCell::new(Vec::new()));
    let log = std::rc::Rc::clone(&seen);
    let options = MagnetOptions {
        steps: Some(4),
        ..quick()
    };
    troupe::with_progress(
        move |done, total| {
            log.borrow_mut().push((done, total));
            true
        },
        || {
            model
                .magnet()
                .unwrap()
                .generate("dd100", frames.view(), None, &options)
        },
    )
    .unwrap();
    let seen = seen.borrow();
    assert_eq!(seen.len(), 4, "one report per network call: {seen:?}");
    assert_eq!(*seen.last().unwrap(), (4, 4));
    let e = troupe::with_progress(
        |done, _| done < 2,
        || {
            model
                .magnet()
                .unwrap()
                .generate("dd100", frames.view(), None, &options)
        },
    )
    .expect_err("cancelled");
    assert!(matches!(e, troupe::Error::Cancelled(_)), "{e}");

    // A call budget: 4 sampler iterations are over a budget of 3, refused before any network
    // call; within it the generation is what it is without one.
    let generate = || {
        model
            .magnet()
            .unwrap()
            .generate("dd100", frames.view(), None, &options)
    };
    let tight = troupe::CallBudget {
        max_work: 3,
        max_seconds: 0.0,
    };
    let e = troupe::with_call_budget(tight, generate).expect_err("over the budget");
    assert!(
        matches!(&e, troupe::Error::InvalidOption(m)
            if m.contains("would take 4 sampler iterations, above this thread's call budget of 3")),
        "{e}"
    );
    let roomy = troupe::CallBudget {
        max_work: 4,
        max_seconds: 60.0,
    };
    let within = troupe::with_call_budget(roomy, generate).unwrap();
    assert_eq!(within.frames, generate().unwrap().frames);
}

/// The seed's own normals for `config`, queued in the sampler's order: each draw's size is read
/// from the refusal of a queue that stops short of it (the sizes are §3.5's, which a caller
/// replaying a recorded run already has).
fn seeded_normals(
    model: &Model,
    config: &str,
    frames: &Array3<f32>,
    options: &MagnetOptions,
) -> Vec<f32> {
    let seed = options.seed.expect("a seeded run");
    let mut queue = Vec::new();
    for draw in 0.. {
        let probe = MagnetOptions {
            normals: Some(queue.clone()),
            ..options.clone()
        };
        let Err(e) = model
            .magnet()
            .unwrap()
            .generate(config, frames.view(), None, &probe)
        else {
            return queue;
        };
        queue.extend(common::magnet_draw_refused(&e, draw, seed));
    }
    unreachable!()
}

/// The run's normals as one queue (what C and Python give to replay another implementation's
/// draws): the seed's own normals give the seeded run bit for bit, every one of them used; a
/// queue that runs short or holds a NaN is refused naming the draw, and draws given both ways
/// are refused.
#[test]
fn injected_normals_replay_a_seeded_run_exactly() {
    let (model, frames) = tiny();
    let magnet = model.magnet().unwrap();
    for config in ["dd100", "dd100_inbetweening"] {
        let mut options = MagnetOptions {
            seed: Some(4),
            ..quick()
        };
        if config == "dd100_inbetweening" {
            options.keyframes = Some(vec![0, 63]);
            options.without_x0_guidance = false;
        }
        let seeded = magnet
            .generate(config, frames.view(), None, &options)
            .unwrap();
        let queue = seeded_normals(&model, config, &frames, &options);
        let replay = MagnetOptions {
            normals: Some(queue.clone()),
            ..options.clone()
        };
        let replayed = magnet
            .generate(config, frames.view(), None, &replay)
            .unwrap();
        assert_eq!(replayed.tokens, seeded.tokens, "{config}");
        assert_eq!(replayed.frames, seeded.frames, "{config}");
        assert_eq!(
            (replayed.draws, replayed.normals_used),
            (seeded.draws, queue.len()),
            "{config}"
        );
        let mut bad = queue.clone();
        bad[3] = f32::NAN;
        let e = magnet
            .generate(
                config,
                frames.view(),
                None,
                &MagnetOptions {
                    normals: Some(bad),
                    ..options.clone()
                },
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("injected normal 3 is not finite"), "{e}");
    }
    let both = MagnetOptions {
        normals: Some(vec![0.0; 4]),
        draws: Some(vec![vec![0.0; 4]]),
        ..quick()
    };
    let e = magnet
        .generate("dd100", frames.view(), None, &both)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not both"), "{e}");
}

/// A configuration given as JSON is held to the manifest's rules: an unknown key is refused with
/// the key named (a misspelt `stepz` was silently the default), and `subseq_len` and `eta` out of
/// range are refused before anything runs (2^64 - 1 and 1e30 failed later as inference errors).
#[test]
fn json_configurations_refuse_unknown_keys_and_values_out_of_range() {
    let (model, frames) = tiny();
    let magnet = model.magnet().unwrap();
    let base = serde_json::to_value(&magnet.spec().sampling["dd100"]).unwrap();
    let with = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = base.clone();
        edit(&mut v);
        v.to_string()
    };
    for (config, wanted) in [
        (with(&|v| v["stepz"] = 3.into()), "unknown field `stepz`"),
        (
            with(&|v| v["guidance"]["smoothing"]["wieght"] = 1.0.into()),
            "unknown field `wieght`",
        ),
        (with(&|v| v["subseq_len"] = u64::MAX.into()), "subseq_len"),
        (with(&|v| v["eta"] = 1e30.into()), "eta"),
        (with(&|v| v["eta"] = (-0.5).into()), "eta"),
    ] {
        let e = magnet
            .generate(&config, frames.view(), None, &quick())
            .unwrap_err();
        assert!(
            matches!(e, troupe::Error::InvalidOption(_)) && e.to_string().contains(wanted),
            "wanted {wanted}: {e}"
        );
    }
    let fine = with(&|v| v["subseq_len"] = 16.into());
    assert!(magnet
        .generate(&fine, frames.view(), None, &quick())
        .is_ok());
}
