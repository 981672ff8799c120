//! UMF text-to-group generation: golden parity of the committed tiny bundles against the
//! PyTorch reference sampler (`onnx/troupe_onnx/umf/reference.py`) with the same noise, seeded
//! noise against the Python generator, the official text branches, and every bad input rejected
//! with a clear error. `umf-tiny` is the official UMF layout at reduced width with the released sampler: its
//! weights also load as an official checkpoint (`onnx/tests/test_official.py`).
//! Tolerances: latents max-abs <= 1e-5, motion <= 1e-4.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ndarray::{Array1, Array2, ArrayD};
use ndarray_npy::read_npy;
use serde_json::Value;
use troupe::{Error, GroupNoise, GroupOptions, Method, Model, Solver};

const LATENT_TOL: f32 = 1e-5;
const MOTION_TOL: f32 = 1e-4;

fn bundle(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("onnx")
        .join("bundles")
        .join(name)
}

fn tiny() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| Model::load(bundle("umf-tiny")).expect("umf-tiny loads"))
}

fn temporal() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| Model::load(bundle("umf-tiny-temporal")).expect("umf-tiny-temporal loads"))
}

fn npy(model: &Model, name: &str) -> Option<ArrayD<f32>> {
    let path = model.source().join("golden").join(format!("{name}.npy"));
    path.exists()
        .then(|| read_npy(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

fn flat(a: &ArrayD<f32>) -> Vec<f32> {
    a.iter().copied().collect()
}

fn cases(model: &Model) -> serde_json::Map<String, Value> {
    let text = std::fs::read_to_string(model.source().join("golden/cases.json")).unwrap();
    serde_json::from_str::<Value>(&text)
        .unwrap()
        .as_object()
        .unwrap()
        .clone()
}

fn solver(v: &Value) -> Solver {
    let method = match v["method"].as_str().unwrap() {
        "euler" => Method::Euler,
        "rk4" => Method::Rk4,
        other => panic!("unknown method {other}"),
    };
    Solver {
        method,
        steps: v["steps"].as_u64().unwrap() as u32,
    }
}

/// The golden case's settings, and the noise it was run with.
fn case_options(
    model: &Model,
    case: &str,
    spec: &Value,
) -> (usize, Option<Vec<f32>>, GroupOptions, GroupNoise) {
    let people = spec["people"].as_u64().unwrap() as usize;
    let condition = npy(model, &format!("{case}_condition")).map(|c| flat(&c));
    assert_eq!(
        condition.is_some(),
        spec["has_condition"].as_bool().unwrap()
    );
    let stages = model.umf().unwrap().spec().pyramid.stages.len();
    let noise = GroupNoise {
        prior: flat(&npy(model, &format!("{case}_prior_noise")).unwrap()),
        jumps: (1..stages)
            .map(|s| flat(&npy(model, &format!("{case}_jump{s}")).unwrap()))
            .collect(),
        reactions: npy(model, &format!("{case}_reaction_noise"))
            .map(|r| {
                r.outer_iter()
                    .map(|p| p.iter().copied().collect())
                    .collect()
            })
            .unwrap_or_default(),
    };
    let options = GroupOptions {
        seed: spec["seed"].as_u64().unwrap_or(0),
        cfg_scale: Some(spec["cfg_scale"].as_f64().unwrap() as f32),
        prior: Some(
            spec["prior"]
                .as_array()
                .unwrap()
                .iter()
                .map(solver)
                .collect(),
        ),
        reaction: Some(solver(&spec["reaction"])),
        noise: None,
    };
    (people, condition, options, noise)
}

fn max_abs(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Every golden case of `model`: injected noise reproduces the reference; for seeded cases the
/// seeded draws equal the reference's noise files too.
fn check_golden(model: &Model) -> usize {
    let mut checked = 0;
    for (case, spec) in cases(model) {
        let (people, condition, mut options, noise) = case_options(model, &case, &spec);
        if !spec["seed"].is_null() {
            let drawn = model
                .umf()
                .unwrap()
                .group_noise(options.seed, people)
                .unwrap();
            assert_eq!(drawn.prior, noise.prior, "{case}: seeded prior noise");
            assert_eq!(
                drawn.reactions, noise.reactions,
                "{case}: seeded reaction noise"
            );
            for (k, (a, b)) in drawn.jumps.iter().zip(&noise.jumps).enumerate() {
                assert_eq!(a, b, "{case}: seeded jump noise {k}");
            }
        } else {
            options.noise = Some(noise);
        }
        let group = model
            .umf()
            .unwrap()
            .generate_group(condition.as_deref(), people, &options)
            .unwrap();
        let latents = max_abs(
            group.latents.as_slice().unwrap(),
            &flat(&npy(model, &format!("{case}_latents")).unwrap()),
        );
        let want_motion = npy(model, &format!("{case}_motion")).unwrap();
        assert_eq!(group.motion.shape(), want_motion.shape(), "{case}");
        let motion = max_abs(group.motion.as_slice().unwrap(), &flat(&want_motion));
        println!(
            "{}/{case}: {people} people, max-abs latents {latents:.2e}, motion {motion:.2e}",
            model.manifest().name
        );
        assert!(latents <= LATENT_TOL, "{case}: latents off by {latents}");
        assert!(motion <= MOTION_TOL, "{case}: motion off by {motion}");
        checked += 1;
    }
    checked
}

#[test]
fn golden_parity_grid_pyramid_1_to_4_people() {
    let model = tiny();
    let names: Vec<String> = cases(model).keys().cloned().collect();
    for needed in [
        "rk4_1p",
        "rk4_2p",
        "text_3p",
        "rk4_4p",
        "euler_paper_2p",
        "seeded_2p",
    ] {
        assert!(
            names.iter().any(|n| n == needed),
            "missing golden case {needed}"
        );
    }
    assert!(check_golden(model) >= 6);
}

#[test]
fn golden_parity_temporal_pyramid_with_three_stages() {
    let model = temporal();
    assert_eq!(model.umf().unwrap().spec().pyramid.stages.len(), 3);
    assert!(check_golden(model) >= 2);
}

/// The official text branches: CLIP token features give the condition the reference computed,
/// the one the text-conditioned golden group (`text_3p`) was generated from.
#[test]
fn text_branch_gives_the_reference_condition() {
    let model = tiny();
    assert_eq!(model.text_token_dim(), Some(16));
    assert_eq!(temporal().text_token_dim(), Some(16));
    let golden = model.source().join("golden");
    let tokens: Array2<f32> = read_npy(golden.join("text_clip_tokens.npy")).unwrap();
    let eot: Array1<i64> = read_npy(golden.join("text_eot_index.npy")).unwrap();
    let got = model.encode_text(tokens.view(), eot[0] as usize).unwrap();
    assert_eq!(got.len(), model.condition_dim());
    let want = flat(&npy(model, "text_condition").unwrap());
    let err = max_abs(&got, &want);
    println!("umf-tiny text branch: max-abs condition {err:.2e}");
    assert!(err <= LATENT_TOL, "text branch off by {err}");
    assert_eq!(want, flat(&npy(model, "text_3p_condition").unwrap()));
    // CLIP's width is 16 here, not the condition's 32.
    let wide = Array2::<f32>::zeros((77, 32));
    let msg = model.encode_text(wide.view(), 1).unwrap_err().to_string();
    assert!(
        msg.contains("expected at least one token of 16 floats"),
        "{msg}"
    );
}

#[test]
fn seeds_are_deterministic_and_people_build_on_each_other() {
    let model = tiny();
    let opts = |seed| GroupOptions {
        seed,
        ..Default::default()
    };
    let a = model
        .umf()
        .unwrap()
        .generate_group(None, 3, &opts(5))
        .unwrap();
    let b = model
        .umf()
        .unwrap()
        .generate_group(None, 3, &opts(5))
        .unwrap();
    assert_eq!(a.motion, b.motion);
    let c = model
        .umf()
        .unwrap()
        .generate_group(None, 3, &opts(6))
        .unwrap();
    assert_ne!(a.latents, c.latents);
    // The first two people of a three-person group are the two-person group with that seed:
    // each person depends only on the ones before it.
    let two = model
        .umf()
        .unwrap()
        .generate_group(None, 2, &opts(5))
        .unwrap();
    let first_two = a.latents.slice(ndarray::s![..2, .., ..]);
    assert_eq!(first_two, two.latents);
    assert_eq!(
        (a.motion.shape()[1], a.motion.shape()[2]),
        (model.clip_frames(), model.frame_dim())
    );
}

fn invalid(result: troupe::Result<troupe::Group>) -> String {
    match result {
        Err(e @ (Error::InvalidInput(_) | Error::InvalidOption(_))) => e.to_string(),
        Err(e) => panic!("wrong error kind: {e}"),
        Ok(_) => panic!("accepted a bad input"),
    }
}

#[test]
fn bad_inputs_are_rejected_with_a_clear_error() {
    let model = tiny();
    let ok = GroupOptions::default();
    let msg = invalid(model.umf().unwrap().generate_group(None, 0, &ok));
    assert!(msg.contains("people is 0"), "{msg}");
    let msg = invalid(model.umf().unwrap().generate_group(Some(&[0.0; 5]), 1, &ok));
    assert!(msg.contains("condition has 5 floats"), "{msg}");
    let mut nan = vec![0.0; model.condition_dim()];
    nan[3] = f32::NAN;
    let msg = invalid(model.umf().unwrap().generate_group(Some(&nan), 1, &ok));
    assert!(msg.contains("index 3"), "{msg}");
    let one_stage = GroupOptions {
        prior: Some(vec![Solver::euler(10)]),
        ..Default::default()
    };
    let msg = invalid(model.umf().unwrap().generate_group(None, 1, &one_stage));
    assert!(
        msg.contains("1 prior solvers given for a pyramid of 2 stages"),
        "{msg}"
    );
    let zero_steps = GroupOptions {
        reaction: Some(Solver::rk4(0)),
        ..Default::default()
    };
    assert!(invalid(model.umf().unwrap().generate_group(None, 2, &zero_steps)).contains("0 steps"));
    let cfg = GroupOptions {
        cfg_scale: Some(f32::INFINITY),
        ..Default::default()
    };
    assert!(invalid(model.umf().unwrap().generate_group(None, 1, &cfg)).contains("CFG"));
    let mut noise = model.umf().unwrap().group_noise(1, 2).unwrap();
    noise.reactions.pop();
    let short = GroupOptions {
        noise: Some(noise),
        ..Default::default()
    };
    let msg = invalid(model.umf().unwrap().generate_group(None, 2, &short));
    assert!(msg.contains("0 reactions"), "{msg}");
    // Families do not mix: what the bundle's family does not offer is unsupported.
    let armflow = Model::load(bundle("armflow-tiny")).unwrap();
    let e = armflow.umf().unwrap_err();
    assert!(matches!(e, Error::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("an `armflow` model"), "{e}");
    let e = model
        .session(troupe::SessionOptions::default())
        .unwrap_err();
    assert!(matches!(e, Error::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("a `umf` model"), "{e}");
}

/// Copies umf-tiny, edits its manifest, and returns the load error.
fn load_edited(edit: impl FnOnce(&mut Value)) -> String {
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(bundle("umf-tiny")).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_file() {
            std::fs::copy(entry.path(), dir.path().join(entry.file_name())).unwrap();
        }
    }
    let path = dir.path().join("troupe.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    match Model::load(dir.path()) {
        Err(e @ Error::Manifest { .. }) => e.to_string(),
        Err(e) => panic!("wrong error kind: {e}"),
        Ok(_) => panic!("loaded a mismatched bundle"),
    }
}

#[test]
fn mismatched_stage_tables_are_rejected_at_load() {
    let msg = load_edited(|v| v["pyramid"]["stages"][1]["start_t"] = 0.3.into());
    assert!(
        msg.contains("stages[1].start_t is 0.3") && msg.contains("0.2898"),
        "{msg}"
    );
    let msg = load_edited(|v| v["pyramid"]["gamma"] = (-0.25).into());
    assert!(msg.contains("start_t"), "{msg}");
    let msg = load_edited(|v| v["pyramid"]["stages"][0]["tokens"] = 8.into());
    assert!(msg.contains("stages[0] has 8 tokens"), "{msg}");
    let msg = load_edited(|v| {
        v["sampler"]["prior"].as_array_mut().unwrap().pop();
    });
    assert!(msg.contains("1 solvers for 2 pyramid stages"), "{msg}");
    let msg = load_edited(|v| v["text"]["prior_dim"] = 3.into());
    assert!(msg.contains("must equal condition.dim"), "{msg}");
    let msg = load_edited(|v| v["condition"]["null"] = Value::Array(vec![0.5.into()]));
    assert!(msg.contains("condition.null holds 1 floats"), "{msg}");
    let msg = load_edited(|v| v["pyramid"]["gamma"] = 0.5.into());
    assert!(msg.contains("gamma"), "{msg}");
    let msg = load_edited(|v| v["graphs"]["reaction"]["inputs"][0]["shape"][2] = 7.into());
    assert!(msg.contains("graphs.reaction.inputs"), "{msg}");
    let msg = load_edited(|v| v["family"] = "interdance".into());
    assert!(
        msg.contains("family `interdance` is not supported"),
        "{msg}"
    );
}

#[test]
fn shape_of_group_queries() {
    let model = tiny();
    assert_eq!(model.manifest().family_name(), "umf");
    assert_eq!((model.frames_per_token(), model.latency_frames()), (0, 0));
    assert_eq!(model.max_output_frames(10), 0);
    let noise = model.umf().unwrap().group_noise(0, 4).unwrap();
    let spec = model.umf().unwrap().spec();
    let dim = spec.latent.dim;
    assert_eq!(noise.prior.len(), spec.pyramid.stages[0].tokens * dim);
    assert_eq!(noise.reactions.len(), 3);
}
