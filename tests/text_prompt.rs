//! Text prompts to conditions through the Rust API: every committed bundle that carries CLIP's
//! text tower and tokenizer gives, for the golden prompts, the token ids of OpenAI's tokenizer
//! exactly and the condition of the PyTorch reference within 1e-5; the empty prompt is the
//! manifest's null condition (the official "no text"); sessions, clips and groups conditioned on
//! a prompt equal the same conditioned on its vector; bundles and manifests that cannot take
//! prompts are refused with a message.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use ndarray::{Array2, Axis};
use ndarray_npy::read_npy;
use troupe::{Error, Model, ReactorOptions};

/// The bundles exported with a text encoder.
const PROMPT_BUNDLES: [&str; 4] = [
    "armflow-tiny-interhuman",
    "armflow-tiny-interx",
    "umf-tiny",
    "umf-tiny-temporal",
];

/// Max-abs tolerance of prompt -> condition against the PyTorch reference at tiny size.
const TOLERANCE: f32 = 1e-5;

fn bundle(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("onnx/bundles")
        .join(name)
}

fn golden_prompts(dir: &Path) -> (Vec<String>, Array2<i64>, Array2<f32>) {
    let g = dir.join("golden");
    let prompts: Vec<String> =
        serde_json::from_str(&std::fs::read_to_string(g.join("prompts.json")).unwrap()).unwrap();
    let ids: Array2<i64> = read_npy(g.join("prompt_ids.npy")).unwrap();
    let conditions: Array2<f32> = read_npy(g.join("prompt_conditions.npy")).unwrap();
    assert_eq!(prompts.len(), ids.nrows());
    (prompts, ids, conditions)
}

#[test]
fn golden_prompts_give_the_reference_ids_and_conditions() {
    for name in PROMPT_BUNDLES {
        let dir = bundle(name);
        let model = Model::load(&dir).unwrap();
        assert!(model.takes_prompts(), "{name}");
        let (prompts, ids, conditions) = golden_prompts(&dir);
        let mut worst = 0f32;
        for (i, prompt) in prompts.iter().enumerate() {
            let got = model.prompt_token_ids(prompt).unwrap();
            assert_eq!(got, ids.row(i).to_vec(), "{name}: ids of {prompt:?}");
            let condition = model.encode_prompt(prompt).unwrap();
            let err = max_abs_diff(&condition, conditions.row(i).as_slice().unwrap());
            assert!(
                err <= TOLERANCE,
                "{name}: {prompt:?} is {err} from the reference"
            );
            worst = worst.max(err);
            // Asked again, the cached condition is the same.
            assert_eq!(model.encode_prompt(prompt).unwrap(), condition);
        }
        println!(
            "{name}: {} prompts, ids exact, conditions within {worst:.2e} of the reference",
            prompts.len()
        );
    }
}

#[test]
fn the_empty_prompt_is_the_null_condition() {
    for name in PROMPT_BUNDLES {
        let model = Model::load(bundle(name)).unwrap();
        let condition = &model.manifest().condition;
        assert_eq!(condition.null_source(), "empty_prompt", "{name}");
        let null = condition.null.as_ref().unwrap();
        let err = max_abs_diff(&model.encode_prompt("").unwrap(), null);
        assert!(
            err <= TOLERANCE,
            "{name}: empty prompt {err} from condition.null"
        );
        assert!(
            null.iter().any(|&v| v != 0.0),
            "{name}: the null is not zeros"
        );
    }
}

#[test]
fn sessions_clips_and_groups_take_prompts_as_their_vectors() {
    let prompt = "two people shake hands";
    let armflow = Model::load(bundle("armflow-tiny-interhuman")).unwrap();
    let condition = armflow.encode_prompt(prompt).unwrap();
    let actor = golden2_in(&bundle("armflow-tiny-interhuman"), "clip_actor");
    let run = |options: ReactorOptions, set_prompt: bool| {
        let mut s = armflow.session(options).unwrap();
        if set_prompt {
            s.set_prompt(prompt).unwrap();
        }
        s.step(actor.view()).unwrap()
    };
    let seeded = |condition: Option<Vec<f32>>, prompt: Option<String>| ReactorOptions {
        seed: 3,
        condition,
        prompt,
        ..Default::default()
    };
    let by_vector = run(seeded(Some(condition.clone()), None), false);
    assert_eq!(run(seeded(None, Some(prompt.into())), false), by_vector);
    assert_eq!(run(seeded(None, None), true), by_vector);
    assert_ne!(
        run(seeded(None, None), false),
        by_vector,
        "the prompt changes the output"
    );
    match armflow.session(seeded(Some(condition.clone()), Some(prompt.into()))) {
        Err(Error::InvalidOption(m)) => assert!(m.contains("not both"), "{m}"),
        other => panic!("condition and prompt together: {other:?}"),
    }
}

fn golden2_in(dir: &Path, name: &str) -> Array2<f32> {
    read_npy(dir.join("golden").join(format!("{name}.npy"))).unwrap()
}

#[test]
fn bundles_without_a_text_encoder_refuse_prompts_by_name() {
    let model = model();
    assert!(!model.takes_prompts());
    for result in [
        model.encode_prompt("hello").map(|_| ()),
        model.prompt_token_ids("hello").map(|_| ()),
        model
            .session(ReactorOptions {
                prompt: Some("hello".into()),
                ..default_options()
            })
            .map(|_| ()),
    ] {
        match result {
            Err(Error::InvalidInput(m)) => {
                assert!(
                    m.contains("armflow-tiny") && m.contains("takes no text prompts"),
                    "{m}"
                )
            }
            other => panic!("a prompt to a bundle without a text encoder: {other:?}"),
        }
    }
    let mut session = model.session(default_options()).unwrap();
    assert!(session.set_prompt("hello").is_err());
}

#[test]
fn over_long_and_unusual_prompts_are_cut_at_77_tokens_or_refused() {
    let model = Model::load(bundle("armflow-tiny-interhuman")).unwrap();
    let long = "a person waves ".repeat(200);
    let ids = model.prompt_token_ids(&long).unwrap();
    assert_eq!(ids.len(), 77);
    let eot = *ids.iter().max().unwrap();
    assert_eq!(ids[76], eot, "the last id of a cut prompt is <|endoftext|>");
    assert!(model
        .encode_prompt(&long)
        .unwrap()
        .iter()
        .all(|v| v.is_finite()));
    for odd in ["\u{0}", "\t\n  ", "🏃‍♀️🤝", "<|endoftext|> hidden", "ÀÉÎÕÜ ﬁ"] {
        let c = model.encode_prompt(odd).unwrap();
        assert!(c.iter().all(|v| v.is_finite()), "{odd:?}");
    }
    let huge = "x".repeat(1 << 20);
    assert!(matches!(
        model.encode_prompt(&huge),
        Err(Error::InvalidInput(_))
    ));
}

/// Loads `dir`, expecting a manifest error that mentions `needle`.
fn refused(dir: &Path, needle: &str) {
    match Model::load(dir) {
        Err(e @ Error::Manifest { .. }) => assert!(e.to_string().contains(needle), "{e}"),
        other => panic!("expected a manifest error about {needle:?}, got {other:?}"),
    }
}

#[test]
fn inconsistent_text_sections_are_refused_at_load() {
    let bundle = copy_of_bundle("armflow-tiny-interhuman");
    let dir = bundle.path();
    let original = std::fs::read_to_string(dir.join("troupe.json")).unwrap();
    let reset = || std::fs::write(dir.join("troupe.json"), &original).unwrap();

    edit_manifest(dir, |m| {
        m.as_object_mut().unwrap().remove("tokenizer");
    });
    refused(dir, "tokenizer");
    reset();
    edit_manifest(dir, |m| m["tokenizer"]["merges"] = 999.into());
    refused(dir, "merges");
    reset();
    edit_manifest(dir, |m| m["tokenizer"]["kind"] = "sentencepiece".into());
    refused(dir, "tokenizer.kind");
    reset();
    edit_manifest(dir, |m| m["tokenizer"]["context"] = 78.into());
    refused(dir, "tokenizer.context");
    reset();
    edit_manifest(dir, |m| m["condition"]["null_source"] = "zeros".into());
    refused(dir, "null_source");
    reset();
    edit_manifest(dir, |m| {
        m["condition"]["null_source"] = "label:mirror".into()
    });
    refused(dir, "label");
    reset();
    edit_manifest(dir, |m| m["condition"]["null_source"] = "whatever".into());
    refused(dir, "unknown");
    reset();
    // A merges file that is not a merges file.
    std::fs::write(
        dir.join("clip_merges.txt"),
        "#version: 0.2\nonly-one-symbol\n",
    )
    .unwrap();
    match Model::load(dir) {
        Err(e) => assert!(e.to_string().contains("clip_merges.txt"), "{e}"),
        Ok(_) => panic!("a broken merges file loaded"),
    }
}

#[test]
fn a_prompt_session_streams_like_a_vector_session_token_by_token() {
    let dir = bundle("armflow-tiny-interhuman");
    let model = Model::load(&dir).unwrap();
    let actor = golden2_in(&dir, "clip_actor");
    let prompt = "A person waves at the other, then both sit down.";
    let mut a = model
        .session(ReactorOptions {
            prompt: Some(prompt.into()),
            ..Default::default()
        })
        .unwrap();
    let mut b = model
        .session(ReactorOptions {
            condition: Some(model.encode_prompt(prompt).unwrap()),
            ..Default::default()
        })
        .unwrap();
    for chunk in actor.axis_chunks_iter(Axis(0), 7) {
        assert_eq!(a.step(chunk).unwrap(), b.step(chunk).unwrap());
    }
}
