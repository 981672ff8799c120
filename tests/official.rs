//! Parity with the official ARMFlow sampler: the committed bundles
//! `onnx/bundles/armflow-tiny-interhuman` and `onnx/bundles/armflow-tiny-interx` hold random
//! weights in the official layout (written as an official checkpoint and exported from it,
//! `onnx/tests/test_official.py`), and their goldens come from the PyTorch reference of the
//! official loops (`onnx/troupe_onnx/armflow/reference.py::clip_reference`, `stream_reference`)
//! on the same weights and injected noise.
//!
//! Tolerances: latents and contexts 1e-5, frames 1e-4 (the parity bounds).

mod common;

use std::path::PathBuf;
use std::sync::OnceLock;

use common::max_abs_diff;
use ndarray::{Array1, Array2};
use ndarray_npy::read_npy;
use troupe::{ClipNoise, ClipOptions, Error, Model, Reactor, ReactorOptions, TokenNoise};

const LATENT_TOL: f32 = 1e-5;
const FRAME_TOL: f32 = 1e-4;
const CONFIGS: [&str; 2] = ["interhuman", "interx"];

fn dir(config: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("onnx/bundles/armflow-tiny-{config}"))
}

fn model(config: &str) -> &'static Model {
    static MODELS: [OnceLock<Model>; 2] = [OnceLock::new(), OnceLock::new()];
    let i = CONFIGS.iter().position(|c| *c == config).unwrap();
    MODELS[i].get_or_init(|| Model::load(dir(config)).expect("the committed bundle loads"))
}

fn g2(config: &str, name: &str) -> Array2<f32> {
    read_npy(dir(config).join("golden").join(format!("{name}.npy")))
        .unwrap_or_else(|e| panic!("{config} golden {name}: {e}"))
}

fn g1(config: &str, name: &str) -> Array1<f32> {
    read_npy(dir(config).join("golden").join(format!("{name}.npy")))
        .unwrap_or_else(|e| panic!("{config} golden {name}: {e}"))
}

fn flat(a: &Array2<f32>) -> Vec<f32> {
    a.iter().copied().collect()
}

fn golden_noise(config: &str, case: &str) -> ClipNoise {
    ClipNoise {
        actor_posterior: flat(&g2(config, &format!("{case}_xi"))),
        reactor_noise: g1(config, &format!("{case}_eps")).to_vec(),
    }
}

/// The clip loop on `condition` with the golden case's draws, against the reference.
fn check_clip(config: &str, case: &str, condition: Option<&[f32]>) {
    check_clip_of(model(config), config, case, condition);
}

fn check_clip_of(m: &Model, config: &str, case: &str, condition: Option<&[f32]>) {
    let options = ClipOptions {
        noise: Some(golden_noise(config, case)),
        ..Default::default()
    };
    let clip = m
        .armflow()
        .unwrap()
        .generate_clip(
            g2(config, &format!("{case}_actor")).view(),
            condition,
            &options,
        )
        .unwrap();
    let diff = |got: &Array2<f32>, k: &str| {
        let want = g2(config, &format!("{case}_{k}"));
        assert_eq!(got.shape(), want.shape(), "{config} {case} {k} shape");
        max_abs_diff(&flat(got), &flat(&want))
    };
    let (a, b, c, f) = (
        diff(&clip.actor_latents, "actor_latents"),
        diff(&clip.reactor_latents, "reactor_latents"),
        diff(&clip.contexts, "contexts"),
        diff(&clip.frames, "frames"),
    );
    println!(
        "{config} {case}: max-abs actor latents {a:.2e}, reactor latents {b:.2e}, contexts {c:.2e}, frames {f:.2e}"
    );
    assert!(
        a <= LATENT_TOL && b <= LATENT_TOL && c <= LATENT_TOL,
        "{config} {case}: latents off"
    );
    assert!(f <= FRAME_TOL, "{config} {case}: frames off by {f}");
}

fn text_condition(config: &str) -> Vec<f32> {
    let eot = g1_i64(config, "text_eot_index");
    let got = model(config)
        .encode_text(g2(config, "text_clip_tokens").view(), eot)
        .unwrap();
    let want = g1(config, "text_condition").to_vec();
    let d = max_abs_diff(&got, &want);
    println!("{config} text branch: max-abs condition {d:.2e}");
    assert!(d <= LATENT_TOL, "{config}: text branch off by {d}");
    got
}

fn g1_i64(config: &str, name: &str) -> usize {
    let a: Array1<i64> = read_npy(dir(config).join("golden").join(format!("{name}.npy"))).unwrap();
    a[0] as usize
}

#[test]
fn interhuman_clip_matches_the_official_loop() {
    let condition = text_condition("interhuman");
    check_clip("interhuman", "clip", Some(&condition));
    check_clip("interhuman", "clip_null", None);
}

#[test]
fn interx_clip_matches_the_official_loop() {
    let condition = text_condition("interx");
    check_clip("interx", "clip", Some(&condition));
    check_clip("interx", "clip_null", None);
}

#[test]
fn interx_pads_the_decoded_clip_by_repeating_the_last_frame() {
    let m = model("interx");
    let clip = m
        .armflow()
        .unwrap()
        .generate_clip(
            g2("interx", "clip_actor").view(),
            None,
            &ClipOptions::default(),
        )
        .unwrap();
    assert_eq!(clip.frames.nrows(), 150);
    assert_eq!(clip.reactor_latents.nrows(), 37);
    assert_eq!(clip.frames.row(147), clip.frames.row(148));
    assert_eq!(clip.frames.row(147), clip.frames.row(149));
    assert_ne!(clip.frames.row(146), clip.frames.row(147));
}

/// Stream mode with the non-causal official VAE: windows and lookahead from the manifest,
/// against the reference stream loop with the same windows.
#[test]
fn stream_mode_with_lookahead_windows_matches_the_reference() {
    for config in CONFIGS {
        check_stream(model(config), config, "stream");
    }
}

/// A session with the bundle's default options, on the `clip` golden's actor and text condition
/// with the golden `case`'s draws, against the reference stream loop.
fn check_stream(m: &Model, config: &str, case: &str) {
    let condition = g1(config, "text_condition").to_vec();
    let mut session = m
        .session(ReactorOptions {
            condition: Some(condition),
            ..Default::default()
        })
        .unwrap();
    for (a, r) in g2(config, &format!("{case}_xi"))
        .rows()
        .into_iter()
        .zip(g2(config, &format!("{case}_eps")).rows())
    {
        session
            .family_mut::<Reactor>()
            .unwrap()
            .queue_noise(TokenNoise {
                actor: a.to_vec(),
                reactor: r.to_vec(),
            })
            .unwrap();
    }
    let actor = g2(config, "clip_actor");
    let (mut frames, mut reactor) = (Vec::new(), Vec::new());
    for chunk in actor.axis_chunks_iter(ndarray::Axis(0), 7) {
        let out = session.step_detailed(chunk).unwrap();
        frames.extend(out.frames.iter().copied());
        reactor.extend(out.tokens.iter().flat_map(|t| t.reactor_latent.clone()));
    }
    let (fb, rb) = (
        max_abs_diff(&frames, &flat(&g2(config, &format!("{case}_frames")))),
        max_abs_diff(
            &reactor,
            &flat(&g2(config, &format!("{case}_reactor_latents"))),
        ),
    );
    println!("{config} {case}: max-abs reactor latents {rb:.2e}, frames {fb:.2e}");
    assert!(
        rb <= LATENT_TOL && fb <= FRAME_TOL,
        "{config} {case} off: {rb} {fb}"
    );
}

/// A checkpoint saved with `mf.cfg_scale: 2` exports `sampler.cfg_scale: 2`; with no option
/// given, the clip loop and the stream then guide as the official sampler does (a null row with
/// the actor token and context zeroed, `u_null + 2 (u_cond - u_null)`), against the reference
/// with guidance. The same scale given as an option on the unguided bundle gives the same clip.
#[test]
fn a_guided_checkpoint_guides_the_clip_and_the_stream() {
    for config in CONFIGS {
        let dir = common::copy_of_bundle(&format!("armflow-tiny-{config}"));
        common::edit_manifest(dir.path(), |m| m["sampler"]["cfg_scale"] = 2.0.into());
        let guided = Model::load(dir.path()).unwrap();
        let condition = g1(config, "text_condition").to_vec();
        check_clip_of(&guided, config, "clip_guided", Some(&condition));
        check_stream(&guided, config, "stream_guided");
        let asked = ClipOptions {
            noise: Some(golden_noise(config, "clip_guided")),
            cfg_scale: Some(2.0),
            ..Default::default()
        };
        let actor = g2(config, "clip_guided_actor");
        let by_option = model(config)
            .armflow()
            .unwrap()
            .generate_clip(actor.view(), Some(&condition), &asked)
            .unwrap();
        let by_default = guided
            .armflow()
            .unwrap()
            .generate_clip(
                actor.view(),
                Some(&condition),
                &ClipOptions {
                    noise: asked.noise.clone(),
                    ..Default::default()
                },
            )
            .unwrap();
        assert_eq!(by_option.reactor_latents, by_default.reactor_latents);
    }
}

#[test]
fn seeded_clip_draws_are_the_session_draws_of_those_tokens() {
    let m = model("interhuman");
    let noise = m.armflow().unwrap().clip_noise(11).unwrap();
    let session = m
        .session(ReactorOptions {
            seed: 11,
            ..Default::default()
        })
        .unwrap();
    let lat = m.latent_dim();
    let reactor = session.family_ref::<Reactor>().unwrap();
    for j in [0usize, 1, 74] {
        let s = reactor.seeded_noise(j as u64);
        assert_eq!(&noise.actor_posterior[j * lat..(j + 1) * lat], &s.actor[..]);
    }
    assert_eq!(noise.reactor_noise, reactor.seeded_noise(74).reactor);
    let seeded = ClipOptions {
        seed: 11,
        ..Default::default()
    };
    let injected = ClipOptions {
        noise: Some(noise),
        ..Default::default()
    };
    let actor = g2("interhuman", "clip_actor");
    let a = m
        .armflow()
        .unwrap()
        .generate_clip(actor.view(), None, &seeded)
        .unwrap();
    let b = m
        .armflow()
        .unwrap()
        .generate_clip(actor.view(), None, &injected)
        .unwrap();
    assert_eq!(a.frames, b.frames);
}

fn err<T: std::fmt::Debug>(r: Result<T, Error>) -> String {
    match r {
        Err(Error::InvalidInput(msg)) => msg,
        other => panic!("expected InvalidInput, got {other:?}"),
    }
}

#[test]
fn bad_clip_inputs_are_rejected_with_a_message() {
    let m = model("interhuman");
    let d = m.frame_dim();
    let opts = ClipOptions::default();
    let too_long = Array2::<f32>::zeros((301, d));
    assert!(err(m
        .armflow()
        .unwrap()
        .generate_clip(too_long.view(), None, &opts))
    .contains("1..=300 frames"));
    let empty = Array2::<f32>::zeros((0, d));
    assert!(err(m
        .armflow()
        .unwrap()
        .generate_clip(empty.view(), None, &opts))
    .contains("0x262"));
    let narrow = Array2::<f32>::zeros((10, d - 1));
    assert!(err(m
        .armflow()
        .unwrap()
        .generate_clip(narrow.view(), None, &opts))
    .contains("of 262 floats"));
    let mut nan = Array2::<f32>::zeros((10, d));
    nan[[3, 4]] = f32::NAN;
    assert!(
        err(m.armflow().unwrap().generate_clip(nan.view(), None, &opts)).contains("actor clip")
    );
    let ok = Array2::<f32>::zeros((10, d));
    let short = ClipOptions {
        noise: Some(ClipNoise {
            actor_posterior: vec![0.0; 3],
            reactor_noise: vec![0.0; m.latent_dim()],
        }),
        ..Default::default()
    };
    assert!(
        err(m.armflow().unwrap().generate_clip(ok.view(), None, &short))
            .contains("actor_posterior")
    );
    assert!(err(m
        .armflow()
        .unwrap()
        .generate_clip(ok.view(), Some(&[1.0; 3]), &opts))
    .contains("condition"));
    let zero_steps = ClipOptions {
        steps: Some(0),
        ..Default::default()
    };
    match m
        .armflow()
        .unwrap()
        .generate_clip(ok.view(), None, &zero_steps)
    {
        Err(Error::InvalidOption(msg)) => assert!(msg.contains("steps"), "{msg}"),
        other => panic!("expected InvalidOption, got {other:?}"),
    }
    let tokens = Array2::<f32>::zeros((5, m.condition_dim()));
    assert!(err(m.encode_text(tokens.view(), 5)).contains("outside"));

    // A streaming-only bundle has no clip; a group bundle is another family.
    let tiny = common::model();
    assert!(err(tiny
        .armflow()
        .unwrap()
        .generate_clip(ok.view(), None, &opts))
    .contains("no `clip` section"));
    assert!(err(tiny.encode_text(tokens.view(), 0)).contains("no text_branch"));
}
