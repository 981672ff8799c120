//! Streaming behaviour of a session: KV cache against full recompute, chunking, reset,
//! determinism, bounded memory, latency.

mod common;

use common::*;
use ndarray::{s, Array2};
use troupe::{ActorLatent, Model, Reactor, ReactorOptions, Session};

fn session(options: ReactorOptions) -> Session {
    model().session(options).unwrap()
}

/// The cached context of every token equals a from-scratch causal pass over its history.
#[test]
fn kv_cached_stream_equals_full_causal_recompute() {
    let condition: Vec<f32> = (0..model().condition_dim())
        .map(|i| (i as f32 * 0.37).sin())
        .collect();
    let mut s = session(ReactorOptions {
        condition: Some(condition.clone()),
        ..default_options()
    });
    let out = s.step_detailed(actor().view()).unwrap();
    assert_eq!(out.tokens.len(), 48);
    let mut pairs = Vec::new();
    let mut worst = 0f32;
    for t in &out.tokens {
        let full = model()
            .armflow()
            .unwrap()
            .recompute_context(Some(&condition), &pairs)
            .unwrap();
        worst = worst.max(max_abs_diff(&full, &t.context));
        pairs.extend(&t.actor_latent);
        pairs.extend(&t.reactor_latent);
    }
    println!("cached vs recomputed context over 48 tokens: max-abs {worst:.2e}");
    assert!(
        worst <= 1e-5,
        "cached context differs from recompute by {worst}"
    );
}

#[test]
fn chunk_sizes_give_identical_output() {
    let actor = actor();
    let reference = run_chunked(&mut session(default_options()), &actor, 1);
    assert_eq!(reference.0.len(), 48 * 4 * model().frame_dim());
    for chunk in [3, 4, 37, actor.nrows()] {
        let got = run_chunked(&mut session(default_options()), &actor, chunk);
        assert!(
            got == reference,
            "chunks of {chunk} frames differ from frame-by-frame"
        );
    }
}

#[test]
fn frames_come_out_one_token_after_its_last_actor_frame() {
    let m = model();
    assert_eq!(m.latency_frames(), m.frames_per_token() - 1);
    let mut s = session(default_options());
    let actor = actor();
    for i in 0..20 {
        let out = s.step(actor.slice(s![i..i + 1, ..])).unwrap();
        let expect = if (i + 1) % 4 == 0 { 4 } else { 0 };
        assert_eq!(out.nrows(), expect, "after actor frame {i}");
    }
    assert_eq!(
        s.step(Array2::zeros((0, m.frame_dim())).view())
            .unwrap()
            .nrows(),
        0
    );
    assert_eq!(
        (
            s.frames_received(),
            s.frames_emitted(),
            s.tokens_generated()
        ),
        (20, 20, 5)
    );
}

#[test]
fn reset_equals_a_fresh_session() {
    let actor = actor();
    let options = ReactorOptions {
        steps: Some(2),
        cfg_scale: Some(1.5),
        ..default_options()
    };
    let fresh = run_chunked(&mut session(options.clone()), &actor, 7);
    let mut s = session(options.clone());
    run_chunked(&mut s, &actor.slice(s![..90, ..]).to_owned(), 5);
    let reactor = s.family_mut::<Reactor>().unwrap();
    reactor.queue_noise(reactor.seeded_noise(99)).unwrap(); // queued noise is dropped by reset too
    s.reset();
    assert_eq!(
        (s.frames_received(), s.tokens_generated(), s.context_len()),
        (0, 0, 0)
    );
    assert!(run_chunked(&mut s, &actor, 7) == fresh);

    // Settings changed before a reset persist, and the result equals a fresh session with them.
    let mut s = session(default_options());
    run_chunked(&mut s, &actor, 11);
    s.set_seed(3);
    s.set_steps(3).unwrap();
    s.reset();
    let want = run_chunked(
        &mut session(ReactorOptions {
            seed: 3,
            steps: Some(3),
            ..default_options()
        }),
        &actor,
        11,
    );
    assert!(run_chunked(&mut s, &actor, 11) == want);
}

#[test]
fn same_seed_is_bit_identical_across_runs_and_threads() {
    let actor = actor();
    let reference = run_chunked(&mut session(default_options()), &actor, 4);
    assert!(run_chunked(&mut session(default_options()), &actor, 4) == reference);
    let shared: Model = model().clone();
    let handles: Vec<_> = (0..4)
        .map(|_| {
            let (model, actor) = (shared.clone(), actor.clone());
            std::thread::spawn(move || {
                let mut s = model.session(default_options()).unwrap();
                run_chunked(&mut s, &actor, 4)
            })
        })
        .collect();
    for h in handles {
        assert!(h.join().unwrap() == reference, "a thread's stream differs");
    }
    let other = run_chunked(
        &mut session(ReactorOptions {
            seed: 12,
            ..default_options()
        }),
        &actor,
        4,
    );
    assert!(
        other.1 != reference.1,
        "a different seed must change the reactor"
    );
}

#[test]
fn injected_noise_reproduces_a_seeded_run() {
    let actor = actor();
    let seeded = run_chunked(&mut session(default_options()), &actor, 4);
    let mut s = session(ReactorOptions {
        seed: 999,
        ..default_options()
    });
    let donor = session(default_options());
    let donor = donor.family_ref::<Reactor>().unwrap();
    let reactor = s.family_mut::<Reactor>().unwrap();
    for j in 0..48 {
        reactor.queue_noise(donor.seeded_noise(j)).unwrap();
    }
    assert!(run_chunked(&mut s, &actor, 4) == seeded);
}

#[test]
fn posterior_mean_ignores_actor_noise() {
    let run = |seed| {
        let mut s = session(ReactorOptions {
            seed,
            actor_latent: Some(ActorLatent::Mean),
            ..default_options()
        });
        s.step_detailed(actor().view()).unwrap().tokens
    };
    let (a, b) = (run(1), run(2));
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.actor_latent, y.actor_latent);
    }
    assert_ne!(a[0].reactor_latent, b[0].reactor_latent);
}

#[test]
fn changing_the_condition_changes_later_tokens_only() {
    let actor = actor();
    let half = actor.slice(s![..96, ..]).to_owned();
    let rest = actor.slice(s![96.., ..]).to_owned();
    let mut plain = session(default_options());
    let mut switched = session(default_options());
    let a1 = run_chunked(&mut plain, &half, 4);
    let b1 = run_chunked(&mut switched, &half, 4);
    assert!(a1 == b1);
    let cond = vec![0.5f32; model().condition_dim()];
    switched.set_condition(Some(&cond)).unwrap();
    assert!(run_chunked(&mut plain, &rest, 4).1 != run_chunked(&mut switched, &rest, 4).1);
}

/// A long stream stays within the context capacity and its buffers stop growing.
#[test]
fn long_stream_runs_in_bounded_context() {
    let capacity = 8;
    let mut s = session(ReactorOptions {
        context_capacity: Some(capacity),
        ..default_options()
    });
    let actor = actor();
    let mut emitted = 0;
    let mut held = Vec::new();
    for lap in 0..5 {
        for chunk in actor.axis_chunks_iter(ndarray::Axis(0), 16) {
            let out = s.step(chunk).unwrap();
            assert!(out.iter().all(|v| v.is_finite()));
            emitted += out.nrows();
        }
        assert!(
            s.context_len() <= capacity,
            "lap {lap}: {} entries",
            s.context_len()
        );
        held.push(s.memory_bytes());
    }
    // Memory stops growing once the cache is full: laps 2.. hold no more than lap 1.
    assert!(held[2..].iter().all(|&b| b <= held[1]), "{held:?}");
    let c = &model().armflow().unwrap().spec().context;
    let kv = capacity * 2 * c.layers * c.heads * c.head_dim * 4;
    assert!(
        held[4] >= kv && held[4] < kv + 1_000_000,
        "{held:?} vs cache {kv}"
    );
    assert_eq!(s.context_len(), capacity);
    assert_eq!(emitted as u64, s.frames_emitted());
    assert_eq!(s.frames_received(), 5 * actor.nrows() as u64);
}

#[test]
fn handles_are_send_and_sync_where_documented() {
    fn send_sync<T: Send + Sync>() {}
    fn send<T: Send>() {}
    send_sync::<Model>();
    send::<Reactor>();
    send::<troupe::Session>();
    send_sync::<troupe::Armflow>();
}

#[test]
fn queries_report_the_bundle() {
    let m = model();
    assert_eq!(m.frame_dim(), 262);
    assert_eq!(m.fps(), 30);
    assert_eq!(m.frames_per_token(), 4);
    assert_eq!(m.latent_dim(), 16);
    assert_eq!(m.condition_dim(), 32);
    assert_eq!(m.manifest().motion.layout, "interhuman262");
}

#[test]
fn meanflow_grid_runs_from_noise_to_data() {
    assert_eq!(troupe::meanflow_grid(1), vec![1.0, 0.0]);
    assert_eq!(troupe::meanflow_grid(4), vec![1.0, 0.75, 0.5, 0.25, 0.0]);
    // torch.linspace(1, 0, 4) in f32, as the official code computes the grid: one ulp below
    // the exact fraction 2/3 rounded once.
    assert_eq!(troupe::meanflow_grid(3)[1].to_bits(), 0x3f2aaaaa);
}

/// The bundle's per-token VAE steps (explicit convolution state, O(1) per token) give the same
/// stream as the VAE windows, and keep only the unfinished token's frames.
#[test]
fn vae_steps_equal_vae_windows() {
    let model = model();
    assert!(model.armflow().unwrap().has_vae_steps());
    let run = |vae_windows| {
        let mut s = session(ReactorOptions {
            vae_windows,
            cfg_scale: Some(2.0),
            ..default_options()
        });
        assert_eq!(
            s.family_ref::<Reactor>().unwrap().uses_vae_steps(),
            !vae_windows
        );
        run_chunked(&mut s, &actor(), 5)
    };
    let (frames_steps, tokens_steps) = run(false);
    let (frames_windows, tokens_windows) = run(true);
    let latents = |t: &[troupe::TokenTrace]| -> Vec<f32> {
        t.iter()
            .flat_map(|t| t.actor_latent.iter().chain(&t.reactor_latent).copied())
            .collect()
    };
    let d_frames = max_abs_diff(&frames_steps, &frames_windows);
    let d_latents = max_abs_diff(&latents(&tokens_steps), &latents(&tokens_windows));
    println!("VAE steps vs windows over 48 tokens: latents {d_latents:.2e}, frames {d_frames:.2e}");
    // Each output of a causal convolution reads the same inputs either way, so the two paths
    // usually agree bit for bit; the tolerance allows a runtime to reorder the sums.
    assert!(
        d_latents <= 1e-5 && d_frames <= 1e-4,
        "{d_latents} {d_frames}"
    );
}

/// The window VAE of a bundle with per-token steps is optimised on its first call
/// (`src/shared/graph.rs`): threads racing to that first call all get the same stream, the one a
/// session gets once the graphs are ready.
#[test]
fn window_graphs_optimised_on_first_use_serve_racing_threads() {
    let fresh = Model::load(bundle_dir()).unwrap();
    let run = |model: &Model| {
        let mut s = model
            .session(ReactorOptions {
                vae_windows: true,
                ..default_options()
            })
            .unwrap();
        run_chunked(&mut s, &actor(), 8).0
    };
    let racing: Vec<Vec<f32>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..4).map(|_| scope.spawn(|| run(&fresh))).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let after = run(&fresh);
    assert!(racing.iter().all(|r| *r == after));
}

/// A session reaches its reactor's own settings through `family_ref`/`family_mut`, refuses
/// another family's stream type as unsupported, and is not stepped together with a session of
/// another model.
#[test]
fn a_session_reaches_its_reactor_and_no_other_stream() {
    let m = model();
    let mut s = m.session(default_options()).unwrap();
    assert_eq!(s.family(), "armflow");
    assert!(s.family_ref::<Reactor>().unwrap().uses_vae_steps());
    assert_eq!(s.family_ref::<Reactor>().unwrap().recentring(), None);
    let e = s.family_mut::<troupe::LivePartner>().unwrap_err();
    assert!(matches!(e, troupe::Error::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("`armflow` model"), "{e}");

    let mut other = Model::load(bundle_dir())
        .unwrap()
        .session(default_options())
        .unwrap();
    let mut mixed = [&mut s, &mut other];
    let e = troupe::step_sessions(&mut mixed, &[&[][..], &[][..]]).unwrap_err();
    assert!(e.to_string().contains("another model"), "{e}");
}

/// `TRACT_CPU_ISA` chooses troupe's kernels (the attention, the products with float16 weights)
/// and tract's matrix kernels together: on an AVX-512 machine the AVX2 and portable builds run
/// too (the way a benchmark shows how another machine's kernels do), and every build streams the
/// same motion up to float rounding, with float32 weights and with float16 ones.
#[test]
fn every_kernel_build_streams_the_same_motion() {
    for bundle in ["onnx/bundles/armflow-tiny", "onnx/bundles/armflow-demo-f16"] {
        every_kernel_build_streams_the_same_motion_on(bundle);
    }
}

fn every_kernel_build_streams_the_same_motion_on(bundle: &str) {
    let builds: [(&str, &str); 3] = [
        ("", ""),
        (
            "-avx512f,-avx512vnni,-avx512fp16,-avxvnni",
            "attention avx2+fma; float16 products avx2+fma",
        ),
        (
            "-avx512f,-avx512vnni,-avx512fp16,-avxvnni,-avx2,-fma,-avx,-f16c",
            "attention portable; float16 products portable",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    let mut streams = Vec::new();
    for (i, (isa, expected)) in builds.iter().enumerate() {
        let out = dir.path().join(format!("reactor{i}.npy"));
        let run = common::run_ok(
            std::process::Command::new(common::example("stream"))
                .current_dir(env!("CARGO_MANIFEST_DIR"))
                .env("TRACT_CPU_ISA", isa)
                .args(["--bundle", bundle, "--synthetic"])
                .args(["--frames", "160", "--no-pictures", "--out"])
                .arg(&out),
        );
        let text = common::output_text(&run);
        let kernels = text.lines().find(|l| l.starts_with("kernels: ")).unwrap();
        println!("{bundle}, TRACT_CPU_ISA={isa:?}: {kernels}");
        // A CPU without AVX2 runs the portable build whatever is asked.
        let has_avx2 = cfg!(target_arch = "x86_64") && kernels.contains(",avx2");
        if !expected.is_empty() && (has_avx2 || expected.ends_with("portable")) {
            assert!(kernels.contains(expected), "{kernels}");
        }
        streams.push(ndarray_npy::read_npy::<_, Array2<f32>>(&out).unwrap());
    }
    let scale = streams[0].iter().fold(0f32, |m, v| m.max(v.abs()));
    for (i, other) in streams.iter().enumerate().skip(1) {
        let d = max_abs_diff(streams[0].as_slice().unwrap(), other.as_slice().unwrap());
        println!("{bundle}, build {i} against the machine's own: {d:.2e} (scale {scale:.2})");
        assert!(d <= 1e-4 * scale, "build {i} differs by {d}");
    }
}
