//! Golden parity: the committed tiny bundle run by troupe against the PyTorch reference loop
//! (`onnx/troupe_onnx/armflow/reference.py::stream_reference`) with the same injected noise.
//! Tolerances: latents and contexts max-abs <= 1e-5, frames <= 1e-4, over 48 tokens.

mod common;

use common::*;
use troupe::{SessionOptions, TokenTrace};

const LATENT_TOL: f32 = 1e-5;
const FRAME_TOL: f32 = 1e-4;

struct Parity {
    actor: f32,
    reactor: f32,
    context: f32,
    frames: f32,
}

fn run_case(case: &str, options: SessionOptions, chunk: usize) -> Parity {
    let mut session = model().session(options).unwrap();
    queue_golden_noise(&mut session, case);
    let (frames, tokens) = run_chunked(&mut session, &actor(), chunk);
    let gather = |f: fn(&TokenTrace) -> &Vec<f32>| -> Vec<f32> {
        tokens.iter().flat_map(|t| f(t).iter().copied()).collect()
    };
    let (a, b, c) = (
        gather(|t| &t.actor_latent),
        gather(|t| &t.reactor_latent),
        gather(|t| &t.context),
    );
    let want = |k: &str| golden2(&format!("{case}_{k}")).into_raw_vec_and_offset().0;
    assert_eq!(session.tokens_generated(), 48);
    Parity {
        actor: max_abs_diff(&a, &want("actor_latents")),
        reactor: max_abs_diff(&b, &want("reactor_latents")),
        context: max_abs_diff(&c, &want("contexts")),
        frames: max_abs_diff(&frames, &want("frames")),
    }
}

fn assert_parity(case: &str, p: Parity) {
    println!(
        "{case}: max-abs actor latents {:.2e}, reactor latents {:.2e}, contexts {:.2e}, frames {:.2e}",
        p.actor, p.reactor, p.context, p.frames
    );
    assert!(
        p.actor <= LATENT_TOL,
        "{case}: actor latents off by {}",
        p.actor
    );
    assert!(
        p.reactor <= LATENT_TOL,
        "{case}: reactor latents off by {}",
        p.reactor
    );
    assert!(
        p.context <= LATENT_TOL,
        "{case}: contexts off by {}",
        p.context
    );
    assert!(p.frames <= FRAME_TOL, "{case}: frames off by {}", p.frames);
}

#[test]
fn default_case_matches_pytorch() {
    let options = SessionOptions {
        condition: Some(golden1("default_condition").to_vec()),
        ..Default::default()
    };
    assert_parity("default", run_case("default", options, 1));
}

/// Two MeanFlow steps, CFG 2.5 with the null branch, null condition, and a context capacity of
/// 16 so the sliding window evicts entries for 32 of the 48 tokens.
#[test]
fn cfg_multistep_sliding_window_matches_pytorch() {
    let options = SessionOptions {
        steps: Some(2),
        cfg_scale: Some(2.5),
        context_capacity: Some(16),
        ..Default::default()
    };
    assert_parity("cfg_steps_window", run_case("cfg_steps_window", options, 5));
}

/// The portable generator gives the same normals as the Python implementation, bit for bit.
#[test]
fn seeded_noise_matches_python_bit_for_bit() {
    let model = model();
    let session = model
        .session(SessionOptions {
            seed: 7,
            ..Default::default()
        })
        .unwrap();
    let lat = model.latent_dim();
    for stream in [0u32, 1] {
        let want = golden2(&format!("philox_seed7_stream{stream}"));
        for (row, token) in [0u64, 1, 2, 1000].iter().enumerate() {
            let mut got = vec![0f32; want.ncols()];
            troupe::noise::fill_normals(7, *token, stream, &mut got);
            assert_eq!(got, want.row(row).to_vec(), "stream {stream} token {token}");
            let noise = session.seeded_noise(*token);
            let expect = if stream == 0 {
                &noise.actor
            } else {
                &noise.reactor
            };
            assert_eq!(expect[..], got[..lat]);
        }
    }
}
