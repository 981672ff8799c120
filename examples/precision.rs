//! How far a reduced-precision bundle's stream is from its float32 original: both bundles stream
//! the same actor with the same seed, every token traced, and the largest differences are
//! reported relative to the float32 values' largest magnitude (the error table of
//! docs/PERFORMANCE.md, "Weights in int8").
//!
//! ```text
//! cargo run --release --example precision -- --reference DIR --reduced DIR [--tokens N] [--seed S]
//! ```
//! The actor is the reference bundle's golden actor (`golden/actor.npy`) when it has one, else
//! the examples' synthetic clip.

use std::error::Error;

use ndarray::Array2;
use troupe::{Model, ReactorOptions, TokenTrace};

mod common;

fn main() -> Result<(), Box<dyn Error>> {
    let (mut reference, mut reduced, mut tokens, mut seed) = (None, None, 48usize, 1u64);
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--reference" => reference = Some(value()?),
            "--reduced" => reduced = Some(value()?),
            "--tokens" => tokens = value()?.parse()?,
            "--seed" => seed = value()?.parse()?,
            _ => {
                return Err(
                    format!("unknown option {flag}; see the top of examples/precision.rs").into(),
                )
            }
        }
    }
    let (reference, reduced) = (
        reference.ok_or("--reference DIR is required")?,
        reduced.ok_or("--reduced DIR is required")?,
    );
    let (full, small) = (Model::load(&reference)?, Model::load(&reduced)?);
    let fpt = full.frames_per_token();
    let frames = tokens * fpt;
    let golden = std::path::Path::new(&reference).join("golden/actor.npy");
    let actor: Array2<f32> = match ndarray_npy::read_npy::<_, Array2<f32>>(&golden) {
        Ok(a) if a.nrows() >= frames => a.slice(ndarray::s![..frames, ..]).to_owned(),
        _ => common::synthetic_actor(frames, full.frame_dim()),
    };
    let run = |model: &Model| -> Result<(Vec<f32>, Vec<TokenTrace>), troupe::Error> {
        let mut s = model.session(ReactorOptions {
            seed,
            ..Default::default()
        })?;
        let out = s.step_detailed(actor.view())?;
        Ok((out.frames.into_raw_vec_and_offset().0, out.tokens))
    };
    let ((want_frames, want), (got_frames, got)) = (run(&full)?, run(&small)?);
    let gather = |t: &[TokenTrace], f: fn(&TokenTrace) -> &Vec<f32>| -> Vec<f32> {
        t.iter().flat_map(|t| f(t).iter().copied()).collect()
    };
    let relative = |got: &[f32], want: &[f32]| {
        let scale = want
            .iter()
            .fold(0f32, |m, v| m.max(v.abs()))
            .max(f32::MIN_POSITIVE);
        let diff = got
            .iter()
            .zip(want)
            .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
        (diff, diff / scale)
    };
    let report = |what: &str, (abs, rel): (f32, f32)| {
        println!("{what:>16}: max-abs {abs:.3e}, relative to the largest float32 value {rel:.3e}");
    };
    println!(
        "{} ({reduced}) vs {} ({reference}): {} tokens, seed {seed}",
        small.manifest().name,
        full.manifest().name,
        want.len()
    );
    report(
        "actor latents",
        relative(
            &gather(&got, |t| &t.actor_latent),
            &gather(&want, |t| &t.actor_latent),
        ),
    );
    report(
        "reactor latents",
        relative(
            &gather(&got, |t| &t.reactor_latent),
            &gather(&want, |t| &t.reactor_latent),
        ),
    );
    report(
        "first token",
        relative(&got[0].reactor_latent, &want[0].reactor_latent),
    );
    report("frames", relative(&got_frames, &want_frames));
    Ok(())
}
