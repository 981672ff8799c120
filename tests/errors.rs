//! Every bad input is rejected with a clear error and leaves the session as it was; corrupt or
//! mismatched bundles are rejected at load with the file, tensor and shape named.

mod common;

use std::path::Path;

use common::*;
use ndarray::{s, Array2};
use troupe::{Error, Model, Reactor, ReactorOptions, Session, TokenNoise};

/// A session that has consumed 10 frames (2 tokens), and a twin to compare against.
fn twins() -> (Session, Session) {
    let actor = actor();
    let mut a = model().session(default_options()).unwrap();
    let mut b = model().session(default_options()).unwrap();
    a.step(actor.slice(s![..10, ..])).unwrap();
    b.step(actor.slice(s![..10, ..])).unwrap();
    (a, b)
}

/// The session behaves exactly like its untouched twin from here on.
fn assert_unchanged(touched: &mut Session, twin: &mut Session) {
    assert_eq!(touched.frames_received(), twin.frames_received());
    assert_eq!(touched.tokens_generated(), twin.tokens_generated());
    let rest = actor().slice(s![10.., ..]).to_owned();
    assert!(run_chunked(touched, &rest, 9) == run_chunked(twin, &rest, 9));
}

fn message(e: Error) -> String {
    e.to_string()
}

#[test]
fn wrong_frame_dim_is_rejected() {
    let (mut s, mut twin) = twins();
    let e = s.step(Array2::<f32>::zeros((4, 100)).view()).unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)));
    assert!(
        message(e).contains("100 features"),
        "message names the size"
    );
    let e = s.step_flat(&[0.0; 263]).unwrap_err();
    assert!(message(e).contains("263 floats"));
    assert_unchanged(&mut s, &mut twin);
}

#[test]
fn non_finite_frames_are_rejected() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let (mut s, mut twin) = twins();
        let mut frames = actor().slice(s![10..20, ..]).to_owned();
        frames[[7, 5]] = bad;
        let e = s.step(frames.view()).unwrap_err();
        let text = message(e);
        assert!(
            text.contains("non-finite") && text.contains("at frame 7, feature 5"),
            "{text}"
        );
        assert_unchanged(&mut s, &mut twin);
    }
}

#[test]
fn bad_options_are_rejected() {
    let m = model();
    let opt = |o: ReactorOptions| m.session(o).unwrap_err();
    assert!(matches!(
        opt(ReactorOptions {
            steps: Some(0),
            ..Default::default()
        }),
        Error::InvalidOption(_)
    ));
    assert!(matches!(
        opt(ReactorOptions {
            cfg_scale: Some(f32::NAN),
            ..Default::default()
        }),
        Error::InvalidOption(_)
    ));
    assert!(matches!(
        opt(ReactorOptions {
            context_capacity: Some(1),
            ..Default::default()
        }),
        Error::InvalidOption(_)
    ));
    let e = opt(ReactorOptions {
        condition: Some(vec![0.0; 5]),
        ..Default::default()
    });
    assert!(message(e).contains("condition has 5 floats, the bundle expects 32"));
    let mut nan = vec![0.0; 32];
    nan[3] = f32::NAN;
    let e = opt(ReactorOptions {
        condition: Some(nan),
        ..Default::default()
    });
    assert!(message(e).contains("condition holds a non-finite value"));
}

#[test]
fn bad_setters_leave_the_session_unchanged() {
    let (mut s, mut twin) = twins();
    assert!(s.set_steps(0).is_err());
    assert!(s.set_cfg_scale(f32::INFINITY).is_err());
    assert!(s.set_condition(Some(&[1.0; 31])).is_err());
    assert!(s.set_condition(Some(&[f32::NAN; 32])).is_err());
    let lat = model().latent_dim();
    let e = s
        .family_mut::<Reactor>()
        .unwrap()
        .queue_noise(TokenNoise {
            actor: vec![0.0; lat - 1],
            reactor: vec![0.0; lat],
        })
        .unwrap_err();
    assert!(message(e).contains("actor noise has 15 floats"));
    let e = s
        .family_mut::<Reactor>()
        .unwrap()
        .queue_noise(TokenNoise {
            actor: vec![0.0; lat],
            reactor: vec![f32::NAN; lat],
        })
        .unwrap_err();
    assert!(message(e).contains("reactor noise holds a non-finite value"));
    assert_unchanged(&mut s, &mut twin);
}

#[test]
fn bad_history_for_recompute_is_rejected() {
    let e = model()
        .armflow()
        .unwrap()
        .recompute_context(None, &[0.0; 33])
        .unwrap_err();
    assert!(message(e).contains("not a multiple of the token width 32"));
    let e = model()
        .armflow()
        .unwrap()
        .recompute_context(Some(&[0.0; 3]), &[])
        .unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)));
}

// ---- bundles ----------------------------------------------------------------------------------

fn load_error(dir: &Path) -> String {
    message(Model::load(dir).unwrap_err())
}

#[test]
fn a_copy_of_the_bundle_loads() {
    let dir = bundle_copy();
    Model::load(dir.path()).unwrap();
}

#[test]
fn missing_bundle_or_manifest_names_the_path() {
    let e = Model::load("/nonexistent/bundle").unwrap_err();
    assert!(matches!(e, Error::Io { .. }));
    assert!(message(e).contains("/nonexistent/bundle/troupe.json"));
}

#[test]
fn corrupt_manifest_is_rejected() {
    let dir = bundle_copy();
    std::fs::write(dir.path().join("troupe.json"), "{ not json").unwrap();
    let text = load_error(dir.path());
    assert!(
        text.contains("troupe.json") && text.contains("key must be a string"),
        "{text}"
    );

    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| v["format_version"] = 2.into());
    assert!(load_error(dir.path()).contains("format_version 2 is not supported"));

    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| v["family"] = "interdance".into());
    assert!(load_error(dir.path()).contains("family `interdance` is not supported"));

    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v.as_object_mut().unwrap().remove("sampler");
    });
    assert!(load_error(dir.path()).contains("missing field `sampler`"));

    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| v["context"]["heads"] = 3.into());
    assert!(load_error(dir.path())
        .contains("context.heads 3 * context.head_dim 16 must equal context.width 32"));
}

#[test]
fn manifest_inconsistent_with_the_runtime_contract_names_tensor_and_shape() {
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["graphs"]["context_layers"][2]["inputs"][1]["shape"][1] = 4.into()
    });
    let text = load_error(dir.path());
    assert!(
        text.contains("graphs.context_layers.inputs (context_layer_2.onnx)")
            && text.contains("`attention` float32 [N, 4]"),
        "{text}"
    );
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["graphs"]["velocity"]["outputs"][0]["name"] = "u".into()
    });
    assert!(load_error(dir.path()).contains("missing tensor `velocity`"));
}

#[test]
fn condition_feedback_is_checked_at_load() {
    let feedback = |kind: &str| serde_json::json!({"kind": kind, "dim": 5});
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["condition"]["feedback"] = feedback("gaze")
    });
    let text = load_error(dir.path());
    assert!(
        text.contains("condition.feedback `gaze` of 5 floats is unknown"),
        "{text}"
    );
    // Declared, but the conditioning graph reads only the caller's 32 floats, not 32 + 5.
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["condition"]["feedback"] = feedback("partner_placement")
    });
    let text = load_error(dir.path());
    assert!(text.contains("`condition` float32 [1, 37]"), "{text}");
    // Only an ARMFlow stream reads its reactor's placement.
    let dir = copy_of_bundle("umf-tiny");
    edit_manifest(dir.path(), |v| {
        v["condition"]["feedback"] = feedback("partner_placement")
    });
    let text = load_error(dir.path());
    assert!(
        text.contains("condition.feedback `partner_placement` is not read by umf bundles"),
        "{text}"
    );
}

#[test]
fn missing_graph_file_names_it() {
    let dir = bundle_copy();
    std::fs::remove_file(dir.path().join("velocity.onnx")).unwrap();
    let e = Model::load(dir.path()).unwrap_err();
    assert!(matches!(e, Error::Io { .. }));
    assert!(message(e).contains("velocity.onnx"));
}

#[test]
fn corrupt_graph_is_rejected() {
    let dir = bundle_copy();
    let path = dir.path().join("vae_decoder.onnx");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 3]).unwrap();
    // Refused by its digest first; with the digest recorded again, by the ONNX reader.
    let e = Model::load(dir.path()).unwrap_err();
    assert!(message(e).contains("SHA-256"));
    record_digests(dir.path());
    let e = Model::load(dir.path()).unwrap_err();
    assert!(matches!(e, Error::Graph { .. }));
    let text = message(e);
    assert!(
        text.contains("vae_decoder.onnx") && text.contains("not a loadable ONNX model"),
        "{text}"
    );
}

#[test]
fn mismatched_graph_names_file_tensor_and_shape() {
    // A graph of another role in the velocity slot: its tensors are not the velocity's.
    let dir = bundle_copy();
    std::fs::copy(
        bundle_dir().join("conditioning.onnx"),
        dir.path().join("velocity.onnx"),
    )
    .unwrap();
    record_digests(dir.path());
    let text = load_error(dir.path());
    assert!(
        text.contains("velocity.onnx") && text.contains("graph input `condition` is not declared"),
        "{text}"
    );

    // A manifest that is consistent with itself but not with its graphs: condition dim 48
    // declared, 32 in the conditioning graph.
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["condition"]["dim"] = 48.into();
        v["graphs"]["conditioning"]["inputs"][0]["shape"][1] = 48.into();
    });
    let text = load_error(dir.path());
    assert!(
        text.contains("conditioning.onnx")
            && text.contains("input `condition` is F32 [1, 32] in the graph")
            && text.contains("the manifest declares `condition` float32 [1, 48]"),
        "{text}"
    );
}

/// The per-token VAE steps are checked like every graph: they come as a pair, need a streaming
/// VAE, and each `state_i` needs a `next_state_i` of its shape in the graph and the manifest.
#[test]
fn inconsistent_vae_step_graphs_are_rejected() {
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["graphs"]
            .as_object_mut()
            .unwrap()
            .remove("vae_decoder_step");
    });
    assert!(load_error(dir.path()).contains("come together"));
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["vae"]["encoder"]["lookahead_frames"] = 4.into()
    });
    assert!(load_error(dir.path()).contains("without lookahead"));
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["graphs"]["vae_encoder_step"]["outputs"][2]["shape"][2] = 5.into()
    });
    let text = load_error(dir.path());
    assert!(
        text.contains("graphs.vae_encoder_step.outputs") && text.contains("next_state_0"),
        "{text}"
    );
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        let inputs = v["graphs"]["vae_decoder_step"]["inputs"]
            .as_array_mut()
            .unwrap();
        inputs[1]["shape"][2] = 3.into();
        let outputs = v["graphs"]["vae_decoder_step"]["outputs"]
            .as_array_mut()
            .unwrap();
        outputs[1]["shape"][2] = 3.into();
    });
    let text = load_error(dir.path());
    assert!(
        text.contains("vae_decoder_step.onnx") && text.contains("state_0"),
        "{text}"
    );
}

#[test]
fn condition_labels_are_checked_at_load_and_named_on_use() {
    let one_hot = |k: usize| -> Vec<f32> { (0..32).map(|i| f32::from(i == k)).collect() };
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["condition"]["labels"] = serde_json::json!([
            {"name": "mirror", "vector": one_hot(0), "about": "mirrors"},
            {"name": "follow", "vector": one_hot(1)},
        ])
    });
    let model = Model::load(dir.path()).unwrap();
    let names: Vec<&str> = model
        .condition_labels()
        .iter()
        .map(|l| l.name.as_str())
        .collect();
    assert_eq!(names, ["mirror", "follow"]);
    assert_eq!(model.condition_for("follow").unwrap(), one_hot(1));
    let text = message(model.condition_for("dance").unwrap_err());
    assert!(
        text.contains("no condition `dance`") && text.contains("has: mirror, follow"),
        "{text}"
    );
    let plain = message(common::model().condition_for("mirror").unwrap_err());
    assert!(plain.contains("has no named conditions"), "{plain}");

    let bad: [(serde_json::Value, &str); 4] = [
        (
            serde_json::json!([{"name": "mirror", "vector": [1.0, 0.0]}]),
            "condition.labels[0] (`mirror`) holds 2 floats, condition.dim is 32",
        ),
        (
            serde_json::json!([{"name": "a", "vector": one_hot(0)}, {"name": "a", "vector": one_hot(1)}]),
            "condition.labels: `a` is named twice",
        ),
        (
            serde_json::json!([{"name": "", "vector": one_hot(0)}]),
            "condition.labels[0] has an empty or NUL-holding name",
        ),
        (
            serde_json::json!([{"name": "x", "vector": one_hot(0)}, {"vector": one_hot(1)}]),
            "missing field `name`",
        ),
    ];
    for (labels, want) in bad {
        let dir = bundle_copy();
        edit_manifest(dir.path(), |v| v["condition"]["labels"] = labels);
        let text = load_error(dir.path());
        assert!(text.contains(want), "{text}");
    }
}
