//! The penetration guard of ARMFlow (and ARFlow online) streams on the trained demo model and real motion capture
//! (`tests/data/mocap/cmu-playground.features.npy`): the mirror partner keeps out of the actor by
//! itself and the guard keeps it so; when a glitching tracker jumps the actor onto the partner,
//! the guard makes the reactor pass through the actor less often and less deep; it never moves
//! faster than the guard's speed limit and keeps the body's shape; off, nothing changes; a crowd
//! with the guard equals each stream alone.

use std::path::PathBuf;

use ndarray::{s, Array2};
use ndarray_npy::read_npy;
use troupe::motion::{penetration_metrics, BodyModel, PenetrationMetrics};
use troupe::{
    step_sessions, Error, Model, PenetrationGuard, ReactorOptions, RootSmoothing, Session,
};

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn demo() -> Model {
    Model::load(repo("onnx/bundles/armflow-demo")).unwrap()
}

fn actor() -> Array2<f32> {
    read_npy(repo("tests/data/mocap/cmu-playground.features.npy")).unwrap()
}

fn session(model: &Model, rule: &str, guard: Option<PenetrationGuard>) -> Session {
    let mut session = model
        .session(ReactorOptions {
            seed: 7,
            condition: Some(model.condition_for(rule).unwrap()),
            ..Default::default()
        })
        .unwrap();
    session.set_penetration_guard(guard).unwrap();
    session
}

fn stream(session: &mut Session, actor: &Array2<f32>) -> Array2<f32> {
    let mut out = Vec::new();
    for chunk in actor.axis_chunks_iter(ndarray::Axis(0), 10) {
        out.extend(session.step(chunk).unwrap().iter().copied());
    }
    Array2::from_shape_vec((out.len() / 262, 262), out).unwrap()
}

fn joints(frames: &Array2<f32>) -> Vec<Vec<[f64; 3]>> {
    frames
        .outer_iter()
        .map(|f| {
            (0..22)
                .map(|j| [0, 1, 2].map(|k| f[3 * j + k] as f64))
                .collect()
        })
        .collect()
}

fn metrics(actor: &Array2<f32>, reactor: &Array2<f32>) -> PenetrationMetrics {
    let a = actor.slice(s![..reactor.nrows(), ..]).to_owned();
    penetration_metrics(&BodyModel::t2m22(), &joints(&a), &joints(reactor)).unwrap()
}

/// The CMU clip as a glitching tracker delivers it: every second the actor's reported position
/// jumps onto the spot where `rule`'s partner stands at that frame, and stays shifted after. The
/// committed model's partners keep out of the actor of the clip as captured by themselves (and
/// step away from one that walks into them), so a glitch is what puts the bodies inside each
/// other: for the frames the model needs to react, nothing but the guard stands between them.
fn glitched_actor(model: &Model, rule: &str) -> Array2<f32> {
    let mut actor = actor();
    let n = actor.nrows();
    for k in (30..n - 10).step_by(30) {
        let partner = stream(&mut session(model, rule, None), &actor);
        let shift = [
            partner[[k, 0]] - actor[[k, 0]],
            partner[[k, 2]] - actor[[k, 2]],
        ];
        for j in 0..22 {
            for (axis, d) in [(0, shift[0]), (2, shift[1])] {
                actor
                    .slice_mut(s![k.., 3 * j + axis])
                    .mapv_inplace(|x| x + d);
                // A frame's velocity is the step to the next frame: the one before the jump.
                actor[[k - 1, 66 + 3 * j + axis]] += d;
            }
        }
    }
    actor
}

#[test]
fn the_guard_pulls_the_reactor_out_without_jumps() {
    let model = demo();
    let guard = PenetrationGuard::default();
    let step = guard.max_speed / 30.0;
    for (case, actor) in [
        ("as captured", actor()),
        ("glitching", glitched_actor(&model, "mirror")),
    ] {
        let rule = "mirror";
        let free = stream(&mut session(&model, rule, None), &actor);
        let guarded = stream(&mut session(&model, rule, Some(guard)), &actor);
        let (before, after) = (metrics(&actor, &free), metrics(&actor, &guarded));
        println!(
            "{case}: intersecting frames {} -> {}, depth sum {:.3} -> {:.3} m",
            before.frames_intersecting,
            after.frames_intersecting,
            before.depth_sum,
            after.depth_sum
        );
        if case == "as captured" {
            // The committed model's mirror partner keeps out of the actor on this clip by
            // itself; the guard must not push it in.
            assert_eq!(before.frames_intersecting, 0, "{case}: the model alone");
            assert_eq!(after.frames_intersecting, 0, "{case}: with the guard");
        } else {
            assert!(
                before.frames_intersecting >= 5,
                "{case}: the glitches should put the bodies inside each other"
            );
            assert!(
                2 * after.frames_intersecting <= before.frames_intersecting,
                "{case}"
            );
            assert!(after.depth_sum < 0.5 * before.depth_sum, "{case}");
        }
        // A rigid shift in the floor plane, at most `step` per frame: heights, rotations and
        // contacts as decoded; every joint shifted by the same offset.
        let mut previous = [0f64; 2];
        for (t, (g, f)) in guarded.outer_iter().zip(free.outer_iter()).enumerate() {
            let o = [(g[0] - f[0]) as f64, (g[2] - f[2]) as f64];
            for j in 0..22 {
                assert!(
                    ((g[3 * j] - f[3 * j]) as f64 - o[0]).abs() < 1e-5,
                    "{case} {t}"
                );
                assert!(
                    (g[3 * j + 1] - f[3 * j + 1]).abs() < 1e-6,
                    "{case} {t}: height"
                );
                assert!(((g[3 * j + 2] - f[3 * j + 2]) as f64 - o[1]).abs() < 1e-5);
                let dv = (g[66 + 3 * j] - f[66 + 3 * j]) as f64;
                assert!(
                    (dv - (o[0] - previous[0])).abs() < 1e-5,
                    "{case} {t}: velocity"
                );
            }
            assert_eq!(g.slice(s![132..]), f.slice(s![132..]), "{case} {t}");
            let moved = ((o[0] - previous[0]).powi(2) + (o[1] - previous[1]).powi(2)).sqrt();
            assert!(
                moved <= step + 1e-5,
                "{case} {t}: the offset moved {moved} m"
            );
            previous = o;
        }
    }
}

#[test]
fn off_by_default_and_a_crowd_equals_each_alone() {
    let model = demo();
    let actor = actor();
    let plain = stream(&mut session(&model, "mirror", None), &actor);
    let mut switched = session(&model, "mirror", Some(PenetrationGuard::default()));
    switched.set_penetration_guard(None).unwrap();
    assert_eq!(stream(&mut switched, &actor), plain);
    // A crowd: two guarded streams and one free, stepped together.
    let guard = Some(PenetrationGuard::default());
    let alone: Vec<Array2<f32>> = [("mirror", guard), ("keep-away", guard), ("mirror", None)]
        .iter()
        .map(|&(rule, g)| stream(&mut session(&model, rule, g), &actor))
        .collect();
    let mut crowd = [
        session(&model, "mirror", guard),
        session(&model, "keep-away", guard),
        session(&model, "mirror", None),
    ];
    let mut together: Vec<Vec<f32>> = vec![Vec::new(); 3];
    for chunk in actor.axis_chunks_iter(ndarray::Axis(0), 10) {
        let chunk = chunk.as_standard_layout().into_owned();
        let frames = [chunk.as_slice().unwrap(); 3];
        let mut refs: Vec<&mut Session> = crowd.iter_mut().collect();
        for (i, out) in step_sessions(&mut refs, &frames)
            .unwrap()
            .into_iter()
            .enumerate()
        {
            together[i].extend(out.frames.iter().copied());
        }
    }
    for (i, (got, want)) in together.iter().zip(&alone).enumerate() {
        let worst = got
            .iter()
            .zip(want.iter())
            .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
        let scale = want.iter().fold(0f32, |m, v| m.max(v.abs()));
        // Batched products round differently (<= 1e-5 without the guard, tests/batch.rs); the
        // guard's clear-or-not decisions can carry that a little further.
        println!(
            "crowd session {i}: {:.2e} relative to stepping it alone",
            worst / scale
        );
        assert!(worst <= 1e-4 * scale, "session {i}: {worst}");
    }
}

#[test]
fn bad_settings_are_refused() {
    let model = demo();
    let mut s = session(&model, "mirror", None);
    for bad in [
        PenetrationGuard {
            d_safe: -0.1,
            ..Default::default()
        },
        PenetrationGuard {
            max_speed: 0.0,
            ..Default::default()
        },
        PenetrationGuard {
            max_speed: f64::NAN,
            ..Default::default()
        },
    ] {
        assert!(matches!(
            s.set_penetration_guard(Some(bad)),
            Err(Error::InvalidOption(_))
        ));
    }
}

/// Mean size of the root's second difference on the floor (metres per frame²).
fn root_jitter(frames: &Array2<f32>) -> f64 {
    let r: Vec<[f64; 2]> = frames
        .outer_iter()
        .map(|f| [f64::from(f[0]), f64::from(f[2])])
        .collect();
    let n = r.len() - 2;
    (0..n)
        .map(|t| {
            let a = [0, 1].map(|k| r[t + 2][k] - 2.0 * r[t + 1][k] + r[t][k]);
            (a[0] * a[0] + a[1] * a[1]).sqrt()
        })
        .sum::<f64>()
        / n as f64
}

#[test]
fn root_smoothing_calms_the_root_moves_the_body_rigidly_and_keeps_the_guard() {
    let model = demo();
    let actor = actor();
    let smoothed = |guard: Option<PenetrationGuard>, smoothing: Option<RootSmoothing>| {
        let mut s = session(&model, "mirror", guard);
        s.set_root_smoothing(smoothing).unwrap();
        stream(&mut s, &actor)
    };
    let free = smoothed(None, None);
    let calm = smoothed(None, Some(RootSmoothing::default()));
    assert!(
        root_jitter(&calm) < 0.7 * root_jitter(&free),
        "{} vs {}",
        root_jitter(&calm),
        root_jitter(&free)
    );
    // A rigid shift on the floor: heights and every joint's offset from the root unchanged.
    for (a, b) in free.outer_iter().zip(calm.outer_iter()) {
        for j in 0..22 {
            assert_eq!(a[3 * j + 1], b[3 * j + 1]);
            for k in [0, 2] {
                let (da, db) = (a[3 * j + k] - a[k], b[3 * j + k] - b[k]);
                assert!((da - db).abs() < 1e-5);
            }
        }
    }
    // With the guard after it, the bodies stay apart as with the guard alone.
    let guard = PenetrationGuard {
        d_safe: 0.5,
        max_speed: 10.0,
    };
    let both = smoothed(Some(guard), Some(RootSmoothing::default()));
    assert_eq!(metrics(&actor, &both).frames_intersecting, 0);
    // Refused settings leave the session as it was.
    let mut s = session(&model, "mirror", None);
    let bad = RootSmoothing { time_constant: 0.0 };
    assert!(matches!(
        s.set_root_smoothing(Some(bad)),
        Err(Error::InvalidOption(_))
    ));
    assert_eq!(stream(&mut s, &actor), free);
}

/// ARFlow's online stream speaks the same frames as ARMFlow, so the session's guard works on it
/// unchanged: on the guard test's clip the small untrained model's reactor, which stands in the
/// actor a quarter of the time, is pulled out of it. Measured (docs/MOTION.md): 57 of 230 frames
/// intersecting and 1.25 m of summed depth without the guard, 30 and 0.58 m with it; the tiny
/// model's body jumps from frame to frame faster than the guard's 10 m/s can follow, so unlike
/// the trained demo's it is not kept out entirely.
#[test]
fn the_guard_keeps_an_arflow_online_stream_out_of_the_actor() {
    let model = Model::load(repo("onnx/bundles/arflow-tiny-online")).unwrap();
    let actor = actor().slice(s![..230, ..]).to_owned();
    let run = |guard: Option<PenetrationGuard>| {
        let mut session = model.session(troupe::SessionOptions::default()).unwrap();
        session.set_penetration_guard(guard).unwrap();
        stream(&mut session, &actor)
    };
    let guard = PenetrationGuard {
        d_safe: 0.5,
        max_speed: 10.0,
    };
    let (free, guarded) = (run(None), run(Some(guard)));
    let (before, after) = (metrics(&actor, &free), metrics(&actor, &guarded));
    println!(
        "arflow online: intersecting frames {} -> {}, depth sum {:.3} -> {:.3} m",
        before.frames_intersecting, after.frames_intersecting, before.depth_sum, after.depth_sum
    );
    assert!(before.frames_intersecting > 40, "{before:?}");
    assert!(
        after.frames_intersecting * 3 < before.frames_intersecting * 2,
        "{after:?}"
    );
    assert!(after.depth_sum < 0.6 * before.depth_sum, "{after:?}");
    // Off again, the stream is the free one.
    let mut off = model.session(troupe::SessionOptions::default()).unwrap();
    off.set_penetration_guard(Some(guard)).unwrap();
    off.set_penetration_guard(None).unwrap();
    assert_eq!(stream(&mut off, &actor), free);
}
