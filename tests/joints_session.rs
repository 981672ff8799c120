//! Sessions that speak joint positions: `Session::step_joints` and `step_sessions_joints` on
//! real motion capture (the committed CMU excerpt, 120 fps, Z up), against the feature path.

mod common;

use ndarray::{s, Array2, Array3, ArrayView3, Axis};
use ndarray_npy::read_npy;
use troupe::motion::{
    decode_frame, FeatureStream, FootLockOptions, JointsFormat, Pose, Units, UpAxis,
};
use troupe::{
    step_sessions_joints, Model, Reactor, ReactorOptions, Recentring, Session, HISTORY_TOKENS,
};

fn cmu() -> Array3<f32> {
    read_npy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/mocap/cmu-playground-120fps.npy"),
    )
    .unwrap()
}

fn format() -> JointsFormat {
    JointsFormat {
        units: Units::Meters,
        up: UpAxis::Z,
        fps: 120.0,
        ..Default::default()
    }
}

#[test]
fn joints_in_poses_out_equal_the_feature_path() {
    let model = common::model();
    let clip = cmu().slice(s![..200, .., ..]).to_owned();
    let mut joints = model.session(common::default_options()).unwrap();
    joints.set_joints_format(format()).unwrap();
    assert_eq!(
        joints.joints_latency_frames().unwrap(),
        model.latency_frames() + 1
    );
    assert_eq!(model.joints_latency_frames(), model.latency_frames() + 1);
    // Streams that take no joint positions have no joint latency.
    for other in ["armflow-tiny-interx", "umf-tiny"] {
        let m = Model::load(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("onnx/bundles")
                .join(other),
        );
        assert_eq!(m.unwrap().joints_latency_frames(), 0, "{other}");
    }
    // The same motion through an explicit feature stream and the feature session.
    let mut features = model.session(common::default_options()).unwrap();
    let mut stream = FeatureStream::new(format(), model.fps() as f32, None).unwrap();
    let (mut poses, mut expected) = (Vec::new(), Vec::new());
    for chunk in clip.axis_chunks_iter(Axis(0), 7) {
        poses.extend(joints.step_joints(chunk).unwrap());
        let rows: Vec<f32> = chunk
            .outer_iter()
            .flat_map(|f| stream.push(f).unwrap())
            .flatten()
            .collect();
        let rows = Array2::from_shape_vec((rows.len() / 262, 262), rows).unwrap();
        let out = features.step(rows.view()).unwrap();
        let placement = *stream.placement().unwrap();
        expected.extend(
            out.outer_iter()
                .map(|r| decode_frame(r, &placement).unwrap()),
        );
    }
    // 200 frames at 120 fps are 50 at 30 fps, 49 feature frames, 12 whole tokens of 4 frames.
    assert_eq!(poses.len(), 48);
    assert_eq!(poses, expected);
    assert_eq!(joints.joints_placement(), stream.placement().copied());
    // Poses are in the caller's world: z up, near where the actor is.
    let root = poses[0].root_translation();
    let actor_root = [clip[[0, 0, 0]], clip[[0, 0, 1]]];
    let distance = ((root[0] - actor_root[0]).powi(2) + (root[1] - actor_root[1]).powi(2)).sqrt();
    assert!(
        distance < 10.0,
        "reactor root {root:?}, actor {actor_root:?}"
    );
}

#[test]
fn a_refused_chunk_leaves_the_session_and_its_joint_stream_unchanged() {
    let model = common::model();
    let clip = cmu().slice(s![..80, .., ..]).to_owned();
    let mut a = model.session(common::default_options()).unwrap();
    let mut b = model.session(common::default_options()).unwrap();
    for session in [&mut a, &mut b] {
        session.set_joints_format(format()).unwrap();
        session.step_joints(clip.slice(s![..40, .., ..])).unwrap();
    }
    let mut bad = clip.slice(s![40..60, .., ..]).to_owned();
    bad[[13, 5, 2]] = f32::NAN;
    let err = a.step_joints(bad.view()).unwrap_err().to_string();
    assert!(
        err.contains("frame 13") && err.contains("right_knee"),
        "{err}"
    );
    let wrong = Array3::<f32>::zeros((3, 24, 3));
    assert!(a.step_joints(wrong.view()).is_err());
    let rest = clip.slice(s![40.., .., ..]);
    assert_eq!(a.step_joints(rest).unwrap(), b.step_joints(rest).unwrap());
}

#[test]
fn many_sessions_at_once_equal_each_alone() {
    let model = common::model();
    let clip = cmu();
    let chunks = [
        clip.slice(s![..64, .., ..]),
        clip.slice(s![300..340, .., ..]),
    ];
    let make = || -> Vec<Session> {
        (0..2)
            .map(|i| {
                let mut s = model
                    .session(troupe::ReactorOptions {
                        seed: 5 + i,
                        ..Default::default()
                    })
                    .unwrap();
                s.set_joints_format(format()).unwrap();
                s
            })
            .collect()
    };
    let (mut together, mut alone) = (make(), make());
    let mut refs: Vec<_> = together.iter_mut().collect();
    let batched = step_sessions_joints(&mut refs, &chunks).unwrap();
    for (i, s) in alone.iter_mut().enumerate() {
        assert_eq!(batched[i], s.step_joints(chunks[i]).unwrap(), "session {i}");
    }
}

#[test]
fn bundles_without_joint_features_refuse_joints() {
    let interx = Model::load(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-tiny-interx"),
    )
    .unwrap();
    let mut session = interx.session(common::default_options()).unwrap();
    let err = session.set_joints_format(format()).unwrap_err().to_string();
    assert!(err.contains("interhuman262"), "{err}");
    let err = session
        .step_joints(cmu().slice(s![..4, .., ..]))
        .unwrap_err()
        .to_string();
    assert!(err.contains("interhuman262"), "{err}");
}

#[test]
fn the_foot_lock_holds_feet_moves_nothing_else_and_restarts_with_the_stream() {
    let model = common::model();
    let clip = cmu().slice(s![..400, .., ..]).to_owned();
    let stream = |lock: Option<FootLockOptions>| {
        let mut s = model.session(common::default_options()).unwrap();
        s.set_foot_lock(lock).unwrap();
        s.set_joints_format(format()).unwrap();
        (s.step_joints(clip.view()).unwrap(), s)
    };
    // A threshold the tiny model's labels cross, and a stretch that never lets go.
    let lock = FootLockOptions {
        contact_threshold: 0.05,
        max_stretch: 1.0,
        ..FootLockOptions::default()
    };
    let (free, _) = stream(None);
    let (held, mut session) = stream(Some(lock));
    assert_eq!(free.len(), held.len());
    let (mut still, mut pairs) = (0, 0);
    for t in 1..held.len() {
        assert_eq!(free[t].contacts, held[t].contacts);
        assert_eq!(
            free[t].positions[0], held[t].positions[0],
            "the root is untouched"
        );
        for (ankle, label) in [(7, 0), (8, 2)] {
            let on = |p: &troupe::motion::Pose| p.contacts[label] >= lock.contact_threshold;
            if on(&held[t]) && on(&held[t - 1]) {
                pairs += 1;
                let step: f32 = (0..3)
                    .map(|d| {
                        (held[t].positions[ankle][d] - held[t - 1].positions[ankle][d]).powi(2)
                    })
                    .sum();
                still += usize::from(step.sqrt() < 1e-4);
            }
        }
    }
    assert!(pairs > 10 && still * 2 > pairs, "{still} of {pairs} held");
    // Refused settings leave the lock as it was; a reset stream repeats itself exactly.
    assert!(session
        .set_foot_lock(Some(FootLockOptions {
            release_frames: 0,
            ..lock
        }))
        .is_err());
    assert_eq!(session.foot_lock(), Some(lock));
    session.reset();
    assert_eq!(session.step_joints(clip.view()).unwrap(), held);
}

fn recentring_session(model: &Model, seed: u64, distance: Option<f64>) -> Session {
    let mut s = model
        .session(ReactorOptions {
            seed,
            recentring: distance.map(|distance| Recentring { distance }),
            ..Default::default()
        })
        .unwrap();
    s.set_joints_format(format()).unwrap();
    s
}

fn stream_in_chunks(session: &mut Session, clip: ArrayView3<f32>, chunk: usize) -> Vec<Pose> {
    clip.axis_chunks_iter(Axis(0), chunk)
        .flat_map(|c| session.step_joints(c).unwrap())
        .collect()
}

#[test]
fn recentring_does_not_depend_on_how_frames_are_split_and_a_refused_call_undoes_it() {
    let model = common::model();
    let clip = cmu();
    let clip = clip.slice(s![..720, .., ..]);
    let whole = stream_in_chunks(&mut recentring_session(model, 3, Some(0.25)), clip, 8);
    // It recentred: the networks saw other positions than without it (the actor travels 1.7 m).
    let plain = stream_in_chunks(&mut recentring_session(model, 3, None), clip, 8);
    assert_eq!(
        whole[..8],
        plain[..8],
        "nothing moves before the actor does"
    );
    assert_ne!(whole, plain);
    // Calls of 13 frames, with a refused call in the middle of each fourth: the same stream.
    let mut session = recentring_session(model, 3, Some(0.25));
    let mut got = Vec::new();
    for (k, chunk) in clip.axis_chunks_iter(Axis(0), 13).enumerate() {
        if k % 4 == 3 {
            let memory = session.memory_bytes();
            let mut bad = chunk.to_owned();
            let last = bad.shape()[0] - 1;
            bad[[last, 3, 1]] = f32::NAN;
            assert!(session.step_joints(bad.view()).is_err());
            assert_eq!(session.memory_bytes(), memory);
        }
        got.extend(session.step_joints(chunk).unwrap());
    }
    assert_eq!(got, whole);
}

/// Feature frames (the CMU clip's, its first root at the origin) moved 5 m along x and 3 m along
/// z: a recentring session moves its centre to the first root at once, so the networks see what
/// they see of the clip where it was, and the reactor comes back moved by the same 5 and 3 m.
#[test]
fn a_recentring_session_answers_motion_far_from_the_origin_as_at_it() {
    let model = common::model();
    let actor: Array2<f32> = read_npy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/mocap/cmu-playground.features.npy"),
    )
    .unwrap();
    let moved_by = |frames: &Array2<f32>, by: [f32; 2]| {
        let mut out = frames.clone();
        for mut row in out.outer_iter_mut() {
            for j in 0..22 {
                row[3 * j] += by[0];
                row[3 * j + 2] += by[1];
            }
        }
        out
    };
    let stream = |frames: &Array2<f32>, recentring: bool| {
        let mut session = model
            .session(ReactorOptions {
                recentring: recentring.then_some(Recentring { distance: 0.5 }),
                ..Default::default()
            })
            .unwrap();
        let rows: Vec<Array2<f32>> = frames
            .axis_chunks_iter(Axis(0), 12)
            .map(|c| session.step(c).unwrap())
            .collect();
        ndarray::concatenate(Axis(0), &rows.iter().map(|r| r.view()).collect::<Vec<_>>()).unwrap()
    };
    let near = stream(&actor, true);
    let far = stream(&moved_by(&actor, [5.0, 3.0]), true);
    // Turned on mid-stream, far from the centre, it waits for a token of history, then moves.
    let mut late = model.session(ReactorOptions::default()).unwrap();
    let moved = moved_by(&actor, [5.0, 3.0]);
    late.step(moved.slice(s![..40, ..])).unwrap();
    late.family_mut::<Reactor>()
        .unwrap()
        .set_recentring(Some(Recentring::default()))
        .unwrap();
    for chunk in moved.slice(s![40.., ..]).axis_chunks_iter(Axis(0), 1) {
        assert!(late.step(chunk).unwrap().iter().all(|v| v.is_finite()));
    }
    let back = moved_by(&far, [-5.0, -3.0]);
    let diff = common::max_abs_diff(back.as_slice().unwrap(), near.as_slice().unwrap());
    assert!(diff < 1e-3, "{diff}");
    // Without recentring the networks see the moved motion, and answer otherwise.
    let far = moved_by(&stream(&moved_by(&actor, [5.0, 3.0]), false), [-5.0, -3.0]);
    let diff = common::max_abs_diff(far.as_slice().unwrap(), near.as_slice().unwrap());
    assert!(diff > 0.05, "{diff}");
}

#[test]
fn recentring_sessions_stepped_together_equal_each_alone() {
    let model = common::model();
    let clip = cmu();
    let make = || -> Vec<Session> {
        (0..2)
            .map(|i| recentring_session(model, 5 + i, Some(0.25)))
            .collect()
    };
    let (mut together, mut alone) = (make(), make());
    for start in (0..600).step_by(12) {
        let chunks = [
            clip.slice(s![start..start + 12, .., ..]),
            clip.slice(s![start + 300..start + 312, .., ..]),
        ];
        let mut refs: Vec<_> = together.iter_mut().collect();
        let batched = step_sessions_joints(&mut refs, &chunks).unwrap();
        for (i, s) in alone.iter_mut().enumerate() {
            assert_eq!(
                batched[i],
                s.step_joints(chunks[i]).unwrap(),
                "session {i}, {start}"
            );
        }
    }
}

#[test]
fn recentring_is_refused_where_it_cannot_run_and_out_of_range() {
    let model = common::model();
    let windows = ReactorOptions {
        vae_windows: true,
        ..Default::default()
    };
    let mut session = model.session(windows.clone()).unwrap();
    let on = Some(Recentring::default());
    assert!(matches!(
        session.family_mut::<Reactor>().unwrap().set_recentring(on),
        Err(troupe::Error::Unsupported(_))
    ));
    assert_eq!(session.family_ref::<Reactor>().unwrap().recentring(), None);
    let refused = model.session(ReactorOptions {
        recentring: on,
        ..windows
    });
    assert!(matches!(refused, Err(troupe::Error::Unsupported(_))));

    let mut session = recentring_session(model, 0, Some(1.0));
    for distance in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e3] {
        let err = session
            .family_mut::<Reactor>()
            .unwrap()
            .set_recentring(Some(Recentring { distance }));
        assert!(
            matches!(err, Err(troupe::Error::InvalidOption(_))),
            "{distance}"
        );
        assert_eq!(
            session.family_ref::<Reactor>().unwrap().recentring(),
            Some(Recentring { distance: 1.0 })
        );
    }
    // The history it keeps is bounded (the last HISTORY_TOKENS tokens of both people), and
    // dropped when it is turned off.
    let clip = cmu();
    let mut plain = recentring_session(model, 0, None);
    let token_bytes = 2 * model.frames_per_token() * 262 * 4;
    let history = HISTORY_TOKENS * token_bytes;
    for chunk in clip.axis_chunks_iter(Axis(0), 40) {
        session.step_joints(chunk).unwrap();
        plain.step_joints(chunk).unwrap();
        // Room for one token more than it keeps, made once.
        assert!(session.memory_bytes() <= plain.memory_bytes() + history + token_bytes);
    }
    let held = session.memory_bytes();
    session
        .family_mut::<Reactor>()
        .unwrap()
        .set_recentring(None)
        .unwrap();
    assert!(held - session.memory_bytes() >= history);
}

/// Every streaming family takes the same joint positions and gives poses back: ARFlow's online
/// stream (its `interhuman262` frames, as ARMFlow's) and MAGNet's live partner (its SMPL-X
/// frames found by inverse kinematics), through the same `Session` calls as ARMFlow's reactor.
#[test]
fn every_streaming_family_streams_joint_positions() {
    let bundles = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles");
    let clip = cmu().slice(s![..360, .., ..]).to_owned();
    let magnet = Model::load(bundles.join("magnet-tiny")).unwrap();
    // A partner opening from the bundle's golden pair (frames of the model's own world).
    let golden: Array3<f32> = read_npy(bundles.join("magnet-tiny/golden/frames.npy")).unwrap();
    let opening = |frames: usize| -> Vec<f32> {
        golden
            .slice(s![..frames, 1, ..])
            .as_standard_layout()
            .iter()
            .copied()
            .collect()
    };
    let arflow = Model::load(bundles.join("arflow-tiny-online")).unwrap();
    let armflow = common::model();
    for (model, latency) in [(armflow, 1), (&arflow, 1), (&magnet, 0)] {
        let mut session = model.session(troupe::SessionOptions::default()).unwrap();
        if let Ok(partner) = session.family_mut::<troupe::LivePartner>() {
            partner.set_partner_opening(&opening(32)).unwrap();
        }
        session.set_joints_format(format()).unwrap();
        assert_eq!(
            session.joints_latency_frames().unwrap(),
            model.latency_frames() + latency,
            "{}",
            model.family()
        );
        let mut poses = Vec::new();
        for chunk in clip.axis_chunks_iter(Axis(0), 12) {
            let want = session.joints_ready_after(chunk.shape()[0]).unwrap();
            let got = session.step_joints(chunk).unwrap();
            assert_eq!(got.len(), want, "{}", model.family());
            poses.extend(got);
        }
        // 360 frames at 120 fps are 90 at 30: all but the latency come back, finite, with unit
        // root rotations (the tiny models are untrained: where their bodies stand is not checked).
        let family = model.family();
        assert!(
            poses.len() + model.latency_frames() + latency >= 90 && poses.len() <= 90,
            "{family}: {} poses",
            poses.len()
        );
        for pose in &poses {
            assert!(
                pose.positions.iter().flatten().all(|v| v.is_finite()),
                "{family}"
            );
            let q = pose.rotations[0];
            let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
            assert!((n - 1.0).abs() < 1e-3, "{family}: {q:?}");
        }
        // The guard and the smoothing take every family's joints; the foot lock needs contacts.
        session
            .set_penetration_guard(Some(troupe::PenetrationGuard::default()))
            .unwrap();
        session
            .set_root_smoothing(Some(troupe::RootSmoothing::default()))
            .unwrap();
        let lock = session.set_foot_lock(Some(FootLockOptions::default()));
        assert_eq!(lock.is_ok(), family != "magnet", "{family}: {lock:?}");
        let more = session
            .step_joints(cmu().slice(s![360..480, .., ..]))
            .unwrap();
        assert!(!more.is_empty(), "{family}");
        // A snapshot keeps the stages and the conversion: the restored session goes on alike.
        let mut restored = model.restore(&session.snapshot().unwrap()).unwrap();
        let next = cmu().slice(s![480..560, .., ..]).to_owned();
        assert_eq!(
            restored.step_joints(next.view()).unwrap(),
            session.step_joints(next.view()).unwrap(),
            "{family}"
        );
    }
}
