//! MAGNet's live partner as a streaming [`troupe::Session`] against the reference stream
//! (`onnx/troupe_onnx/magnet/live.py`): the golden clip's person 0 is the user, person 1's first
//! frames the partner's opening; the partner's tokens within 1e-5 of the reference's largest
//! value, its frames within 1e-4, both emission modes. Then what a stream promises: the output
//! does not depend on how the user's frames are cut, a crowd stepped together equals each
//! stepped alone, reset returns to the start, bad input changes nothing.

mod common;

use std::path::PathBuf;

use ndarray::{s, Array2, Array3};
use ndarray_npy::read_npy;
use troupe::{step_sessions, Error, LivePartner, Model, PartnerOptions, Session, SessionOptions};

const FRAME: usize = 145;

fn bundle(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("onnx/bundles")
        .join(name)
}

struct Golden {
    model: Model,
    /// `[128, 2, 145]`.
    frames: Array3<f32>,
    cases: serde_json::Value,
}

fn golden() -> Golden {
    let dir = bundle("magnet-tiny");
    let cases = std::fs::read_to_string(dir.join("golden/cases.json")).unwrap();
    Golden {
        model: Model::load(&dir).unwrap(),
        frames: read_npy(dir.join("golden/frames.npy")).unwrap(),
        cases: serde_json::from_str(&cases).unwrap(),
    }
}

impl Golden {
    fn user(&self) -> Vec<f32> {
        self.frames
            .slice(s![.., 0, ..])
            .as_standard_layout()
            .iter()
            .copied()
            .collect()
    }

    fn options(&self, case: &str) -> PartnerOptions {
        let spec = &self.cases[case];
        let sampling = &spec["sampling"];
        let context = sampling["context_len"].as_u64().unwrap() as usize;
        PartnerOptions {
            seed: sampling["seed"].as_u64().unwrap(),
            live_config: Some(sampling.to_string()),
            early_emission: spec["early"].as_bool().unwrap(),
            opening: Some(
                self.frames
                    .slice(s![..context, 1, ..])
                    .as_standard_layout()
                    .iter()
                    .copied()
                    .collect(),
            ),
            ..Default::default()
        }
    }

    fn session(&self, case: &str) -> Session {
        self.model.session(self.options(case)).unwrap()
    }
}

fn relative_error(got: &[f32], want: &[f32]) -> f32 {
    let scale = want.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-6);
    common::max_abs_diff(got, want) / scale
}

/// Steps `session` through `user` in chunks of `n` frames; the frames and tokens out.
fn stream(session: &mut Session, user: &[f32], n: usize) -> (Vec<f32>, Vec<f32>) {
    let (mut frames, mut tokens) = (Vec::new(), Vec::new());
    for chunk in user.chunks(n * FRAME) {
        let expected = session.frames_ready_after(chunk.len() / FRAME);
        let out = session.step_flat(chunk).unwrap();
        assert_eq!(out.frames.nrows(), expected, "frames_ready_after is exact");
        frames.extend(out.frames.iter());
        for t in &out.tokens {
            assert_eq!(t.index as usize, tokens.len() / t.reactor_latent.len());
            tokens.extend(&t.reactor_latent);
        }
    }
    (frames, tokens)
}

#[test]
fn the_stream_matches_the_reference_in_both_emission_modes() {
    let g = golden();
    let dir = bundle("magnet-tiny").join("golden");
    for case in ["live_stream", "live_stream_early"] {
        let mut session = g.session(case);
        assert_eq!(session.family(), "magnet");
        let (frames, tokens) = stream(&mut session, &g.user(), 20);
        let want_frames: Array2<f32> = read_npy(dir.join(format!("{case}_frames.npy"))).unwrap();
        let want_tokens: Array2<f32> = read_npy(dir.join(format!("{case}_tokens.npy"))).unwrap();
        assert_eq!(frames.len(), want_frames.len(), "{case}: frames");
        assert_eq!(tokens.len(), want_tokens.len(), "{case}: tokens");
        let t = relative_error(&tokens, want_tokens.as_slice().unwrap());
        let f = relative_error(&frames, want_frames.as_slice().unwrap());
        println!(
            "{case}: {} frames; tokens {:.2e} max-abs ({t:.2e} relative), frames {:.2e} max-abs \
             ({f:.2e} relative)",
            frames.len() / FRAME,
            common::max_abs_diff(&tokens, want_tokens.as_slice().unwrap()),
            common::max_abs_diff(&frames, want_frames.as_slice().unwrap()),
        );
        assert!(t <= 1e-5, "{case}: tokens differ by {t:.2e}");
        assert!(f <= 1e-4, "{case}: frames differ by {f:.2e}");
        assert_eq!(session.frames_emitted() as usize, frames.len() / FRAME);
        assert_eq!(session.frames_received(), 128);
    }
}

#[test]
fn the_output_does_not_depend_on_how_the_frames_are_cut() {
    let g = golden();
    let whole = stream(&mut g.session("live_stream"), &g.user(), 128);
    let one_by_one = stream(&mut g.session("live_stream"), &g.user(), 1);
    assert_eq!(whole, one_by_one);
}

#[test]
fn latency_and_readiness_follow_the_window() {
    let g = golden();
    let late = g.session("live_stream");
    let early = g.session("live_stream_early");
    // Tm = 16 tokens, Tc = 8: the first chunk needs 64 user frames.
    assert_eq!(late.latency_frames(), 63);
    assert_eq!(early.latency_frames(), 31);
    assert_eq!(late.frames_ready_after(63), 0);
    assert_eq!(late.frames_ready_after(64), 32);
    assert_eq!(early.frames_ready_after(64), 64);
    assert_eq!(late.frames_ready_after(128), 96);
    assert_eq!(early.frames_ready_after(128), 128);
    // The model's bound for a caller's buffer holds in the worst case: one frame completing a
    // chunk that sends a whole window.
    let mut early = early;
    early.step_flat(&g.user()[..63 * FRAME]).unwrap();
    let out = early.step_flat(&g.user()[63 * FRAME..64 * FRAME]).unwrap();
    assert_eq!(out.frames.nrows(), 64);
    assert!(out.frames.nrows() <= g.model.max_output_frames(1));
    assert_eq!(g.model.latency_frames(), 63);
    assert_eq!(g.model.frames_per_token(), 4);
}

#[test]
fn a_crowd_stepped_together_equals_each_stepped_alone() {
    let g = golden();
    let user = g.user();
    let mut alone = Vec::new();
    let seeds = [5u64, 9, 11];
    let offsets = [0usize, 24, 0];
    for (&seed, &offset) in seeds.iter().zip(&offsets) {
        let mut s = g.session("live_stream");
        s.set_seed(seed);
        s.step_flat(&user[..offset * FRAME]).unwrap();
        alone.push(stream(&mut s, &user[offset * FRAME..], 128));
    }
    let mut crowd: Vec<Session> = seeds
        .iter()
        .map(|&seed| {
            let mut s = g.session("live_stream");
            s.set_seed(seed);
            s
        })
        .collect();
    for (s, &offset) in crowd.iter_mut().zip(&offsets) {
        s.step_flat(&user[..offset * FRAME]).unwrap();
    }
    let mut refs: Vec<&mut Session> = crowd.iter_mut().collect();
    let chunks: Vec<&[f32]> = offsets.iter().map(|&o| &user[o * FRAME..]).collect();
    let together = step_sessions(&mut refs, &chunks).unwrap();
    for (i, (out, want)) in together.iter().zip(&alone).enumerate() {
        let got: Vec<f32> = out.frames.iter().copied().collect();
        let tokens: Vec<f32> = out
            .tokens
            .iter()
            .flat_map(|t| t.reactor_latent.clone())
            .collect();
        assert_eq!(got.len(), want.0.len(), "session {i}");
        let (t, f) = (
            relative_error(&tokens, &want.1),
            relative_error(&got, &want.0),
        );
        println!("crowd session {i}: tokens {t:.2e}, frames {f:.2e} relative to stepping it alone");
        // Batched products round differently; the frames' Gram-Schmidt magnifies it (as in the
        // reference parity), so frames are held to the parity bound.
        assert!(t <= 1e-5, "session {i}: tokens {t:.2e}");
        assert!(f <= 1e-4, "session {i}: frames {f:.2e}");
    }
}

#[test]
fn reset_returns_to_the_start_and_the_seed_matters() {
    let g = golden();
    let user = g.user();
    let mut s = g.session("live_stream");
    let first = stream(&mut s, &user, 128);
    s.reset();
    assert_eq!(s.frames_received(), 0);
    assert_eq!(stream(&mut s, &user, 128), first);
    s.reset();
    s.set_seed(1234);
    assert_ne!(stream(&mut s, &user, 128).0, first.0);
}

fn assert_invalid<T: std::fmt::Debug>(r: troupe::Result<T>, needle: &str) {
    match r {
        Err(Error::InvalidInput(m) | Error::InvalidOption(m) | Error::Unsupported(m)) => {
            assert!(m.contains(needle), "`{m}` should mention `{needle}`")
        }
        other => panic!("expected an error about {needle}, got {other:?}"),
    }
}

#[test]
fn bad_input_is_refused_and_changes_nothing() {
    let g = golden();
    let user = g.user();
    // No opening frames: the first user frame is refused, the stream stays empty.
    let mut bare = g
        .model
        .session(SessionOptions {
            seed: 5,
            ..Default::default()
        })
        .unwrap();
    assert_invalid(bare.step_flat(&user[..FRAME]), "opening frames");
    assert_eq!(bare.frames_received(), 0);
    // Opening frames of the wrong length, or not finite.
    assert_invalid(
        partner(&mut bare).set_partner_opening(&user[..FRAME]),
        "opening frames hold",
    );
    let mut nan = user[..32 * FRAME].to_vec();
    nan[7] = f32::NAN;
    assert!(partner(&mut bare).set_partner_opening(&nan).is_err());
    // A running stream: bad frames leave it where it was.
    let mut s = g.session("live_stream");
    s.step_flat(&user[..60 * FRAME]).unwrap();
    let mut bad = user[60 * FRAME..64 * FRAME].to_vec();
    bad[3] = f32::INFINITY;
    assert!(s.step_flat(&bad).is_err());
    assert_invalid(s.step_flat(&user[..FRAME + 1]), "whole number");
    assert_invalid(
        partner(&mut s).set_partner_opening(&user[..32 * FRAME]),
        "before the first step",
    );
    assert_invalid(
        partner(&mut s).set_early_emission(true),
        "before the first step",
    );
    assert_eq!(s.frames_received(), 60);
    let rest = stream(&mut s, &user[60 * FRAME..], 128);
    let mut fresh = g.session("live_stream");
    let all = stream(&mut fresh, &user, 128);
    assert_eq!(rest, all, "a refused step changed the stream");
    // What only ARMFlow's reactors have (conditions, prompts, CFG, noise, joints).
    assert_invalid(s.family_mut::<troupe::Reactor>(), "`magnet` model");
    assert_invalid(
        g.model.session(troupe::ReactorOptions::default()),
        "needs an `armflow` bundle",
    );
    // Options the stream cannot honour, and configurations it cannot run.
    let refuse = |options: PartnerOptions, needle: &str| {
        assert_invalid(g.model.session(options), needle);
    };
    refuse(
        PartnerOptions {
            context_capacity: Some(16),
            ..Default::default()
        },
        "not fewer than the window",
    );
    refuse(
        PartnerOptions {
            live_config: Some("dd100".into()),
            ..Default::default()
        },
        "motion_control_live",
    );
    refuse(
        PartnerOptions {
            live_config: Some("no such".into()),
            ..Default::default()
        },
        "no sampling configuration",
    );
    // A three-person model has no live partner stream.
    let trio = Model::load(bundle("magnet-tiny-trio")).unwrap();
    assert_invalid(trio.session(SessionOptions::default()), "two-person");
}

#[test]
fn lower_latency_settings_run_and_stay_close_to_the_released_ones() {
    // Fewer steps and early emission on the same input: the partner's frames move, by an amount
    // the benchmark reports at released size; here, that they run and stay finite.
    let g = golden();
    let user = g.user();
    for (steps, early, context) in [(2, false, 8), (4, true, 8), (4, false, 12)] {
        let mut options = g.options("live_stream");
        options.steps = Some(steps);
        options.early_emission = early;
        options.context_capacity = Some(context);
        options.opening = Some(
            g.frames
                .slice(s![..context * 4, 1, ..])
                .as_standard_layout()
                .iter()
                .copied()
                .collect(),
        );
        let mut s = g.model.session(options).unwrap();
        let (frames, _) = stream(&mut s, &user, 128);
        assert!(!frames.is_empty() && frames.iter().all(|v| v.is_finite()));
        let stride = 16 - context;
        let want = if early { 4 * stride } else { 4 * 16 } - 1;
        assert_eq!(
            s.latency_frames(),
            want,
            "steps {steps} early {early} Tc {context}"
        );
    }
}

/// The live partner behind a session, for its own settings.
fn partner(session: &mut Session) -> &mut LivePartner {
    session.family_mut::<LivePartner>().unwrap()
}

/// A live partner replays another stream's draws from queued normals: seeded 1234, given every
/// normal seed 5 draws (each draw's size read from the refusal of a queue one normal short of
/// it), it streams exactly as the stream seeded 5. A draw the queue cannot fill fails with the
/// stream as it was.
#[test]
fn queued_normals_replay_another_streams_draws() {
    let g = golden();
    let user = g.user();
    let seed = g.options("live_stream").seed;
    let want = stream(&mut g.session("live_stream"), &user, 128);
    let mut queue: Vec<f32> = Vec::new();
    for draw in 0u64.. {
        let mut s = g.session("live_stream");
        s.set_seed(1234);
        s.queue_normals(&[queue.as_slice(), &[0.0]].concat())
            .unwrap();
        let Err(e) = s.step_flat(&user) else {
            break;
        };
        assert_eq!(s.frames_received(), 0, "a failed step changes nothing");
        queue.extend(common::magnet_draw_refused(&e, draw, seed));
    }
    assert!(!queue.is_empty());
    let mut replay = g.session("live_stream");
    replay.set_seed(1234);
    replay.queue_normals(&queue).unwrap();
    assert_eq!(stream(&mut replay, &user, 128), want);
}
