//! Snapshots of streams (`Session::snapshot`, `Model::restore`): a stream saved at any token
//! and restored on another load of the model continues bit for bit, alone and batched, with
//! every setting and every piece of state it carries; hostile snapshots are refused by name.

mod common;

use std::path::Path;

use ndarray::{s, Array2, Array3, Axis};
use ndarray_npy::read_npy;
use troupe::motion::{FootLockOptions, JointsFormat, UpAxis};
use troupe::{
    step_sessions, ArflowOptions, Error, Model, PartnerOptions, PenetrationGuard, Reactor,
    ReactorOptions, Recentring, RootSmoothing, Session, TokenNoise,
};

fn load(name: &str) -> Model {
    Model::load(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("onnx/bundles")
            .join(name),
    )
    .unwrap()
}

/// Everything a reactor can carry: a small ring (it wraps), CFG, a condition, queued noise (and,
/// through [`busy`], the session's guard and smoothing). `windows`: the VAE over windows rather
/// than per-token steps.
fn busy_options(model: &Model, windows: bool) -> ReactorOptions {
    ReactorOptions {
        seed: 5,
        steps: Some(2),
        cfg_scale: Some(1.5),
        condition: Some(
            (0..model.condition_dim())
                .map(|i| (i as f32 * 0.7).cos())
                .collect(),
        ),
        context_capacity: Some(5),
        vae_windows: windows,
        ..ReactorOptions::default()
    }
}

/// `options`' session with the penetration guard and the root smoothing on (all but the
/// plain default options'), so snapshots carry the session's motion stages too.
fn busy(model: &Model, options: &ReactorOptions) -> Session {
    let mut session = model.session(options.clone()).unwrap();
    if options.condition.is_some() {
        session
            .set_penetration_guard(Some(PenetrationGuard::default()))
            .unwrap();
        session
            .set_root_smoothing(Some(RootSmoothing::default()))
            .unwrap();
    }
    session
}

fn bits(frames: &Array2<f32>) -> Vec<u32> {
    frames.iter().map(|v| v.to_bits()).collect()
}

/// Feeds `actor` in chunks of `sizes` (cycled), returning each step's frames as bits.
fn run(session: &mut Session, actor: &Array2<f32>, from: usize, sizes: &[usize]) -> Vec<u32> {
    let mut out = Vec::new();
    let mut at = from;
    for &n in sizes.iter().cycle() {
        if at >= actor.nrows() {
            break;
        }
        let end = (at + n).min(actor.nrows());
        out.extend(bits(&session.step(actor.slice(s![at..end, ..])).unwrap()));
        at = end;
    }
    out
}

/// Streams `frames` whole (chunks of `sizes`, cycled), then again cut at every frame of `cuts`:
/// saved there, restored on `other` (a second load of the model), the saved session dropped,
/// and continued. The frames out must be the uninterrupted stream's, bit for bit, and the
/// restored session must save to the same bytes.
fn check_cuts(open: impl Fn() -> Session, other: &Model, frames: &Array2<f32>, cuts: &[usize]) {
    let sizes = [3, 1, 4, 9];
    let whole = run(&mut open(), frames, 0, &sizes);
    assert!(!whole.is_empty());
    for &cut in cuts {
        let mut first = open();
        let head = frames.slice(s![..cut, ..]).to_owned();
        let mut got = run(&mut first, &head, 0, &sizes);
        let snapshot = first.snapshot().unwrap();
        drop(first);
        let mut second = other.restore(&snapshot).unwrap();
        assert_eq!(second.frames_received(), cut as u64);
        assert_eq!(second.snapshot().unwrap(), snapshot, "cut at frame {cut}");
        got.extend(run(&mut second, frames, cut, &[5, 2]));
        assert!(
            got == whole,
            "cut at frame {cut}: the continued stream differs"
        );
    }
}

/// A crowd of three streams (`open(seed)`) stepped together to frame `split`, saved, restored on
/// `other`, and stepped together to the end: the same frames as the crowd never stopped.
/// Returns a snapshot of the first stream, for further checks.
fn check_crowd(
    open: impl Fn(u64) -> Session,
    other: &Model,
    frames: &Array2<f32>,
    split: usize,
) -> Vec<u8> {
    let step_all = |crowd: &mut Vec<Session>, a: usize, b: usize| -> Vec<Vec<u32>> {
        let chunk: Vec<f32> = frames.slice(s![a..b, ..]).iter().copied().collect();
        let chunks = vec![chunk.as_slice(); crowd.len()];
        let mut refs: Vec<&mut Session> = crowd.iter_mut().collect();
        step_sessions(&mut refs, &chunks)
            .unwrap()
            .iter()
            .map(|o| bits(&o.frames))
            .collect()
    };
    let mut crowd: Vec<Session> = (0..3).map(open).collect();
    step_all(&mut crowd, 0, split);
    let mut restored: Vec<Session> = crowd
        .iter()
        .map(|s| other.restore(&s.snapshot().unwrap()).unwrap())
        .collect();
    let n = frames.nrows();
    assert_eq!(
        step_all(&mut restored, split, n),
        step_all(&mut crowd, split, n)
    );
    crowd[0].snapshot().unwrap()
}

/// A reactor with `options` and two tokens of queued noise (the rest seeded: the queue is
/// part of the state).
fn reactor(model: &Model, options: &ReactorOptions) -> Session {
    let mut session = busy(model, options);
    let s = session.family_mut::<Reactor>().unwrap();
    for k in 0..2 {
        let v = |o: f32| {
            (0..model.latent_dim())
                .map(|i| ((i + k) as f32 * o).sin())
                .collect()
        };
        s.queue_noise(TokenNoise {
            actor: v(0.3),
            reactor: v(0.9),
        })
        .unwrap();
    }
    session
}

#[test]
fn a_stream_restored_at_any_token_continues_bit_for_bit() {
    let (model, other) = (common::model(), load("armflow-tiny"));
    assert_eq!(model.identity(), other.identity());
    let cuts = [0, 1, 3, 4, 5, 8, 13, 20, 21, 47, 64, 101, 160, 191];
    let actor = common::actor();
    for options in [
        busy_options(model, false),
        busy_options(model, true),
        common::default_options(),
    ] {
        check_cuts(|| reactor(model, &options), &other, &actor, &cuts);
    }
}

#[test]
fn the_demo_model_restores_bit_for_bit() {
    // Its own graphs (prompts-free, with contact labels) and a larger cache.
    let (model, other) = (load("armflow-demo"), load("armflow-demo"));
    let options = busy_options(&model, false);
    let cuts = [0, 6, 33, 100, 190];
    check_cuts(
        || reactor(&model, &options),
        &other,
        &common::actor(),
        &cuts,
    );
}

#[test]
fn restored_sessions_step_together_as_the_uninterrupted_ones() {
    let model = common::model();
    let other = load("armflow-tiny");
    let actor = common::actor();
    let options = [
        busy_options(model, false),
        busy_options(model, true),
        common::default_options(),
    ];
    let open = |m: &Model| -> Vec<Session> { options.iter().map(|o| busy(m, o)).collect() };
    let step_all = |sessions: &mut Vec<Session>, from: usize, to: usize| -> Vec<Vec<u32>> {
        // Session i gets a chunk shifted by i, so their histories differ.
        let chunks: Vec<Vec<f32>> = (0..sessions.len())
            .map(|i| {
                let (a, b) = ((from + i).min(to), to);
                actor.slice(s![a..b, ..]).iter().copied().collect()
            })
            .collect();
        let refs: Vec<&[f32]> = chunks.iter().map(Vec::as_slice).collect();
        let mut views: Vec<&mut Session> = sessions.iter_mut().collect();
        step_sessions(&mut views, &refs)
            .unwrap()
            .iter()
            .map(|o| bits(&o.frames))
            .collect()
    };
    let steps = [(0, 30), (30, 31), (31, 77), (77, 120), (120, 192)];
    let mut whole = open(model);
    let expected: Vec<_> = steps
        .iter()
        .map(|&(a, b)| step_all(&mut whole, a, b))
        .collect();
    for cut in 1..steps.len() {
        let mut sessions = open(model);
        for &(a, b) in &steps[..cut] {
            step_all(&mut sessions, a, b);
        }
        let mut restored: Vec<Session> = sessions
            .iter()
            .map(|s| other.restore(&s.snapshot().unwrap()).unwrap())
            .collect();
        for (k, &(a, b)) in steps.iter().enumerate().skip(cut) {
            assert_eq!(
                step_all(&mut restored, a, b),
                expected[k],
                "cut after step {cut}"
            );
        }
    }
}

#[test]
fn a_joint_stream_with_its_foot_lock_and_recentring_restores_bit_for_bit() {
    let model = common::model();
    let clip: Array3<f32> = read_npy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mocap/cmu-playground-120fps.npy"),
    )
    .unwrap();
    // The second half: the actor jumps forward, so the stream recentres (at 0.1 m) again and again.
    let clip = clip.slice(s![480.., .., ..]).to_owned();
    let n = clip.shape()[0];
    let open = |recentring: bool| {
        let mut r = busy(model, &busy_options(model, false));
        r.set_joints_format(JointsFormat {
            up: UpAxis::Z,
            fps: 120.0,
            ..Default::default()
        })
        .unwrap();
        r.set_foot_lock(Some(FootLockOptions::default())).unwrap();
        r.family_mut::<Reactor>()
            .unwrap()
            .set_recentring(recentring.then_some(Recentring { distance: 0.1 }))
            .unwrap();
        r
    };
    let poses = |r: &mut Session, from: usize, to: usize| -> Vec<u32> {
        clip.slice(s![from..to, .., ..])
            .axis_chunks_iter(Axis(0), 7)
            .flat_map(|c| r.step_joints(c).unwrap())
            .flat_map(|p| {
                let mut v: Vec<u32> = p.positions.iter().flatten().map(|x| x.to_bits()).collect();
                v.extend(p.rotations.iter().flatten().map(|x| x.to_bits()));
                v
            })
            .collect()
    };
    let whole = poses(&mut open(true), 0, n);
    assert!(
        whole != poses(&mut open(false), 0, n),
        "the stream recentred"
    );
    for cut in [1, 2, 50, 121, 239, 350, 479] {
        let mut first = open(true);
        let mut got = poses(&mut first, 0, cut);
        let mut restored = model.restore(&first.snapshot().unwrap()).unwrap();
        got.extend(poses(&mut restored, cut, n));
        assert!(got == whole, "cut at frame {cut}");
    }
}

/// Every count a joint stream's snapshot holds (its resampler's frames in and out, the held
/// frames, the cache's entries, ...), rewritten to values an edit would write with the checksum
/// made to agree, is refused at restore or gives a stream whose next call stays bounded. The
/// resampler's frames-in set to 2^64 - 1 once made that call allocate until the host aborted.
#[test]
fn every_count_of_a_joint_stream_snapshot_edited_is_refused_or_harmless() {
    let model = common::model();
    let clip: Array3<f32> = read_npy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mocap/cmu-playground-120fps.npy"),
    )
    .unwrap();
    let mut stream = busy(model, &busy_options(model, false));
    stream
        .set_joints_format(JointsFormat {
            up: UpAxis::Z,
            fps: 120.0,
            ..Default::default()
        })
        .unwrap();
    stream
        .set_foot_lock(Some(FootLockOptions::default()))
        .unwrap();
    stream.step_joints(clip.slice(s![..61, .., ..])).unwrap();
    let good = stream.snapshot().unwrap();
    let next = clip.slice(s![61..68, .., ..]);
    // Where the snapshot holds what reads as a small count (float data seldom does).
    let counts = (0..good.len() - 12).filter(|&p| {
        let v = u64::from_le_bytes(good[p..p + 8].try_into().unwrap());
        (1..=1 << 20).contains(&v)
    });
    let (mut edits, mut restored) = (0, 0);
    for at in counts {
        for claim in [0, 121, 240, 1 << 31, 1 << 40, u64::MAX] {
            let mut b = good.clone();
            b[at..at + 8].copy_from_slice(&claim.to_le_bytes());
            edits += 1;
            if let Ok(mut s) = model.restore(&reframed(b)) {
                restored += 1;
                if let Ok(poses) = s.step_joints(next) {
                    assert!(poses.len() <= 64, "{} poses for 7 frames", poses.len());
                }
            }
        }
    }
    assert!(
        edits > 100 && restored < edits,
        "{restored} of {edits} edits restored"
    );
}

/// Rewrites a snapshot's checksum after an edit, so the edit reaches the payload's checks.
fn reframed(mut bytes: Vec<u8>) -> Vec<u8> {
    let n = bytes.len() - 4;
    let crc = crc32fast::hash(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
    bytes
}

fn refused(model: &Model, bytes: &[u8]) -> String {
    match model.restore(bytes) {
        Err(e @ Error::InvalidInput(_)) => e.to_string(),
        Err(other) => panic!("refused with the wrong kind of error: {other}"),
        Ok(_) => panic!("a hostile snapshot was restored"),
    }
}

#[test]
fn hostile_snapshots_are_refused_with_a_clear_error() {
    let model = common::model();
    let mut session = busy(model, &busy_options(model, false));
    session.step(common::actor().slice(s![..37, ..])).unwrap();
    let good = session.snapshot().unwrap();
    assert!(model.restore(&good).is_ok());
    assert_eq!(
        crc32fast::hash(&good[..good.len() - 4]).to_le_bytes(),
        good[good.len() - 4..]
    );

    // Every truncation, and a flipped bit anywhere (sampled: every 7th byte); a recentring
    // stream's too, which has recentred (its actor's root strays up to 1.4 m from the origin:
    // it answers otherwise than the same stream without recentring).
    let sine: Vec<f32> = (0..37 * 262).map(|i| (i as f32 * 0.37).sin()).collect();
    let mut recentring = busy(
        model,
        &ReactorOptions {
            recentring: Some(Recentring::default()),
            ..busy_options(model, false)
        },
    );
    let mut plain = busy(model, &busy_options(model, false));
    assert_ne!(
        recentring.step_flat(&sine).unwrap().frames,
        plain.step_flat(&sine).unwrap().frames
    );
    let recentred = recentring.snapshot().unwrap();
    // Turned off after it recentred, the stream keeps its rebuilt cache, and still restores.
    let mut off = model.restore(&recentred).unwrap();
    off.family_mut::<Reactor>()
        .unwrap()
        .set_recentring(None)
        .unwrap();
    off.step_flat(&sine[..8 * 262]).unwrap();
    assert!(model.restore(&off.snapshot().unwrap()).is_ok());
    for good in [&good, &recentred] {
        for n in 0..good.len() {
            refused(model, &good[..n]);
        }
        for i in (0..good.len()).step_by(7) {
            let mut b = good.clone();
            b[i] ^= 0x10;
            refused(model, &b);
        }
    }
    // Another model: the same family, other weights.
    let other = load("armflow-demo");
    let e = refused(&other, &good);
    assert!(e.contains("another model"), "{e}");
    // Another family.
    let e = match load("magnet-tiny").restore(&good) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("restored onto another family"),
    };
    assert!(e.contains("`armflow` stream"), "{e}");
    // Another version of the format.
    let mut b = good.clone();
    b[8] = 4;
    let e = refused(model, &reframed(b));
    assert!(e.contains("version 4"), "{e}");
    // Checksummed lies in the payload.
    survives_lies(
        model,
        &good,
        &common::actor().slice(s![37..45, ..]).to_owned(),
    );
    // Absurd lengths: the held actor frames' count set to 2^60, then to u64::MAX.
    let count_at = actor_frames_count_at(&good);
    for claim in [1u64 << 60, u64::MAX] {
        let mut b = good.clone();
        b[count_at..count_at + 8].copy_from_slice(&claim.to_le_bytes());
        let e = refused(model, &reframed(b));
        assert!(e.contains("actor frames held"), "{e}");
    }
    // Nothing else is a snapshot.
    for junk in [
        &b""[..],
        b"TRPSNAP",
        &[0u8; 100],
        b"{\"not\": \"a snapshot\"}",
    ] {
        refused(model, junk);
    }
}

/// Each payload byte of `good` rewritten in turn (the first 400, then every 61st), the checksum
/// made to agree: each is refused or, where the byte is a free value (a float, the seed),
/// restores to a session that steps without panicking.
fn survives_lies(model: &Model, good: &[u8], frames: &Array2<f32>) {
    let family = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let payload = 8 + 4 + 4 + family + 32 + 8;
    let sampled = (payload..good.len() - 4).filter(|i| *i < payload + 400 || i % 61 == 0);
    for i in sampled {
        for v in [0x00, 0xff, good[i] ^ 0x01, 0x7f] {
            let mut b = good.to_vec();
            b[i] = v;
            if let Ok(mut s) = model.restore(&reframed(b)) {
                let _ = s.step(frames.view());
            }
        }
    }
}

/// Where the count of held actor floats lies: after the frames received (37) and the first
/// frame held (36: with VAE steps only the unfinished token's frame is kept).
fn actor_frames_count_at(snapshot: &[u8]) -> usize {
    let counts: Vec<u8> = [37u64, 36].iter().flat_map(|v| v.to_le_bytes()).collect();
    let at = snapshot
        .windows(16)
        .position(|w| w == counts)
        .expect("the stream's counts");
    assert_eq!(snapshot[at + 16..at + 24], 262u64.to_le_bytes());
    at + 16
}

/// A snapshot sealed under a key restores with that key only, and continues bit for bit; an
/// edited byte anywhere, another key, or a snapshot of the other kind is refused by name.
#[test]
fn a_sealed_snapshot_restores_with_its_key_only() {
    let model = common::model();
    let actor = common::actor();
    let options = busy_options(model, false);
    let mut session = reactor(model, &options);
    run(&mut session, &actor, 0, &[4, 4, 4]);
    let key = b"a key of thirty-two bytes, kept.";
    let sealed = session.snapshot_sealed(key).unwrap();
    assert_eq!(&sealed[44..], &session.snapshot().unwrap()[..]);
    let mut restored = model.restore_sealed(&sealed, key).unwrap();
    assert_eq!(
        run(&mut restored, &actor, 12, &[4, 4]),
        run(&mut session, &actor, 12, &[4, 4])
    );
    let refusal = |r: troupe::Result<Session>| match r {
        Err(Error::InvalidInput(m)) => m,
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("restored"),
    };
    assert!(
        refusal(model.restore_sealed(&sealed, b"another key of 32 bytes, kept..."))
            .contains("does not match this key")
    );
    for at in (0..sealed.len()).step_by(sealed.len() / 97) {
        let mut edited = sealed.clone();
        edited[at] ^= 0x10;
        assert!(model.restore_sealed(&edited, key).is_err(), "byte {at}");
    }
    assert!(refusal(model.restore(&sealed)).contains("sealed with a key"));
    let plain = session.snapshot().unwrap();
    assert!(refusal(model.restore_sealed(&plain, key)).contains("not sealed"));
    assert_eq!(troupe::seal_snapshot(&sealed[44..], key).unwrap(), sealed);
}

#[test]
fn a_family_without_streams_restores_none() {
    let armflow = common::model().session(common::default_options()).unwrap();
    let e = refused(&load("umf-tiny"), &armflow.snapshot().unwrap());
    assert!(e.contains("not a `umf` stream's"), "{e}");
}

/// An ARFlow online stream with every draw on (start noise, stochastic steps, guidance), part
/// of its draws queued: saved at many frames, restored, continued alone and in a crowd.
#[test]
fn an_arflow_online_stream_restores_bit_for_bit() {
    let (model, other) = (load("arflow-tiny-online"), load("arflow-tiny-online"));
    let actor: Array2<f32> = read_npy(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("onnx/bundles/arflow-tiny-online/golden/actor.npy"),
    )
    .unwrap();
    let open = |seed: u64| {
        let mut s = model
            .session(ArflowOptions {
                seed,
                steps: Some(3),
                eta: Some(0.3),
                sigma: Some(0.5),
                guidance: Some(1.0),
                ..ArflowOptions::default()
            })
            .unwrap();
        // Two and a half frames' draws queued: the restored stream must take the rest in order.
        let normals: Vec<f32> = (0..262 * 10).map(|i| (i as f32 * 0.11).sin()).collect();
        s.queue_normals(&normals).unwrap();
        s
    };
    let frames = actor.nrows();
    check_cuts(
        || open(1),
        &other,
        &actor,
        &[0, 1, 2, 3, 9, frames / 2, frames - 1],
    );
    let saved = check_crowd(open, &other, &actor, 5);
    survives_lies(&model, &saved, &actor.slice(s![12..14, ..]).to_owned());
    // Not onto another family, nor another family's snapshot onto it.
    let e = refused(common::model(), &saved);
    assert!(e.contains("`arflow` stream"), "{e}");
}

/// MAGNet's live partner in both emission modes, part of its draws queued: saved before its
/// first chunk, between chunks and mid-chunk, restored, continued alone and in a crowd.
#[test]
fn a_magnet_live_partner_restores_bit_for_bit() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/magnet-tiny");
    let (model, other) = (load("magnet-tiny"), load("magnet-tiny"));
    let frames: Array3<f32> = read_npy(dir.join("golden/frames.npy")).unwrap();
    let cases: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("golden/cases.json")).unwrap())
            .unwrap();
    let user = frames.slice(s![.., 0, ..]).to_owned();
    for case in ["live_stream", "live_stream_early"] {
        let spec = &cases[case];
        let sampling = &spec["sampling"];
        let context = sampling["context_len"].as_u64().unwrap() as usize;
        let open = |seed: u64| {
            let mut s = model
                .session(PartnerOptions {
                    seed,
                    live_config: Some(sampling.to_string()),
                    early_emission: spec["early"].as_bool().unwrap(),
                    opening: Some(frames.slice(s![..context, 1, ..]).iter().copied().collect()),
                    ..Default::default()
                })
                .unwrap();
            // The first chunk's draw (window x 2 people x token floats), the rest seeded.
            let normals: Vec<f32> = (0..3328).map(|i| (i as f32 * 0.13).cos()).collect();
            s.queue_normals(&normals).unwrap();
            s
        };
        let n = user.nrows();
        check_cuts(|| open(3), &other, &user, &[0, 1, 30, 64, 65, 99, n - 1]);
        let saved = check_crowd(open, &other, &user, 70);
        // Checksummed lies in its payload (the configuration's JSON among them).
        survives_lies(&model, &saved, &user.slice(s![..9, ..]).to_owned());
    }
}
