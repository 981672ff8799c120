//! The fuzz targets' bodies, shared by the coverage-guided cargo-fuzz binaries
//! (`fuzz/fuzz_targets/*.rs`, nightly) and by `tests/fuzz.rs`, which replays the committed corpus
//! and every crash ever found, then mutates the corpus for a bounded time on the stable
//! toolchain. A body may return any error; what it must never do is panic, abort, hang, or let
//! a non-finite value out.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use troupe::Model;

/// The committed tiny bundle every target builds on.
pub fn bundle_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|p| p.join("onnx/bundles/armflow-tiny").is_dir())
        .expect("the repository root")
        .join("onnx/bundles/armflow-tiny")
}

/// The tiny bundle's files, by name.
pub fn bundle_files() -> &'static Vec<(String, Vec<u8>)> {
    static FILES: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    FILES.get_or_init(|| {
        let mut files: Vec<_> = std::fs::read_dir(bundle_dir())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .map(|p| {
                let name = p.file_name().unwrap().to_str().unwrap().to_owned();
                (name, std::fs::read(&p).unwrap())
            })
            .collect();
        files.sort();
        files
    })
}

/// The tiny model, loaded once.
pub fn model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| Model::load(bundle_dir()).expect("the committed bundle loads"))
}

/// The tiny bundle's manifest without the digests of its files, as a bundle written before the
/// exporters recorded them: a replaced graph then reaches the graph loader's checks instead of
/// being refused for its digest.
fn manifest_without_digests() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let (_, text) = bundle_files()
            .iter()
            .find(|(name, _)| name == "troupe.json")
            .expect("the manifest");
        let mut manifest: serde_json::Value = serde_json::from_slice(text).unwrap();
        manifest.as_object_mut().unwrap().remove("sha256");
        serde_json::to_vec(&manifest).unwrap()
    })
}

/// A tar archive of the tiny bundle with `replace`'s file swapped for the given bytes (and, when
/// that is not the manifest, the manifest's digests left out).
pub fn archive_with(replace: &str, bytes: &[u8]) -> Vec<u8> {
    let mut builder = tar::Builder::new(Vec::new());
    for (name, data) in bundle_files() {
        let data = match name.as_str() {
            _ if name == replace => bytes,
            "troupe.json" => manifest_without_digests(),
            _ => data,
        };
        let mut header = tar::Header::new_gnu();
        header.set_size(data.len() as u64);
        header.set_mode(0o644);
        builder.append_data(&mut header, name, data).unwrap();
    }
    builder.into_inner().unwrap()
}

/// Tar archives: any bytes as a whole bundle.
pub fn tar_archive(data: &[u8]) {
    let _ = Model::from_archive_bytes(data, "fuzz.troupe");
}

/// Manifests: parsed and validated always; when valid, loaded with the real graphs.
pub fn manifest(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if troupe::Manifest::parse(text, Path::new("troupe.json")).is_ok() {
        let _ = Model::from_archive_bytes(&archive_with("troupe.json", data), "fuzz.troupe");
    }
}

/// ONNX bytes as a velocity graph, through the graph loader (guard, typing, interface check,
/// optimisation) and one run; one input in 64 through the whole bundle loader instead.
pub fn onnx_graph(data: &[u8]) {
    if data.first().is_some_and(|b| b % 64 == 0) {
        let _ = Model::from_archive_bytes(&archive_with("velocity.onnx", data), "fuzz.troupe");
    } else {
        let _ = troupe::load_graph_for_fuzzing(data);
    }
}

/// Reads little-endian numbers off the front of the data.
pub struct Bytes<'a>(pub &'a [u8]);

impl Bytes<'_> {
    pub fn u8(&mut self) -> u8 {
        let Some((&b, rest)) = self.0.split_first() else {
            return 0;
        };
        self.0 = rest;
        b
    }

    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    pub fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Steps `session` up to six times from what is left of `bytes`: chunks of fewer than `most` frames of
/// arbitrary values, an occasional reset; every step either fails or gives finite frames.
fn step_arbitrarily(session: &mut troupe::Session, bytes: &mut Bytes, most: u8) {
    let d = session.frame_dim();
    // A few calls per input: executions, not long streams, are what reach new code.
    for _ in 0..6 {
        if bytes.is_empty() {
            break;
        }
        let frames = usize::from(bytes.u8() % most);
        let mode = bytes.u8();
        let chunk: Vec<f32> = (0..frames * d)
            .map(|i| match mode % 4 {
                0 => ((i as f32) * 0.37).sin(),
                1 => f32::from(bytes.u8()) / 32.0 - 4.0,
                2 => bytes.f32(),
                _ => 0.0,
            })
            .collect();
        if let Ok(out) = session.step_flat(&chunk) {
            assert!(
                out.frames.iter().all(|v| v.is_finite()),
                "a step returned a non-finite frame"
            );
        }
        if mode == 255 {
            session.reset();
        }
    }
}

/// A session stepped with arbitrary options, chunking and values: every step either fails
/// (leaving the session usable) or gives finite frames.
pub fn session_step(data: &[u8]) {
    let model = model();
    let mut bytes = Bytes(data);
    let options = troupe::ReactorOptions {
        seed: u64::from(bytes.u32()),
        steps: Some(u32::from(bytes.u8() % 4)),
        cfg_scale: Some(match bytes.u8() % 4 {
            0 => 1.0,
            1 => bytes.f32(),
            _ => f32::from(bytes.u8()) / 16.0,
        }),
        context_capacity: Some(usize::from(bytes.u8() % 12)),
        ..Default::default()
    };
    let Ok(mut session) = model.session(options) else {
        return;
    };
    step_arbitrarily(&mut session, &mut bytes, 9);
}

/// A committed bundle other than the ARMFlow one, loaded once per name.
fn other_model(name: &'static str) -> &'static Model {
    static MODELS: OnceLock<std::sync::Mutex<Vec<(&'static str, &'static Model)>>> =
        OnceLock::new();
    let mut models = MODELS.get_or_init(Default::default).lock().unwrap();
    if let Some((_, m)) = models.iter().find(|(n, _)| *n == name) {
        return m;
    }
    let dir = bundle_dir().parent().unwrap().join(name);
    let model: &'static Model = Box::leak(Box::new(Model::load(dir).expect("committed bundle")));
    models.push((name, model));
    model
}

/// The golden live configuration of a MAGNet partner at `steps` steps, guidance smoothing off
/// or on (no opening, seed 0).
fn live_partner(steps: u8, guided: bool) -> troupe::PartnerOptions {
    let guidance = if guided {
        r#"{"weight": 2.0, "start": 0.0, "end": 1.0}"#
    } else {
        "null"
    };
    let config = format!(
        r#"{{"task": "motion_control_live", "steps": {steps}, "eta": 0.0,
        "schedule": "causal_uncertainty", "subseq_len": 4, "ar_seq_stride": 8,
        "offset_proportion": 0.0, "seq_len": 96, "context_len": 32, "samples": 1,
        "root_mode": "temporal", "temporal_smoothing": 0.3, "smoothing_start": 0,
        "update_history_transforms": true, "seed": 5, "guidance": {{"scales": [["clean", 1.0]],
        "subset_ratio": 0.5, "partial_level": 0.5, "smoothing": {guidance},
        "foot_skating": null}}}}"#
    );
    troupe::PartnerOptions {
        live_config: Some(config),
        ..Default::default()
    }
}

/// A live partner's opening: 32 frames of a figure standing still, feet on the ground.
fn live_opening() -> Vec<f32> {
    (0..32 * 145)
        .map(|i| match i % 145 {
            10..=135 if (i % 145 - 10) % 6 == 0 || (i % 145 - 10) % 6 == 4 => 1.0,
            136 | 140 => 1.0,
            143 => 0.9,
            _ => 0.0,
        })
        .collect()
}

/// MAGNet's live partner and ARFlow's online stream with arbitrary settings, opening frames,
/// chunking and values: every step either fails (the stream usable) or gives finite frames.
/// One input in two then edits the stream's snapshot ([`edit_snapshot`]) and steps what it
/// restores.
pub fn other_streams(data: &[u8]) {
    let mut bytes = Bytes(data);
    let magnet = bytes.u8() % 2 == 0;
    let session = if magnet {
        let (steps, guided) = (1 + bytes.u8() % 4, bytes.u8() % 2 == 1);
        let options = troupe::PartnerOptions {
            seed: u64::from(bytes.u32()),
            opening: (bytes.u8() % 8 != 0).then(live_opening),
            early_emission: bytes.u8() % 2 == 0,
            ..live_partner(steps, guided)
        };
        other_model("magnet-tiny").session(options)
    } else {
        let options = troupe::ArflowOptions {
            seed: u64::from(bytes.u32()),
            steps: Some(usize::from(bytes.u8() % 4)),
            guidance: Some(f32::from(bytes.u8()) / 32.0),
            weight: Some(f32::from(bytes.u8()) / 200.0),
            eta: Some(f32::from(bytes.u8()) / 300.0),
            d_safe: Some(f32::from(bytes.u8()) / 100.0),
            squared: Some(bytes.u8() % 2 == 0),
            sigma: Some(f32::from(bytes.u8() % 4) / 100.0),
            ..Default::default()
        };
        other_model("arflow-tiny-online").session(options)
    };
    let Ok(mut session) = session else {
        return;
    };
    step_arbitrarily(&mut session, &mut bytes, 40);
    // The stream's snapshot (a MAGNet live partner's or an ARFlow online stream's), edited and
    // restored: refused, or a stream that steps on.
    if bytes.u8() % 2 == 0 {
        let Ok(mut snapshot) = session.snapshot() else {
            return;
        };
        edit_snapshot(&mut snapshot, &mut bytes);
        let model = other_model(if magnet {
            "magnet-tiny"
        } else {
            "arflow-tiny-online"
        });
        if let Ok(mut restored) = model.restore(&snapshot) {
            step_arbitrarily(&mut restored, &mut Bytes(&[9, 0, 33, 0]), 40);
        }
    }
}

/// The penetration metrics and loss on arbitrary joints: errors for non-finite input, finite
/// results otherwise, never a panic.
pub fn penetration(data: &[u8]) {
    use troupe::motion::{penetration_metrics, BodyModel, Hinge, PenetrationLoss};
    let mut bytes = Bytes(data);
    let frames = usize::from(bytes.u8() % 6);
    let mut person = || -> Vec<Vec<[f64; 3]>> {
        (0..frames)
            .map(|_| {
                (0..22)
                    .map(|_| {
                        [0; 3].map(|_| match bytes.u8() % 3 {
                            0 => f64::from(bytes.f32()),
                            _ => f64::from(bytes.u8()) / 100.0 - 1.0,
                        })
                    })
                    .collect()
            })
            .collect()
    };
    let (a, b) = (person(), person());
    let body = BodyModel::t2m22();
    if let Ok(m) = penetration_metrics(&body, &a, &b) {
        assert!(m.frequency.is_finite() && m.depth_sum.is_finite() && m.max_depth.is_finite());
    }
    let loss = PenetrationLoss {
        d_safe: f64::from(bytes.f32()),
        hinge: if bytes.u8() % 2 == 0 {
            Hinge::Linear
        } else {
            Hinge::Squared
        },
    };
    if let Ok(p) = loss.evaluate(&body, &a, &b) {
        assert!(p.loss.is_finite());
        assert!(p.gradient.iter().flatten().flatten().all(|v| v.is_finite()));
    }
}

/// Arbitrary sequences of C API calls on one model: sessions created, stepped, reconfigured,
/// reset and freed in any order, with arbitrary sizes and NULLs. Only statuses may come back.
pub fn c_api_sequence(data: &[u8]) {
    use troupe::ffi::session::*;
    use troupe::ffi::status::TROUPE_OK;
    static HANDLE: OnceLock<usize> = OnceLock::new();
    let model = *HANDLE.get_or_init(|| {
        let path = std::ffi::CString::new(bundle_dir().to_str().unwrap()).unwrap();
        let mut out = std::ptr::null_mut();
        // SAFETY: a valid path and out-pointer.
        let st = unsafe { troupe::ffi::model::troupe_model_load_file(path.as_ptr(), &mut out) };
        assert_eq!(st, TROUPE_OK);
        out as usize
    });
    // SAFETY: the handle loaded above lives for the process.
    let model = unsafe { (model as *const troupe::ffi::model::troupe_model).as_ref() };
    let d = 262usize;
    let mut bytes = Bytes(data);
    let mut sessions: Vec<*mut troupe_session> = Vec::new();
    let frames: Vec<f32> = (0..16 * d).map(|i| ((i as f32) * 0.01).cos()).collect();
    let mut out = vec![0f32; 16 * d];
    let mut written = 0usize;
    while !bytes.is_empty() {
        let op = bytes.u8();
        let pick = usize::from(bytes.u8());
        let session = if sessions.is_empty() || pick == 255 {
            std::ptr::null_mut()
        } else {
            sessions[pick % sessions.len()]
        };
        // SAFETY: every pointer passed is NULL, a live handle from `sessions`, or a buffer of
        // the size passed with it; freed handles are removed from `sessions` at once.
        unsafe {
            match op % 10 {
                0 if sessions.len() < 8 => {
                    let mut options = std::mem::zeroed::<troupe_session_options>();
                    let mut s = std::ptr::null_mut();
                    if troupe_session_options_init(
                        model,
                        &mut options,
                        std::mem::size_of_val(&options),
                    ) == TROUPE_OK
                    {
                        options.steps = bytes.u32() % 5;
                        options.cfg_scale = bytes.f32();
                        options.context_capacity = bytes.u32() % 20;
                        if troupe_session_new(model, &options, &mut s) == TROUPE_OK {
                            sessions.push(s);
                        }
                    }
                }
                1 => {
                    let n = usize::from(bytes.u8() % 17);
                    let cap = usize::from(bytes.u8() % 17);
                    troupe_session_step(
                        session,
                        frames.as_ptr(),
                        n,
                        out.as_mut_ptr(),
                        cap,
                        &mut written,
                    );
                    assert!(out[..written.min(16) * d].iter().all(|v| v.is_finite()));
                }
                2 => {
                    troupe_session_set_steps(session, bytes.u32());
                }
                3 => {
                    troupe_session_set_cfg_scale(session, bytes.f32());
                }
                4 => {
                    troupe_session_reset(session);
                }
                5 => {
                    let len = usize::from(bytes.u8());
                    troupe_session_set_condition(session, frames.as_ptr(), len);
                }
                6 => {
                    let len = usize::from(bytes.u8());
                    troupe::ffi::armflow::noise::troupe_armflow_session_queue_noise(
                        session,
                        frames.as_ptr(),
                        frames.as_ptr(),
                        len,
                    );
                }
                7 if !session.is_null() => {
                    troupe_session_free(session);
                    sessions.retain(|&s| s != session);
                }
                8 => {
                    let n = usize::from(bytes.u8() % 5);
                    let mut ready = 0;
                    troupe_session_output_frames(session, n, &mut ready);
                }
                9 if !sessions.is_empty() => {
                    let count = sessions.len().min(usize::from(bytes.u8() % 4) + 1);
                    let ins: Vec<*const f32> = vec![frames.as_ptr(); count];
                    let n_in: Vec<usize> =
                        (0..count).map(|_| usize::from(bytes.u8() % 5)).collect();
                    let mut outs: Vec<Vec<f32>> = vec![vec![0f32; 8 * d]; count];
                    let out_ptrs: Vec<*mut f32> = outs.iter_mut().map(|o| o.as_mut_ptr()).collect();
                    let caps = vec![8usize; count];
                    let mut n_out = vec![0usize; count];
                    troupe_sessions_step(
                        sessions.as_ptr(),
                        count,
                        ins.as_ptr(),
                        n_in.as_ptr(),
                        out_ptrs.as_ptr(),
                        caps.as_ptr(),
                        n_out.as_mut_ptr(),
                    );
                    for (o, &n) in outs.iter().zip(&n_out) {
                        assert!(o[..n.min(8) * d].iter().all(|v| v.is_finite()));
                    }
                }
                _ => {}
            }
        }
    }
    for s in sessions {
        // SAFETY: live handles, freed once.
        unsafe { troupe_session_free(s) };
    }
}

/// A target's body.
pub type Target = fn(&[u8]);

/// Every target by name, for the replay and mutation test.
pub const TARGETS: [(&str, Target); 15] = [
    ("tar_archive", tar_archive),
    ("manifest", manifest),
    ("onnx_graph", onnx_graph),
    ("session_step", session_step),
    ("c_api_sequence", c_api_sequence),
    ("other_streams", other_streams),
    ("penetration", penetration),
    ("bvh_reader", bvh_reader),
    ("fbx_reader", fbx_reader),
    ("prompt_encoder", prompt_encoder),
    ("magnet_config", magnet_config),
    ("motion_encoder", motion_encoder),
    ("rig_retarget", rig_retarget),
    ("session_snapshot", session_snapshot),
    ("snapshot_edits", snapshot_edits),
];

/// The snapshot of every kind of stream, each with the state that kind adds, made once per
/// process: (its model, the snapshot, whether it takes joint positions).
fn prepared_snapshots() -> &'static Vec<(&'static Model, Vec<u8>, bool)> {
    static SNAPSHOTS: OnceLock<Vec<(&'static Model, Vec<u8>, bool)>> = OnceLock::new();
    SNAPSHOTS.get_or_init(|| {
        let armflow = model();
        let mut out = Vec::new();
        let features = |s: &troupe::Session, frames: usize| -> Vec<f32> {
            (0..frames * s.frame_dim())
                .map(|i| ((i as f32) * 0.37).sin())
                .collect()
        };
        // Feature streams with every option that adds state: a small ring that wraps, CFG, the
        // guard and the smoothing, and either the VAE over windows or recentring (which needs
        // the per-token VAE).
        for windows in [true, false] {
            let mut busy = armflow
                .session(troupe::ReactorOptions {
                    seed: 3,
                    steps: Some(2),
                    cfg_scale: Some(1.5),
                    context_capacity: Some(3),
                    vae_windows: windows,
                    recentring: (!windows).then(troupe::Recentring::default),
                    ..Default::default()
                })
                .expect("options in range");
            busy.set_penetration_guard(Some(troupe::PenetrationGuard::default()))
                .expect("an armflow session is guarded");
            busy.set_root_smoothing(Some(troupe::RootSmoothing::default()))
                .expect("an armflow session is smoothed");
            let frames = features(&busy, 21);
            busy.step_flat(&frames).expect("finite frames step");
            out.push((armflow, busy.snapshot().expect("saves"), false));
        }
        // Joint streams, resampled from other rates, one with the foot lock.
        for (fps, foot_lock) in [(120.0, true), (29.97, false)] {
            let mut joints = armflow
                .session(troupe::ReactorOptions::default())
                .expect("defaults");
            let format = troupe::motion::JointsFormat {
                fps,
                ..Default::default()
            };
            joints.set_joints_format(format).expect("a valid format");
            if foot_lock {
                joints
                    .set_foot_lock(Some(troupe::FootLockOptions::default()))
                    .expect("an armflow session locks feet");
            }
            joints
                .step_joints(joint_frames(23, 0).view())
                .expect("finite positions step");
            out.push((armflow, joints.snapshot().expect("saves"), true));
        }
        // MAGNet's live partner, past its opening, and ARFlow's online stream.
        let magnet = other_model("magnet-tiny");
        let mut live = magnet
            .session(troupe::PartnerOptions {
                opening: Some(live_opening()),
                ..live_partner(2, true)
            })
            .expect("the golden live configuration");
        let frames = features(&live, 40);
        live.step_flat(&frames).expect("finite frames step");
        out.push((magnet, live.snapshot().expect("saves"), false));
        let arflow = other_model("arflow-tiny-online");
        let mut online = arflow
            .session(troupe::ArflowOptions {
                steps: Some(2),
                ..Default::default()
            })
            .expect("options in range");
        let frames = features(&online, 9);
        online.step_flat(&frames).expect("finite frames step");
        out.push((arflow, online.snapshot().expect("saves"), false));
        out
    })
}

/// The key sealed snapshots are fuzzed under.
const SEAL_KEY: &[u8] = b"the fuzzing key!";

/// The snapshot of a stream of every kind ([`prepared_snapshots`]: features with every option,
/// over VAE windows or recentred,
/// joint positions resampled with and without the foot lock, MAGNet's live partner, ARFlow's
/// online stream), edited as an attacker would ([`edit_snapshot`]), one time in four sealed
/// first and its seal edited too: refused, or a stream whose next calls stay bounded and save
/// again. Made once, the snapshots cost nothing per input, so this target runs far more edits a
/// second than those that make a stream for each.
pub fn snapshot_edits(data: &[u8]) {
    let mut bytes = Bytes(data);
    let prepared = prepared_snapshots();
    let (model, snapshot, joints) = &prepared[usize::from(bytes.u8()) % prepared.len()];
    let sealed = bytes.u8().is_multiple_of(4);
    let mut edited = if sealed {
        troupe::seal_snapshot(snapshot, SEAL_KEY).expect("a snapshot seals")
    } else {
        snapshot.clone()
    };
    edit_snapshot(&mut edited, &mut bytes);
    let restored = if sealed {
        model.restore_sealed(&edited, SEAL_KEY)
    } else {
        model.restore(&edited)
    };
    if let Ok(mut restored) = restored {
        goes_on_bounded(&mut restored, *joints);
    }
}

/// Whatever a restore accepted, the stream's next calls stay bounded (a tampered resampler
/// count once made this allocate until the host aborted), step to finite frames and save again.
/// `joints`: the stream takes joint positions.
fn goes_on_bounded(restored: &mut troupe::Session, joints: bool) {
    if joints {
        if let Ok(poses) = restored.step_joints(joint_frames(9, 40).view()) {
            assert!(
                poses.len() <= 64,
                "{} poses for 9 joint frames",
                poses.len()
            );
        }
    }
    step_arbitrarily(restored, &mut Bytes(&[4, 0, 9, 0]), 9);
    restored.snapshot().expect("a restored session saves");
}

/// Snapshots of streams: a real snapshot of a session stepped from the input (settings, the
/// guard, feature frames or, one time in three, joint positions at another rate with the foot
/// lock), then edited by the rest of the input ([`edit_snapshot`]); or, when the first byte
/// says so, the input itself as a snapshot. Whatever is restored takes joint positions with
/// bounded output, steps to finite frames and snapshots again.
pub fn session_snapshot(data: &[u8]) {
    let model = model();
    // Any bytes through the sealed restore: refused without reading past the seal's header.
    assert!(model.restore_sealed(data, b"the fuzzing key!").is_err());
    let mut bytes = Bytes(data);
    let snapshot = if bytes.u8() % 8 == 0 {
        bytes.0.to_vec()
    } else {
        let options = troupe::ReactorOptions {
            seed: u64::from(bytes.u8()),
            steps: Some(1 + u32::from(bytes.u8() % 3)),
            context_capacity: Some(2 + usize::from(bytes.u8() % 6)),
            vae_windows: bytes.u8() % 2 == 0,
            recentring: (bytes.u8() % 2 == 0).then(troupe::Recentring::default),
            ..Default::default()
        };
        let Ok(mut session) = model.session(options) else {
            return;
        };
        let guard = (bytes.u8() % 2 == 0).then(troupe::PenetrationGuard::default);
        let smoothing = (bytes.u8() % 2 == 0).then(troupe::RootSmoothing::default);
        session
            .set_penetration_guard(guard)
            .expect("an armflow session is guarded");
        session
            .set_root_smoothing(smoothing)
            .expect("an armflow session is smoothed");
        let frames = usize::from(bytes.u8() % 24);
        // One stream in three takes joint positions at another rate than the bundle's, so that
        // its snapshot carries the resampler's counts, the placement and the foot lock.
        let pick = usize::from(bytes.u8()) % (3 * JOINT_RATES.len());
        let joint_rate = JOINT_RATES.get(pick).copied().unwrap_or(0.0);
        if joint_rate > 0.0 {
            let format = troupe::motion::JointsFormat {
                fps: joint_rate,
                ..Default::default()
            };
            session.set_joints_format(format).expect("a valid format");
            if bytes.u8() % 2 == 0 {
                session
                    .set_foot_lock(Some(troupe::FootLockOptions::default()))
                    .expect("an armflow session locks feet");
            }
            session
                .step_joints(joint_frames(frames, 0).view())
                .expect("finite positions step");
        } else {
            let actor: Vec<f32> = (0..frames * session.frame_dim())
                .map(|i| ((i as f32) * 0.37).sin())
                .collect();
            session.step_flat(&actor).expect("finite frames step");
        }
        let mut snapshot = session.snapshot().expect("an armflow session saves");
        edit_snapshot(&mut snapshot, &mut bytes);
        snapshot
    };
    if let Ok(mut restored) = model.restore(&snapshot) {
        goes_on_bounded(&mut restored, true);
    }
}

/// Edits a snapshot as an attacker with write access to the store would: bytes and whole counts
/// rewritten (where the snapshot holds what reads as a small count: the counts and lengths;
/// float data seldom reads as one), sometimes cut short, and the checksum made to agree one
/// time in two, so that the edits reach the payload's checks.
fn edit_snapshot(snapshot: &mut Vec<u8>, bytes: &mut Bytes) {
    if snapshot.is_empty() {
        return;
    }
    let counts: Vec<usize> = (0..snapshot.len().saturating_sub(7))
        .filter(|&p| {
            let v = u64::from_le_bytes(snapshot[p..p + 8].try_into().unwrap());
            (1..=1 << 20).contains(&v)
        })
        .collect();
    for _ in 0..1 + bytes.u8() % 8 {
        if bytes.u8().is_multiple_of(2) && !counts.is_empty() {
            let at = counts[(bytes.u32() as usize) % counts.len()];
            let value = COUNTS[usize::from(bytes.u8()) % COUNTS.len()];
            snapshot[at..at + 8].copy_from_slice(&value.to_le_bytes());
        } else {
            let at = (bytes.u32() as usize) % snapshot.len();
            snapshot[at] = bytes.u8();
        }
    }
    if bytes.u8().is_multiple_of(4) {
        let keep = (bytes.u32() as usize) % (snapshot.len() + 1);
        snapshot.truncate(keep);
    }
    if bytes.u8().is_multiple_of(2) && snapshot.len() >= 4 {
        let n = snapshot.len() - 4;
        let crc = crc32fast::hash(&snapshot[..n]);
        snapshot[n..].copy_from_slice(&crc.to_le_bytes());
    }
}

/// Joint frame rates a fuzzed stream feeds (0: features instead); the bundle's is 30.
const JOINT_RATES: [f32; 5] = [24.0, 60.0, 120.0, 29.97, 100.0];

/// Counts an edited snapshot may carry.
const COUNTS: [u64; 8] = [0, 1, 121, 240, 1 << 31, 1 << 40, u64::MAX, u64::MAX / 2];

/// `n` frames of a standing figure that sways (t2m-22 joints, metres, Y up), from frame `t0`.
fn joint_frames(n: usize, t0: usize) -> ndarray::Array3<f32> {
    ndarray::Array3::from_shape_fn((n, 22, 3), |(t, j, d)| {
        let sway = (((t0 + t) as f32) * 0.2).sin() * 0.05;
        match d {
            0 => (j % 3) as f32 * 0.15 - 0.15 + sway,
            1 => 1.7 - (j / 3) as f32 * 0.2,
            _ => (j % 2) as f32 * 0.05,
        }
    })
}

/// Any bytes as a rig (a rig JSON document, or a BVH hierarchy): whatever is accepted retargets
/// a few frames of troupe's body moving to finite rotations and translations, and writes a
/// `.glb` and a BVH on the rig; anything else is an error.
pub fn rig_retarget(data: &[u8]) {
    use troupe::motion::bvh::{parse_bvh, write_rig_bvh, BvhWriteOptions};
    use troupe::motion::{
        write_glb, GltfOptions, GltfPerson, JointMap, RetargetOptions, Retargeter, Rig, Skeleton,
        SourceFrame,
    };
    let rig = match std::str::from_utf8(data).ok().map(Rig::from_json) {
        Some(Ok(rig)) => rig,
        _ => match parse_bvh(data, "fuzz.bvh").and_then(|b| b.rig(None, "fuzz")) {
            Ok(rig) => rig,
            Err(_) => return,
        },
    };
    let skeleton = Skeleton::t2m22();
    let Ok(mut retargeter) = Retargeter::new(
        &rig,
        &JointMap::builtin(),
        &skeleton,
        RetargetOptions::default(),
    ) else {
        return;
    };
    let rest = skeleton.rest_positions();
    let mut poses = Vec::new();
    for t in 0..6 {
        let wave = 0.05 * f64::from(t);
        let frame: Vec<[f64; 3]> = rest
            .iter()
            .enumerate()
            .map(|(j, p)| [p[0] + wave, p[1] + 0.02 * (wave * j as f64).sin(), p[2]])
            .collect();
        let pose = retargeter
            .push(&SourceFrame {
                positions: &frame,
                rotations: None,
                contacts: None,
            })
            .expect("a finite frame of 22 joints retargets");
        assert!(
            pose.rotations
                .iter()
                .all(|q| [q.w, q.x, q.y, q.z].iter().all(|v| v.is_finite()))
                && pose.root_translation.iter().all(|v| v.is_finite()),
            "a non-finite pose"
        );
        poses.push(pose);
    }
    let person = GltfPerson {
        name: "fuzz",
        rig: &rig,
        poses: &poses,
        color: [0.5, 0.5, 0.5],
    };
    if let Ok(bytes) = write_glb(&[person], &GltfOptions::default()) {
        assert_eq!(&bytes[..4], b"glTF");
    }
    let _ = write_rig_bvh(&rig, &poses, &BvhWriteOptions::default());
}

/// BVH text: whatever the reader accepts gives finite positions (forward kinematics of every
/// joint, and the t2m-22 joints through the built-in map), or an error.
pub fn bvh_reader(data: &[u8]) {
    use troupe::motion::bvh::parse_bvh;
    let Ok(bvh) = parse_bvh(data, "fuzz.bvh") else {
        return;
    };
    assert!(
        bvh.positions().iter().all(|v| v.is_finite()),
        "the reader accepted a file whose positions are not finite"
    );
    if let Ok(joints) = bvh.to_t2m22(&troupe::motion::JointMap::builtin(), None, "fuzz.bvh") {
        assert!(joints.positions.iter().all(|v| v.is_finite()));
    }
}

/// FBX bytes (binary or ASCII) through ufbx and troupe's conversion to a skeleton's clip:
/// whatever is accepted gives finite positions, a rig, and t2m-22 joints or an error.
pub fn fbx_reader(data: &[u8]) {
    use troupe::motion::fbx::parse_fbx;
    let Ok(clip) = parse_fbx(data, "fuzz.fbx", None) else {
        return;
    };
    assert!(
        clip.positions().iter().all(|v| v.is_finite()),
        "the reader accepted a file whose positions are not finite"
    );
    let _ = clip.rig(None, "fuzz");
    if let Ok(joints) = clip.to_t2m22(&troupe::motion::JointMap::builtin(), None, "fuzz.fbx") {
        assert!(joints.positions.iter().all(|v| v.is_finite()));
    }
}

/// Any text as a prompt, through the official-layout tiny bundle's tokenizer, text tower and
/// text branch: a finite condition or an error.
pub fn prompt_encoder(data: &[u8]) {
    let model = other_model("armflow-tiny-interhuman");
    let text = String::from_utf8_lossy(data);
    if let Ok(condition) = model.encode_prompt(&text) {
        assert!(
            condition.iter().all(|v| v.is_finite()),
            "a non-finite condition"
        );
    }
}

/// Plausible MAGNet frames `[F, P, 145]`: identity rotations, people a metre apart.
fn magnet_frames(frames: usize, people: usize) -> ndarray::Array3<f32> {
    ndarray::Array3::from_shape_fn((frames, people, 145), |(t, p, i)| match i {
        10..=135 if (i - 10) % 6 == 0 || (i - 10) % 6 == 4 => 1.0,
        136 | 140 | 144 => 1.0,
        139 => p as f32 + 0.01 * t as f32,
        143 => 0.9,
        _ => 0.0,
    })
}

/// Any text as a MAGNet sampling configuration (JSON): refused with a message, or checked and
/// then run at a bounded size (one sample, at most two steps, 64 frames) to finite frames.
pub fn magnet_config(data: &[u8]) {
    let model = other_model("magnet-tiny");
    let magnet = model.magnet().expect("a magnet bundle");
    let text = String::from_utf8_lossy(data);
    let frames = magnet_frames(128, 2);
    let quick = troupe::MagnetOptions {
        samples: Some(1),
        steps: Some(2),
        seq_len: Some(64),
        ..Default::default()
    };
    if magnet.output_shape(&text, 128, &quick).is_err() {
        return;
    }
    if let Ok(out) = magnet.generate(&text, frames.view(), None, &quick) {
        assert!(
            out.frames.iter().all(|v| v.is_finite()),
            "non-finite MAGNet frames"
        );
    }
}

/// Joint positions, formats and placements from the bytes through the clip encoder and the
/// feature stream: finite features or an error.
pub fn motion_encoder(data: &[u8]) {
    use troupe::motion::stream::FeatureStream;
    use troupe::motion::{encode_clip, Handedness, JointsFormat, Placement, Units, UpAxis};
    let mut bytes = Bytes(data);
    let format = JointsFormat {
        units: [Units::Meters, Units::Centimeters, Units::Millimeters][usize::from(bytes.u8() % 3)],
        up: [UpAxis::Y, UpAxis::Z][usize::from(bytes.u8() % 2)],
        handedness: [Handedness::Right, Handedness::Left][usize::from(bytes.u8() % 2)],
        fps: match bytes.u8() % 3 {
            0 => 30.0,
            1 => f32::from(bytes.u8()),
            _ => bytes.f32(),
        },
    };
    let frames = usize::from(bytes.u8() % 8);
    let positions =
        ndarray::Array3::from_shape_fn((frames, 22, 3), |(t, j, d)| match bytes.u8() % 4 {
            0 => bytes.f32(),
            1 => f32::from(bytes.u8()) / 50.0,
            _ => (t as f32) * 0.01 + (j as f32) * 0.07 * (d == 1) as u8 as f32,
        });
    let placement = (bytes.u8() % 2 == 0).then(|| Placement {
        floor: f64::from(bytes.f32()),
        origin: [f64::from(bytes.f32()), f64::from(bytes.f32())],
        ..Placement::identity(format)
    });
    if let Ok(clip) = encode_clip(positions.view(), format, 30.0, placement.as_ref()) {
        assert!(
            clip.features.iter().all(|v| v.is_finite()),
            "non-finite features"
        );
    }
    if let Ok(mut stream) = FeatureStream::new(format, 30.0, placement) {
        for frame in positions.outer_iter() {
            if let Ok(out) = stream.push(frame) {
                assert!(
                    out.iter().flatten().all(|v| v.is_finite()),
                    "non-finite features"
                );
            }
        }
    }
}
