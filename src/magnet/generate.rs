//! [`crate::Magnet::generate`]: one released sampling configuration run on a clip of
//! troupe frames, from the frames in to the frames out.

use ndarray::{s, Array2, Array3, Array4, ArrayView2, ArrayView3, Axis};

use super::draws::Draws;
use super::guidance::Guidance;
use super::layout::{FRAMES_PER_TOKEN, FRAME_DIM};
use super::motion;
use super::networks::Networks;
use super::spec::{SamplingSpec, Task};
use super::tasks::{self, Run};
use crate::shared::checks::check_input;
use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, LIMITS};
use crate::shared::progress;

/// The injected draws `options` give, if any.
pub(crate) fn injected_draws(options: &MagnetOptions) -> Result<Option<Draws>> {
    match (&options.draws, &options.normals) {
        (Some(_), Some(_)) => Err(Error::InvalidOption(
            "give the draws whole or as one queue of normals, not both".into(),
        )),
        (Some(draws), None) => Ok(Some(Draws::injected(draws.clone()))),
        (None, Some(normals)) => Ok(Some(Draws::queue(normals.clone()))),
        (None, None) => Ok(None),
    }
}

/// Changes to a released configuration for one call; `None` keeps the configuration's value.
#[derive(Debug, Clone, Default)]
pub struct MagnetOptions {
    /// Samples generated at once (S).
    pub samples: Option<usize>,
    /// DDIM steps (N).
    pub steps: Option<usize>,
    /// DDIM η.
    pub eta: Option<f32>,
    /// Frames to generate (`sampling_seq_len`).
    pub seq_len: Option<usize>,
    /// The seed of troupe's generator (the configuration's own seed when `None`).
    pub seed: Option<u64>,
    /// Turns the x0 corrections (smoothing, foot skating) off: three to five times cheaper
    /// (`docs/MAGNET.md`), not the released behaviour (§6.5 option (c)).
    pub without_x0_guidance: bool,
    /// In-betweening's key frames within the window: key frame `k` sets token `k / 4`, its
    /// latent from frames `k..k + 4`, its transforms from the token's own frames, as the
    /// official code does (§11 A10); the output's frames `k..k + 4` are the key decoded on its
    /// own where the window holds them (§7.4).
    pub keyframes: Option<Vec<usize>>,
    /// Every draw of the run, in the order of §3.5, instead of troupe's generator.
    pub draws: Option<Vec<Vec<f32>>>,
    /// The run's standard normals as one queue instead of troupe's generator: each draw of
    /// §3.5, in order, takes the next ones it needs (the form C and Python give; not with
    /// `draws`).
    pub normals: Option<Vec<f32>>,
}

/// What [`crate::Magnet::generate`] returns.
#[derive(Debug, Clone)]
pub struct MagnetOutput {
    /// The sampled tokens `[S, T, P, D]`.
    pub tokens: Array4<f32>,
    /// The frames they decode to, `[S, 4T, P, 145]`: betas as given, body rotations, each
    /// person's root in the input's world frame.
    pub frames: Array4<f32>,
    /// The draws the run made.
    pub draws: usize,
    /// The normals it took from [`MagnetOptions::normals`] (0 when none were given).
    pub normals_used: usize,
}

/// The configuration `name` (a released one's name, or a whole configuration as JSON, the
/// fields of the manifest's `sampling` entries) with `options` applied.
pub(crate) fn configuration(
    nets: &Networks,
    name: &str,
    options: &MagnetOptions,
) -> Result<SamplingSpec> {
    let spec = &nets.spec;
    let mut cfg = if name.trim_start().starts_with('{') {
        serde_json::from_str::<SamplingSpec>(name).map_err(|e| {
            Error::InvalidOption(format!("the sampling configuration is not valid: {e}"))
        })?
    } else {
        spec.sampling.get(name).cloned().ok_or_else(|| {
            Error::InvalidOption(format!(
                "bundle `{}` has no sampling configuration `{name}` (it has: {})",
                nets.io.name,
                spec.sampling.keys().cloned().collect::<Vec<_>>().join(", ")
            ))
        })?
    };
    if let Some(s) = options.samples {
        cfg.samples = s;
    }
    if let Some(n) = options.steps {
        cfg.steps = n;
    }
    if let Some(eta) = options.eta {
        cfg.eta = eta;
    }
    if let Some(n) = options.seq_len {
        cfg.seq_len = n;
    }
    if let Some(seed) = options.seed {
        cfg.seed = seed;
    }
    if options.without_x0_guidance {
        cfg.guidance.smoothing = None;
        cfg.guidance.foot_skating = None;
    }
    if let Some(keys) = &options.keyframes {
        cfg.keyframes = keys.clone();
    }
    Ok(cfg)
}

/// The bundle's first `motion_control_live` configuration (by name), what a live partner
/// session runs unless told otherwise.
pub(crate) fn default_live_config(nets: &Networks) -> Result<String> {
    let mut names: Vec<&String> = nets
        .spec
        .sampling
        .iter()
        .filter(|(_, c)| c.task == Task::MotionControlLive)
        .map(|(name, _)| name)
        .collect();
    names.sort();
    names.first().map(|n| n.to_string()).ok_or_else(|| {
        Error::InvalidOption(format!(
            "bundle `{}` has no motion_control_live configuration: give one as JSON \
             (SessionOptions::live_config)",
            nets.io.name
        ))
    })
}

/// Checks a configuration against the model: the manifest's rules, and in-betweening's window.
pub(crate) fn check_configuration(nets: &Networks, cfg: &SamplingSpec) -> Result<()> {
    nets.spec
        .validate_sampling(cfg)
        .map_err(Error::InvalidOption)?;
    at_most(
        "seq_len",
        cfg.seq_len as u64,
        LIMITS.max_frames_per_call,
        true,
    )?;
    let window_frames = nets.spec.model.window * FRAMES_PER_TOKEN;
    if cfg.task == Task::Inbetweening {
        if cfg.seq_len != window_frames {
            return Err(Error::InvalidOption(format!(
                "in-betweening covers one window of {window_frames} frames, not seq_len {}",
                cfg.seq_len
            )));
        }
        if let Some(k) = cfg.keyframes.iter().find(|&&k| k >= window_frames) {
            return Err(Error::InvalidOption(format!(
                "key frame {k}: key frames lie in the window's {window_frames} frames"
            )));
        }
    }
    Ok(())
}

/// Runs `cfg` on `frames` `[F, P, 145]` with presence `mask` `[F, P]`.
pub(crate) fn generate(
    nets: &Networks,
    cfg: SamplingSpec,
    frames: ArrayView3<f32>,
    mask: Option<ArrayView2<bool>>,
    draws: Option<Draws>,
) -> Result<MagnetOutput> {
    let m = &nets.spec.model;
    let (f, p, width) = frames.dim();
    output_shape(nets, &cfg, f)?;
    if p != m.persons || width != FRAME_DIM {
        return Err(Error::InvalidInput(format!(
            "frames are [{f}, {p}, {width}]; bundle `{}` takes [frames, {}, {FRAME_DIM}] \
             ({} people)",
            nets.io.name, m.persons, m.persons
        )));
    }
    let values = frames.as_standard_layout();
    check_input("frames", values.as_slice().expect("standard layout"))?;
    let mask = match mask {
        Some(mask) if mask.dim() != (f, p) => {
            return Err(Error::InvalidInput(format!(
                "the presence mask is {:?}, the frames {:?}",
                mask.dim(),
                (f, p)
            )))
        }
        Some(mask) => mask.to_owned(),
        None => Array2::from_elem((f, p), true),
    };
    // The call budget's clock; the work is checked once the task knows it (`Run::start_task`).
    let _clock = progress::start_clock();
    let clip = motion::clip_from_frames(values.view(), mask.view());
    let betas = motion::normalised_betas(nets, &clip);
    let s = cfg.samples;
    let batch_betas = betas
        .broadcast((s, p, betas.dim().1))
        .expect("[P, 10]")
        .to_owned();
    let seed = cfg.seed;
    let guidance_spec = cfg.guidance.clone();
    let mut run = Run {
        nets,
        schedule: &nets.schedule,
        draws: draws.unwrap_or_else(|| Draws::seeded(seed)),
        guidance: Guidance {
            nets,
            spec: &guidance_spec,
            schedule: &nets.schedule,
            betas: batch_betas,
            total: 0,
            counter: 0,
            runs: 1,
        },
        window: m.window,
        persons: p,
        latent: m.vq.d_latent,
        cfg,
    };
    let per_sample = |a: Array3<f32>| {
        let (t, _, d) = a.dim();
        a.insert_axis(Axis(0))
            .broadcast((s, t, p, d))
            .expect("one clip")
            .to_owned()
    };
    let tc = run.cfg.context_len / FRAMES_PER_TOKEN;
    let task = run.cfg.task;
    // In-betweening's key tokens as given, which decoding puts back (§7.4).
    let mut key_frames = None;
    let tokens = match task {
        Task::Joint | Task::AgenticTurnTaking | Task::AgenticSync => {
            let context = motion::encode(nets, &clip, 0, tc * FRAMES_PER_TOKEN)?;
            let present = clip
                .mask
                .slice(s![..tc * FRAMES_PER_TOKEN;FRAMES_PER_TOKEN, ..])
                .to_owned();
            let present = present
                .insert_axis(Axis(0))
                .broadcast((s, tc, p))
                .expect("one clip")
                .to_owned();
            let context = per_sample(context);
            match task {
                Task::Joint => tasks::joint(&mut run, context.view(), present.view())?,
                Task::AgenticTurnTaking => {
                    tasks::two_worlds(&mut run, context.view(), present.view(), false)?
                }
                _ => tasks::two_worlds(&mut run, context.view(), present.view(), true)?,
            }
        }
        Task::Inbetweening => {
            let (keys, is_key) = motion::key_tokens(nets, &clip, &run.cfg.keyframes)?;
            let tokens = tasks::inbetweening(&mut run, per_sample(keys.clone()).view(), &is_key)?;
            key_frames = Some(keys);
            tokens
        }
        Task::PartnerPrediction
        | Task::MotionControlLive
        | Task::PartnerInpainting
        | Task::Pp2joint => {
            let span = f.min(run.cfg.seq_len) / FRAMES_PER_TOKEN * FRAMES_PER_TOKEN;
            let gt = per_sample(motion::encode(nets, &clip, 0, span)?);
            match task {
                Task::PartnerPrediction => tasks::partner_prediction(&mut run, gt.view())?,
                Task::Pp2joint => {
                    let frames = run.cfg.seq_len;
                    tasks::pp2joint(&mut run, gt.view(), frames)?
                }
                _ => tasks::live_like(&mut run, gt.view(), task)?,
            }
        }
    };
    let used = run.draws.count();
    let normals_used = match run.draws {
        Draws::Queue { used, .. } => used,
        _ => 0,
    };
    let mut decoded = motion::decode(nets, tokens.view(), betas.view())?;
    if let Some(keys) = key_frames {
        let keyframes = &run.cfg.keyframes;
        motion::overwrite_key_frames(
            nets,
            &mut decoded,
            tokens.view(),
            keys.view(),
            keyframes,
            betas.view(),
        )?;
    }
    let c = motion::anchor_frame(run.cfg.context_len);
    let roots = motion::world_roots(&decoded, c, &clip);
    let raw_betas = clip.betas.clone();
    let frames_out = motion::frames_out(&decoded, &roots, raw_betas.view());
    Ok(MagnetOutput {
        tokens: tokens.as_standard_layout().into_owned(),
        frames: frames_out,
        draws: used,
        normals_used,
    })
}

/// `[S, F, P, 145]` of the frames `cfg` returns for `input_frames` frames of input, after the
/// checks `generate` makes of the configuration and the input's length.
pub(crate) fn output_shape(
    nets: &Networks,
    cfg: &SamplingSpec,
    input_frames: usize,
) -> Result<[usize; 4]> {
    check_configuration(nets, cfg)?;
    let need = needed_frames(cfg);
    if input_frames < need {
        return Err(Error::InvalidInput(format!(
            "{} with this configuration needs at least {need} frames of input, got {input_frames}",
            cfg.task.name()
        )));
    }
    at_most(
        "input frames",
        input_frames as u64,
        LIMITS.max_frames_per_call,
        false,
    )?;
    let tokens = output_tokens(nets, cfg, input_frames);
    // The token buffer, the largest allocation of a run, within the limit on any one tensor.
    let m = &nets.spec.model;
    let elements =
        (cfg.samples as u128) * (tokens as u128) * (m.token_dim as u128) * (m.persons as u128);
    at_most(
        "samples x tokens x people x token width",
        u64::try_from(elements).unwrap_or(u64::MAX),
        LIMITS.max_tensor_elements,
        true,
    )?;
    Ok([
        cfg.samples,
        tokens * FRAMES_PER_TOKEN,
        nets.spec.model.persons,
        FRAME_DIM,
    ])
}

/// The tokens a configuration generates from `input_frames` frames of input (§5.1): the AR
/// tasks' whole buffer (context included), the rolling tasks' ground-truth span, pp2joint's
/// span less its context plus the joint phase, in-betweening's window.
fn output_tokens(nets: &Networks, cfg: &SamplingSpec, input_frames: usize) -> usize {
    let m = &nets.spec.model;
    let ar_total = |seq_len: usize| {
        let stride = cfg.ar_seq_stride / FRAMES_PER_TOKEN;
        let need = (seq_len / FRAMES_PER_TOKEN).max(m.window);
        (need - m.window).div_ceil(stride.max(1)) * stride + m.window
    };
    let span = input_frames.min(cfg.seq_len) / FRAMES_PER_TOKEN;
    match cfg.task {
        Task::Joint | Task::AgenticTurnTaking | Task::AgenticSync => ar_total(cfg.seq_len),
        Task::Inbetweening => m.window,
        Task::Pp2joint => span - cfg.context_len / FRAMES_PER_TOKEN + ar_total(cfg.seq_len),
        _ => span,
    }
}

/// The fewest frames of input a configuration reads: the context for every task but
/// in-betweening (the rolling tasks take the others' context from the same frames), the last
/// key frame's 4 frames for in-betweening.
fn needed_frames(cfg: &SamplingSpec) -> usize {
    match cfg.task {
        Task::Inbetweening => cfg
            .keyframes
            .iter()
            .map(|k| k + FRAMES_PER_TOKEN)
            .max()
            .unwrap_or(FRAMES_PER_TOKEN),
        _ => cfg.context_len.max(FRAMES_PER_TOKEN),
    }
}
