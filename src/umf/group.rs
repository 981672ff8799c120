//! Text-to-group generation (UMF, `docs/spec/umf.md`): the first person by Pyramid Flow, every
//! further person by Semi-Noise Flow from a context of everyone generated before, then one
//! decode.
//!
//! ```text
//! z   <- prior noise [tokens_0, dim]
//! for stage k:  (k > 0)  z <- alpha_k * Up(z) + beta_k * n'_k          (pyramid.rs)
//!               solve dz/dtau = G_P(z, (a_k tau + b_k) / time_scale, text_P) over tau in [0, 1]
//! Z_1 <- z
//! for person i >= 2:
//!     C   <- context([Z_1 .. Z_{i-1}])                                 (pooled over persons)
//!     w   <- [eps_i ; C] per token                                      ([tokens, 2 dim])
//!     solve dw/dtau = G_S(w, tau, text_S);  Z_i <- second half of w
//! motion <- decoder(Z_1 .. Z_n)
//! ```
//! `G = G_null + w (G_cond - G_null)`, one network call on the batch `[null; cond]`; with
//! `w = 1` only the conditional half runs.
//!
//! [`crate::Umf::generate_group`] calls [`Networks::generate_group`].

use ndarray::Array3;
use tract_onnx::prelude::TValue;

use super::networks::Networks;
use super::pyramid::Jump;
use super::spec::UmfSpec;
use crate::shared::checks::{check_input, check_output};
use crate::shared::error::{Error, Result};
use crate::shared::graph::{f32_tensor, read_f32, Graph};
use crate::shared::limits::{check_cfg, product_at_most, LIMITS};
use crate::shared::noise::fill_normals;
use crate::shared::progress;
use crate::shared::solver::Solver;

/// Stream id of the first person's starting noise (token index 0).
pub const STREAM_PRIOR_NOISE: u32 = 2;
/// Stream id of the standard normals behind the jump into stage `k` (token index `k`).
pub const STREAM_JUMP_NOISE: u32 = 3;
/// Stream id of person `p`'s (0-based, `p >= 1`) semi-noise start (token index `p`).
pub const STREAM_REACTION_NOISE: u32 = 4;

/// The most people one call generates; the cost grows with the square of the count (each new
/// person's context reads all previous ones).
pub const MAX_PEOPLE: usize = crate::shared::limits::LIMITS.max_people as usize;

/// Settings of one [`crate::Umf::generate_group`] call; `None` takes the bundle's default.
#[derive(Debug, Clone, Default)]
pub struct GroupOptions {
    /// Seed of every random draw not given in `noise`.
    pub seed: u64,
    /// Classifier-free guidance scale (1: conditional branch only).
    pub cfg_scale: Option<f32>,
    /// One solver per pyramid stage, e.g. UMF's code: RK4 with 4 steps per stage; its paper:
    /// Euler 45 and 5.
    pub prior: Option<Vec<Solver>>,
    /// The solver of each further person (UMF: RK4 with 4 steps; its paper: Euler 10).
    pub reaction: Option<Solver>,
    /// Every random draw, given instead of seeded (for parity with a reference run).
    pub noise: Option<GroupNoise>,
}

/// Every random value a group generation uses. Latent-shaped arrays are row-major
/// `[tokens, dim]`.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupNoise {
    /// The first person's starting state at the coarsest stage: `[tokens_0, dim]`.
    pub prior: Vec<f32>,
    /// For each jump (into stage 1, 2, ...), the block-correlated noise `n'` itself, laid out
    /// as the finer stage's tokens: `[tokens_k, dim]`.
    pub jumps: Vec<Vec<f32>>,
    /// For each further person, the noise half of its starting state: `[tokens, dim]`.
    pub reactions: Vec<Vec<f32>>,
}

/// Floats in each array of a [`GroupNoise`] for a number of people: the one place the noise's
/// shape is derived from the bundle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GroupNoiseShape {
    /// Floats of [`GroupNoise::prior`].
    pub prior: usize,
    /// Floats of each of [`GroupNoise::jumps`], in stage order.
    pub jumps: Vec<usize>,
    /// Floats of each of [`GroupNoise::reactions`].
    pub reaction: usize,
    /// How many reactions: one per person after the first.
    pub reactions: usize,
}

/// A generated group.
#[derive(Debug, Clone)]
pub struct Group {
    /// Each person's latent, `[people, tokens, dim]`.
    pub latents: Array3<f32>,
    /// Each person's decoded motion features, `[people, clip_frames, frame_dim]`.
    pub motion: Array3<f32>,
}

/// Settings resolved against the bundle's defaults and checked.
struct Plan<'a> {
    spec: &'a UmfSpec,
    jumps: Vec<Jump>,
    prior: Vec<Solver>,
    reaction: Solver,
    cfg_scale: f32,
}

/// A group's network evaluations so far, reported as its progress.
struct Evaluations {
    done: std::cell::Cell<u64>,
    total: u64,
}

impl Evaluations {
    fn one_more(&self) -> Result<()> {
        self.done.set(self.done.get() + 1);
        progress::report("the group", self.done.get(), self.total)
    }
}

impl Networks {
    /// Generates `people` persons' motion for `condition` (`None`: the null condition).
    pub(crate) fn generate_group(
        &self,
        condition: Option<&[f32]>,
        people: usize,
        options: &GroupOptions,
    ) -> Result<Group> {
        let spec = &self.spec;
        self.check_group_size(people)?;
        let plan = self.plan(spec, options)?;
        let texts = self.texts(spec, condition)?;
        let noise = match &options.noise {
            Some(noise) => {
                self.check_noise(spec, people, noise)?;
                noise.clone()
            }
            None => self.group_noise(options.seed, people)?,
        };
        let (tokens, dim) = (spec.latent.tokens, spec.latent.dim);

        // Progress counts network evaluations, so that one long solve can be stopped too.
        let total = plan.prior.iter().map(|s| s.evaluations()).sum::<usize>()
            + (people - 1) * plan.reaction.evaluations();
        let _clock = progress::start_call("the group", total as u64, "network evaluations")?;
        let counter = Evaluations {
            done: std::cell::Cell::new(0),
            total: total as u64,
        };
        let mut latents = Vec::with_capacity(people * tokens * dim);
        latents.extend(self.first_person(&plan, &self.prior, &texts, &noise, &counter)?);
        for (p, eps) in noise.reactions.iter().enumerate().map(|(i, e)| (i + 1, e)) {
            let context = read_context(&self.context, &latents[..p * tokens * dim], tokens, dim)?;
            let mut state = Vec::with_capacity(tokens * 2 * dim);
            for k in 0..tokens {
                state.extend_from_slice(&eps[k * dim..(k + 1) * dim]);
                state.extend_from_slice(&context[k * dim..(k + 1) * dim]);
            }
            plan.reaction.solve(&mut state, |tau, w| {
                let v = guided(&self.reaction, &plan, w, tokens, tau, &texts.reaction)?;
                counter.one_more()?;
                Ok(v)
            })?;
            for k in 0..tokens {
                latents.extend_from_slice(&state[(2 * k + 1) * dim..(2 * k + 2) * dim]);
            }
        }

        let frames = spec.clip_frames;
        let frame_dim = self.io.frame_dim();
        let out = self
            .decoder
            .run(vec![f32_tensor(&[people, tokens, dim], &latents)])?;
        let motion = read_f32("decoder", "motion", &out[0], &[people, frames, frame_dim])?.to_vec();
        check_output("denoisers", "generated latents", &latents)?;
        check_output("decoder", "decoded motion", &motion)?;
        Ok(Group {
            latents: Array3::from_shape_vec((people, tokens, dim), latents)
                .expect("people * tokens * dim"),
            motion: Array3::from_shape_vec((people, frames, frame_dim), motion)
                .expect("checked shape"),
        })
    }

    /// The noise `generate_group` draws for `seed` and `people` when none is given: Philox
    /// normals (see [`crate::noise`]) on streams [`STREAM_PRIOR_NOISE`],
    /// [`STREAM_JUMP_NOISE`] (turned into block noise by each jump's covariance factor) and
    /// [`STREAM_REACTION_NOISE`].
    pub(crate) fn group_noise(&self, seed: u64, people: usize) -> Result<GroupNoise> {
        let spec = &self.spec;
        let shape = self.group_noise_shape(people)?;
        let dim = spec.latent.dim;
        let draw = |token: u64, stream: u32, n: usize| {
            let mut v = vec![0f32; n];
            fill_normals(seed, token, stream, &mut v);
            v
        };
        let jumps = spec.jumps()?;
        Ok(GroupNoise {
            prior: draw(0, STREAM_PRIOR_NOISE, shape.prior),
            jumps: jumps
                .iter()
                .zip(&shape.jumps)
                .enumerate()
                .map(|(i, (jump, &n))| {
                    let normals = draw(i as u64 + 1, STREAM_JUMP_NOISE, n);
                    jump.block_noise(&normals, n / dim, dim)
                })
                .collect(),
            reactions: (1..people)
                .map(|p| draw(p as u64, STREAM_REACTION_NOISE, shape.reaction))
                .collect(),
        })
    }

    /// The shape of the [`GroupNoise`] of `people` people (1 to [`MAX_PEOPLE`]).
    pub(crate) fn group_noise_shape(&self, people: usize) -> Result<GroupNoiseShape> {
        let spec = &self.spec;
        self.check_group_size(people)?;
        let dim = spec.latent.dim;
        let stages = &spec.pyramid.stages;
        Ok(GroupNoiseShape {
            prior: stages[0].tokens * dim,
            jumps: stages[1..].iter().map(|s| s.tokens * dim).collect(),
            reaction: spec.latent.tokens * dim,
            reactions: people - 1,
        })
    }

    fn plan<'a>(&self, spec: &'a UmfSpec, options: &GroupOptions) -> Result<Plan<'a>> {
        let prior = options
            .prior
            .clone()
            .unwrap_or_else(|| spec.sampler.prior.clone());
        let stages = spec.pyramid.stages.len();
        if prior.len() != stages {
            return Err(Error::InvalidOption(format!(
                "{} prior solvers given for a pyramid of {stages} stages",
                prior.len()
            )));
        }
        for (k, solver) in prior.iter().enumerate() {
            solver.check(&format!("prior solver of stage {k}"))?;
        }
        let reaction = options.reaction.unwrap_or(spec.sampler.reaction);
        reaction.check("reaction solver")?;
        let cfg_scale = options.cfg_scale.unwrap_or(spec.sampler.cfg_scale);
        check_cfg(cfg_scale)?;
        Ok(Plan {
            spec,
            jumps: spec.jumps()?,
            prior,
            reaction,
            cfg_scale,
        })
    }

    /// Splits the condition (or the null condition) into each denoiser's text, each paired with
    /// its null text for guidance.
    fn texts(&self, spec: &UmfSpec, condition: Option<&[f32]>) -> Result<Texts> {
        let null = self.io.condition.null_or_zeros();
        let cond = match condition {
            Some(c) => {
                if c.len() != null.len() {
                    return Err(Error::InvalidInput(format!(
                        "condition has {} floats, the bundle expects {} ({} prior text + {} \
                         reaction text)",
                        c.len(),
                        null.len(),
                        spec.text.prior_dim,
                        spec.text.reaction_dim
                    )));
                }
                check_input("condition", c)?;
                c.to_vec()
            }
            None => null.clone(),
        };
        let at = spec.text.prior_dim;
        let pair = |range: std::ops::Range<usize>| {
            let (null, cond) = (&null[range.clone()], &cond[range]);
            TextPair {
                cond: f32_tensor(&[1, cond.len()], cond),
                batch: f32_tensor(&[2, cond.len()], &[null, cond].concat()),
            }
        };
        Ok(Texts {
            prior: pair(0..at),
            reaction: pair(at..null.len()),
        })
    }

    fn check_noise(&self, spec: &UmfSpec, people: usize, noise: &GroupNoise) -> Result<()> {
        let dim = spec.latent.dim;
        let shape = self.group_noise_shape(people)?;
        let check = |what: String, values: &[f32], floats: usize| {
            if values.len() != floats {
                return Err(Error::InvalidInput(format!(
                    "{what} holds {} floats, expected {} tokens x {dim}",
                    values.len(),
                    floats / dim
                )));
            }
            check_input(&what, values)
        };
        check("prior noise".into(), &noise.prior, shape.prior)?;
        if noise.jumps.len() != shape.jumps.len() || noise.reactions.len() != shape.reactions {
            return Err(Error::InvalidInput(format!(
                "noise holds {} jumps and {} reactions; {} stages and {people} people need {} \
                 and {}",
                noise.jumps.len(),
                noise.reactions.len(),
                shape.jumps.len() + 1,
                shape.jumps.len(),
                shape.reactions
            )));
        }
        for (k, (jump, &floats)) in noise.jumps.iter().zip(&shape.jumps).enumerate() {
            check(format!("jump noise {}", k + 1), jump, floats)?;
        }
        for (p, eps) in noise.reactions.iter().enumerate() {
            check(
                format!("reaction noise of person {}", p + 1),
                eps,
                shape.reaction,
            )?;
        }
        Ok(())
    }

    /// Pyramid Flow: the first person's latent, `[tokens, dim]`.
    fn first_person(
        &self,
        plan: &Plan,
        prior: &Graph,
        texts: &Texts,
        noise: &GroupNoise,
        counter: &Evaluations,
    ) -> Result<Vec<f32>> {
        let pyramid = &plan.spec.pyramid;
        let dim = plan.spec.latent.dim;
        let time_scale = pyramid.time_scale as f32;
        let mut z = noise.prior.clone();
        for (k, (stage, solver)) in pyramid.stages.iter().zip(&plan.prior).enumerate() {
            if k > 0 {
                z = plan.jumps[k - 1].apply(&z, &noise.jumps[k - 1], dim);
            }
            // The official code maps tau linearly onto the stage's table in f32:
            // (slope * tau + intercept) / 1000 with the slope and intercept from f64 values.
            let [first, last] = stage.timesteps;
            let (slope, intercept) = ((last - first) as f32, first as f32);
            solver.solve(&mut z, |tau, y| {
                let timestep = (slope * tau + intercept) / time_scale;
                let v = guided(prior, plan, y, stage.tokens, timestep, &texts.prior)?;
                counter.one_more()?;
                Ok(v)
            })?;
        }
        Ok(z)
    }
}

impl Networks {
    /// `people` within 1..=[`MAX_PEOPLE`], and the group's latents and motion within
    /// `LIMITS.max_tensor_elements` floats each (checked before any is allocated).
    fn check_group_size(&self, people: usize) -> Result<()> {
        check_people(people)?;
        let spec = &self.spec;
        let (p, frames, d) = (
            people as u64,
            spec.clip_frames as u64,
            self.io.frame_dim() as u64,
        );
        let (tokens, dim) = (spec.latent.tokens as u64, spec.latent.dim as u64);
        for (what, factors) in [
            ("the group's latents", [p, tokens, dim]),
            ("the group's motion", [p, frames, d]),
        ] {
            product_at_most(what, &factors, LIMITS.max_tensor_elements)
                .map_err(Error::InvalidInput)?;
        }
        Ok(())
    }
}

fn check_people(people: usize) -> Result<()> {
    if people == 0 || people > MAX_PEOPLE {
        return Err(Error::InvalidInput(format!(
            "people is {people}; a group has 1 to {MAX_PEOPLE} people"
        )));
    }
    Ok(())
}

/// One denoiser's text input, built once per generation: the conditional row alone, and the
/// guidance batch `[null; cond]`.
struct TextPair {
    cond: TValue,
    batch: TValue,
}

struct Texts {
    prior: TextPair,
    reaction: TextPair,
}

/// The guided velocity of a denoiser (`prior` or `reaction`) at state `y` (`[tokens, width]`).
fn guided(
    net: &Graph,
    plan: &Plan,
    y: &[f32],
    tokens: usize,
    timestep: f32,
    text: &TextPair,
) -> Result<Vec<f32>> {
    let width = y.len() / tokens;
    let role = net.role();
    if plan.cfg_scale == 1.0 {
        let out = net.run(vec![
            f32_tensor(&[1, tokens, width], y),
            f32_tensor(&[1], &[timestep]),
            text.cond.clone(),
        ])?;
        return Ok(read_f32(role, "velocity", &out[0], &[1, tokens, width])?.to_vec());
    }
    let states = [y, y].concat();
    let out = net.run(vec![
        f32_tensor(&[2, tokens, width], &states),
        f32_tensor(&[2], &[timestep, timestep]),
        text.batch.clone(),
    ])?;
    let both = read_f32(role, "velocity", &out[0], &[2, tokens, width])?;
    let (uncond, cond) = both.split_at(y.len());
    let w = plan.cfg_scale;
    Ok(uncond
        .iter()
        .zip(cond)
        .map(|(u, c)| u + w * (c - u))
        .collect())
}

/// The context adapter over the people so far (`[p, tokens, dim]`): `[tokens, dim]`.
fn read_context(net: &Graph, people_so_far: &[f32], tokens: usize, dim: usize) -> Result<Vec<f32>> {
    let p = people_so_far.len() / (tokens * dim);
    let out = net.run(vec![f32_tensor(&[1, p, tokens, dim], people_so_far)])?;
    Ok(read_f32("context", "context", &out[0], &[1, tokens, dim])?.to_vec())
}
