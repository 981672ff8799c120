//! ARMFlow's official clip loop, [`crate::Armflow::generate_clip`]: given the same weights and noise,
//! the same motion as the released sampler (`docs/spec/armflow.md` §7).
//!
//! Unlike a [`crate::Session`], which streams, the official sampler works on a whole clip:
//! 1. the actor clip is zero-padded to the clip length (300 frames InterHuman, 150 InterX) and
//!    encoded once, non-causally; actor tokens are the posterior sample
//!    `a = (mean + sqrt(exp(logvar)) * xi) * scale`;
//! 2. for every token `i`, the whole prefix `[<sos>, (a_j || b_j) for j < i]` is re-run through
//!    the context encoder with **no attention mask** (earlier tokens see later ones), and the
//!    context is the output at the last position;
//! 3. **one** noise token `eps` (the official `E[N-1]`) is used for every token:
//!    `b_i = eps - u(eps, r = 0, t = 1)` (more MeanFlow steps follow the session's grid); with
//!    a CFG scale `s` other than 1 (a checkpoint saved with `mf.cfg_scale`, the manifest's
//!    `sampler.cfg_scale`), `u = u_null + s * (u_cond - u_null)`, the null row with the actor
//!    token and the context zeroed, as the official sampler guides;
//! 4. all reactor tokens are decoded at once and padded to the clip length by repeating the
//!    last frame (InterX's 37 tokens decode to 148 frames).
//!
//! Cost: the prefix re-run makes token `i` cost O(i) tokens, the clip O(N²); the official code
//! pays the same.

use ndarray::{Array2, ArrayView2};

use super::meanflow::{guided, meanflow_grid};
use super::networks::Networks;
use super::spec::ClipSpec;
use crate::shared::checks::{check_input, check_output};
use crate::shared::error::{Error, Result};
use crate::shared::graph::{f32_tensor, read_f32, stack_rows};
use crate::shared::limits::{check_cfg, check_steps};
use crate::shared::noise::{fill_normals, STREAM_ACTOR_POSTERIOR, STREAM_REACTOR_NOISE};
use crate::shared::progress;

/// The random draws of one clip. Pass them to reproduce another implementation's draws
/// exactly; leave them out and troupe draws them from the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipNoise {
    /// `xi`, the standard normals of the actor posterior sample, `[clip.tokens, latent_dim]`
    /// row-major (the official first draw).
    pub actor_posterior: Vec<f32>,
    /// `eps`, the one noise token every reactor token starts from, `[latent_dim]` (the
    /// official `E[N-1]` of the second draw).
    pub reactor_noise: Vec<f32>,
}

/// Options of [`crate::Armflow::generate_clip`].
#[derive(Debug, Clone, Default)]
pub struct ClipOptions {
    /// Seed of the draws when `noise` is `None`: `xi` of token `j` is the Philox stream
    /// [`STREAM_ACTOR_POSTERIOR`] at token `j`, and `eps` the stream [`STREAM_REACTOR_NOISE`]
    /// at token `N - 1`, the draws a [`crate::Session`] with this seed makes for those tokens.
    pub seed: u64,
    /// MeanFlow steps per token; `None` takes the bundle's default (1 for the official models).
    pub steps: Option<u32>,
    /// Injected draws; `None` draws from `seed`.
    pub noise: Option<ClipNoise>,
    /// Classifier-free guidance scale; `None` takes the bundle's (`sampler.cfg_scale`, 1 for
    /// the released models), as the official sampler does.
    pub cfg_scale: Option<f32>,
}

/// What [`crate::Armflow::generate_clip`] returns.
#[derive(Debug, Clone)]
pub struct Clip {
    /// Reactor motion, `[clip.frames, frame_dim]`.
    pub frames: Array2<f32>,
    /// Actor tokens `a_i` (scaled), `[clip.tokens, latent_dim]`.
    pub actor_latents: Array2<f32>,
    /// Reactor tokens `b_i` (scaled), `[clip.tokens, latent_dim]`.
    pub reactor_latents: Array2<f32>,
    /// Context `c_i` of every token, `[clip.tokens, 2 * latent_dim]`.
    pub contexts: Array2<f32>,
}

impl Networks {
    /// The draws [`Networks::generate_clip`] makes for `seed` when none are given.
    pub(crate) fn clip_noise(&self, seed: u64) -> Result<ClipNoise> {
        let clip = self.require_clip()?;
        let lat = self.latent_dim();
        let mut actor_posterior = vec![0f32; clip.tokens * lat];
        for (j, row) in actor_posterior.chunks_exact_mut(lat).enumerate() {
            fill_normals(seed, j as u64, STREAM_ACTOR_POSTERIOR, row);
        }
        let mut reactor_noise = vec![0f32; lat];
        fill_normals(
            seed,
            clip.tokens as u64 - 1,
            STREAM_REACTOR_NOISE,
            &mut reactor_noise,
        );
        Ok(ClipNoise {
            actor_posterior,
            reactor_noise,
        })
    }

    /// Runs the official sampler on one actor clip (`[1..=clip.frames, frame_dim]`).
    pub(crate) fn generate_clip(
        &self,
        actor: ArrayView2<f32>,
        condition: Option<&[f32]>,
        options: &ClipOptions,
    ) -> Result<Clip> {
        let clip = self.require_clip()?.clone();
        let spec = &self.spec;
        let (d, lat, c) = (self.frame_dim(), self.latent_dim(), spec.context.width);
        let n = clip.tokens;
        if actor.ncols() != d || actor.nrows() == 0 || actor.nrows() > clip.frames {
            return Err(Error::InvalidInput(format!(
                "actor clip is {}x{}, expected 1..={} frames of {d} floats",
                actor.nrows(),
                actor.ncols(),
                clip.frames
            )));
        }
        let steps = options.steps.unwrap_or(spec.sampler.steps);
        check_steps("clip steps", steps)?;
        let cfg_scale = options.cfg_scale.unwrap_or(spec.sampler.cfg_scale);
        check_cfg(cfg_scale)?;
        let work = n as u64 * u64::from(steps);
        let _clock = progress::start_call("the clip", work, "tokens × steps")?;
        let mut padded = vec![0f32; clip.frames * d];
        for (dst, src) in padded.iter_mut().zip(actor.iter()) {
            *dst = *src;
        }
        check_input("actor clip", &padded[..actor.len()])?;
        let noise = match &options.noise {
            Some(noise) => {
                check_clip_noise(noise, n, lat)?;
                noise.clone()
            }
            None => self.clip_noise(options.seed)?,
        };
        let cond = self.conditioning(condition)?;
        let full = self
            .context_full
            .as_ref()
            .expect("validated: clip needs context_full");

        // 1. One encode of the padded clip; actor tokens are the posterior sample.
        let (mean, logvar) = self.encode(&padded)?;
        let scale = spec.latent.scale;
        let actor_latents: Vec<f32> = (0..n * lat)
            .map(|i| (mean[i] + logvar[i].exp().sqrt() * noise.actor_posterior[i]) * scale)
            .collect();

        // 2.-3. Every token re-runs the whole unmasked prefix; one noise token for all.
        let grid = meanflow_grid(steps);
        let modulation = stack_rows("context_full", &[&cond.modulation])?;
        let mut sequence = cond.start_token.clone(); // [<sos>, (a_j || b_j)...]
        let (mut reactor, mut contexts) = (Vec::with_capacity(n * lat), Vec::with_capacity(n * c));
        for i in 0..n {
            let out = full.run(vec![
                f32_tensor(&[1, i + 1, c], &sequence),
                modulation.clone(),
            ])?;
            let context = read_f32("context_full", "context", &out[0], &[1, c])?.to_vec();
            let a = &actor_latents[i * lat..(i + 1) * lat];
            let mut z = noise.reactor_noise.clone();
            for k in 0..steps as usize {
                // A token of many steps is long: the time budget is checked at each of them.
                progress::check_time("the clip")?;
                let u = self.guided_velocity(a, &z, &context, grid[k + 1], grid[k], cfg_scale)?;
                let dt = grid[k] - grid[k + 1];
                for (zv, uv) in z.iter_mut().zip(&u) {
                    *zv -= dt * uv;
                }
            }
            check_output("velocity", &format!("reactor token {i}"), &z)?;
            check_output("context_full", &format!("context {i}"), &context)?;
            progress::report("the clip", i as u64 + 1, n as u64)?;
            sequence.extend_from_slice(a);
            sequence.extend_from_slice(&z);
            reactor.extend_from_slice(&z);
            contexts.extend_from_slice(&context);
        }

        // 4. One decode of all tokens, padded to the clip by repeating the last frame.
        let unscaled: Vec<f32> = reactor.iter().map(|v| v / scale).collect();
        let mut frames = self.decode(&unscaled)?;
        check_output("vae_decoder", "decoded clip", &frames)?;
        let last = frames[frames.len() - d..].to_vec();
        while frames.len() < clip.frames * d {
            frames.extend_from_slice(&last);
        }
        let rows = |v: Vec<f32>, w: usize| Array2::from_shape_vec((v.len() / w, w), v);
        Ok(Clip {
            frames: rows(frames, d).expect("whole frames"),
            actor_latents: rows(actor_latents, lat).expect("whole tokens"),
            reactor_latents: rows(reactor, lat).expect("whole tokens"),
            contexts: rows(contexts, c).expect("whole contexts"),
        })
    }

    /// `u(z, r, t)` for one token, guided when `scale` is not 1: the conditional and the null
    /// row (actor token and context zeroed) in one call, `u_null + scale * (u_cond - u_null)`.
    fn guided_velocity(
        &self,
        actor: &[f32],
        z: &[f32],
        context: &[f32],
        r: f32,
        t: f32,
        scale: f32,
    ) -> Result<Vec<f32>> {
        if !guided(scale) {
            return self.velocity(actor, z, context, &[r], &[t]);
        }
        let (lat, c) = (actor.len(), context.len());
        let mut actors = actor.to_vec();
        actors.resize(2 * lat, 0.0);
        let mut contexts = context.to_vec();
        contexts.resize(2 * c, 0.0);
        let noisy = [z, z].concat();
        let u = self.velocity(&actors, &noisy, &contexts, &[r, r], &[t, t])?;
        let (cond, null) = u.split_at(lat);
        Ok(cond
            .iter()
            .zip(null)
            .map(|(uc, un)| un + scale * (uc - un))
            .collect())
    }

    fn require_clip(&self) -> Result<&ClipSpec> {
        self.spec.clip.as_ref().ok_or_else(|| {
            Error::InvalidInput(format!(
                "bundle `{}` has no `clip` section: clip generation needs a bundle exported \
                 from the official layout (onnx/cli.py armflow export --preset interhuman | \
                 interx)",
                self.io.name
            ))
        })
    }
}

fn check_clip_noise(noise: &ClipNoise, tokens: usize, lat: usize) -> Result<()> {
    let sizes = [
        ("actor_posterior", noise.actor_posterior.len(), tokens * lat),
        ("reactor_noise", noise.reactor_noise.len(), lat),
    ];
    for (name, got, want) in sizes {
        if got != want {
            return Err(Error::InvalidInput(format!(
                "clip noise `{name}` has {got} floats, expected {want}"
            )));
        }
    }
    check_input("clip noise actor_posterior", &noise.actor_posterior)?;
    check_input("clip noise reactor_noise", &noise.reactor_noise)
}
