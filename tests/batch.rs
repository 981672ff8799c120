//! Many sessions stepped in one call (`step_reactors`) give what each session gives alone, and
//! a bad batch changes no session.

mod common;

use common::*;
use ndarray::s;
use troupe::{ActorLatent, Model, ReactorOptions, Session, StepOutput};

/// Sessions that differ in every setting a batch must keep apart: seed, steps, CFG (so some
/// rows come in pairs), condition, a small capacity (evicting while others do not, so histories
/// of unequal length share a batch), the posterior mean, and the VAE windows path.
fn varied_sessions() -> Vec<Session> {
    let condition: Vec<f32> = (0..model().condition_dim())
        .map(|i| (i as f32 * 0.37).sin())
        .collect();
    let options = [
        default_options(),
        ReactorOptions {
            seed: 5,
            steps: Some(2),
            cfg_scale: Some(2.5),
            ..Default::default()
        },
        ReactorOptions {
            seed: 6,
            condition: Some(condition),
            context_capacity: Some(5),
            ..Default::default()
        },
        ReactorOptions {
            seed: 7,
            steps: Some(3),
            actor_latent: Some(ActorLatent::Mean),
            ..Default::default()
        },
        ReactorOptions {
            seed: 8,
            vae_windows: true,
            cfg_scale: Some(1.5),
            ..Default::default()
        },
    ];
    options
        .into_iter()
        .map(|o| model().session(o).unwrap())
        .collect()
}

/// Chunk sizes per round and session: unequal, sometimes 0, so that sessions join and leave
/// rounds at different times and some generate several tokens in one call.
fn chunk(round: usize, session: usize) -> usize {
    [0, 1, 3, 4, 9, 13][(round * 7 + session * 5) % 6]
}

fn traces(out: &StepOutput) -> Vec<f32> {
    out.tokens
        .iter()
        .flat_map(|t| {
            t.actor_latent
                .iter()
                .chain(&t.reactor_latent)
                .chain(&t.context)
                .copied()
        })
        .collect()
}

#[test]
fn batched_step_equals_stepping_each_session_alone() {
    let actor = actor();
    let mut together = varied_sessions();
    let mut alone = varied_sessions();
    let mut fed = vec![0usize; together.len()];
    let (mut worst_frames, mut worst_latents, mut tokens) = (0f32, 0f32, 0usize);
    for round in 0.. {
        let ranges: Vec<(usize, usize)> = fed
            .iter()
            .enumerate()
            .map(|(i, &f)| (f, (f + chunk(round, i)).min(actor.nrows())))
            .collect();
        if ranges.iter().all(|&(a, _)| a == actor.nrows()) {
            break;
        }
        let chunks: Vec<Vec<f32>> = ranges
            .iter()
            .map(|&(a, b)| actor.slice(s![a..b, ..]).iter().copied().collect())
            .collect();
        let views: Vec<&[f32]> = chunks.iter().map(Vec::as_slice).collect();
        let mut refs: Vec<&mut Session> = together.iter_mut().collect();
        let batched = troupe::step_sessions(&mut refs, &views).unwrap();
        for (i, out) in batched.iter().enumerate() {
            let single = alone[i].step_flat(views[i]).unwrap();
            assert_eq!(
                out.frames.dim(),
                single.frames.dim(),
                "session {i} round {round}"
            );
            assert_eq!(out.tokens.len(), single.tokens.len());
            tokens += out.tokens.len();
            worst_frames = worst_frames.max(max_abs_diff(
                out.frames.as_slice().unwrap(),
                single.frames.as_slice().unwrap(),
            ));
            worst_latents = worst_latents.max(max_abs_diff(&traces(out), &traces(&single)));
        }
        for (i, &(_, b)) in ranges.iter().enumerate() {
            fed[i] = b;
        }
    }
    println!(
        "batched vs alone, {tokens} tokens over 5 sessions: latents and contexts {worst_latents:.2e}, frames {worst_frames:.2e}"
    );
    assert_eq!(tokens, 5 * (actor.nrows() / model().frames_per_token()));
    assert!(worst_latents <= 1e-5, "{worst_latents}");
    assert!(worst_frames <= 1e-5, "{worst_frames}");
    assert_eq!(together[2].context_len(), 5, "the small capacity evicted");
}

#[test]
fn a_bad_batch_changes_no_session() {
    let actor = actor();
    let mut sessions = varied_sessions();
    let mut twins = varied_sessions();
    let warm: Vec<f32> = actor.slice(s![..10, ..]).iter().copied().collect();
    {
        let mut refs: Vec<&mut Session> = sessions.iter_mut().collect();
        troupe::step_sessions(&mut refs, &[warm.as_slice(); 5]).unwrap();
        let mut refs: Vec<&mut Session> = twins.iter_mut().collect();
        troupe::step_sessions(&mut refs, &[warm.as_slice(); 5]).unwrap();
    }
    let good: Vec<f32> = actor.slice(s![10..14, ..]).iter().copied().collect();
    let mut nan = good.clone();
    nan[7] = f32::NAN;
    let short = &good[..good.len() - 1];
    let other_model = Model::load(bundle_dir()).unwrap();
    let mut stranger = other_model.session(default_options()).unwrap();

    let mut refs: Vec<&mut Session> = sessions.iter_mut().collect();
    let bad_chunks: [(Vec<&[f32]>, &str); 3] = [
        (vec![&good, &good, &nan, &good, &good], "session 2: "),
        (vec![&good, &good, &good, short, &good], "session 3: "),
        (vec![&good; 4], "5 sessions but 4 chunks"),
    ];
    for (chunks, expected) in bad_chunks {
        let err = troupe::step_sessions(&mut refs, &chunks)
            .unwrap_err()
            .to_string();
        assert!(err.contains(expected), "{err}");
    }
    refs.push(&mut stranger);
    let err = troupe::step_sessions(&mut refs, &[good.as_slice(); 6])
        .unwrap_err()
        .to_string();
    assert!(err.contains("session 5 runs another model"), "{err}");
    drop(refs);

    // Every session goes on exactly like its twin that saw none of the bad batches.
    let rest: Vec<f32> = actor.slice(s![10.., ..]).iter().copied().collect();
    for (a, b) in sessions.iter_mut().zip(&mut twins) {
        assert_eq!(a.frames_received(), b.frames_received());
        let (x, y) = (a.step_flat(&rest).unwrap(), b.step_flat(&rest).unwrap());
        assert_eq!(x.frames, y.frames);
    }
    assert!(troupe::step_sessions(&mut [], &[]).unwrap().is_empty());
}
