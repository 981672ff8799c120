//! The live partner: `motion_control_live` (`docs/spec/magnet.md` §5.4) as a stream. The
//! user's frames come in as they happen; the partner's frames go out chunk by chunk, each chunk
//! one rolling window of the official loop. Mirrors `onnx/troupe_onnx/magnet/live.py`, whose
//! module comment lists where a stream must differ from the offline loop (the user's tokens from
//! the frames received, the user's partner-relative transforms from the partner's, draws per
//! chunk, emission, decoding by windows, roots chained from the opening frames).
//!
//! Chunk `c` covers the window of tokens `[w0, w0 + Tm)`, `w0 = c (Tm - Tc)`; it runs once the
//! user's frames reach `4 (w0 + Tm)`. Crowds of streams that need a chunk in the same call run
//! it together, their samples stacked ([`advance`]).

use std::collections::VecDeque;
use std::sync::Arc;

use ndarray::{concatenate, s, Array2, Array3, Array4, ArrayView2, Axis};

use super::draws::Draws;
use super::guidance::Guidance;
use super::layout::{
    stats, BETAS, FRAMES_PER_TOKEN, FRAME_BETAS, FRAME_DIM, FRAME_ROOT, TOKEN_TRANSFORMS, TRANSFORM,
};
use super::motion::{self, Decoded};
use super::networks::Networks;
use super::spec::{SamplingSpec, Task};
use super::tasks::{live_matrix, rolling_chunk, Run};
use super::transforms::{canonical_frame, compose, from_9d, inverse, to_9d, Mat4};
use crate::family::session::Session;
use crate::family::stream::{
    downcast_all, Capabilities, Capability, Finish, StepOutput, StepTogether, Stream, TokenTrace,
};
use crate::shared::bundle_io::BundleIo;
use crate::shared::checks::{check_frames, check_input};
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{self, SnapshotReader, SnapshotWriter};

/// Tokens of the user's past frames the encoder sees before a window (its receptive field
/// reaches about 21 tokens back).
pub const ENCODER_CONTEXT_TOKENS: usize = 24;
/// Tokens already sent that the decoder sees before the tokens it decodes (about 22 reach).
pub const DECODER_CONTEXT_TOKENS: usize = 24;

/// How a live partner stream runs (everything `reset` keeps).
#[derive(Debug, Clone)]
pub struct LiveSettings {
    /// A `motion_control_live` configuration; one sample.
    pub sampling: SamplingSpec,
    /// The seed of troupe's generator.
    pub seed: u64,
    /// Emit each chunk's generated tokens at once (latency `4 (Tm - Tc) - 1` frames) rather than
    /// once no later chunk changes them (`4 Tm - 1`, the default).
    pub early: bool,
    /// The partner's opening frames, `[context_len, 145]` row-major.
    pub opening: Option<Vec<f32>>,
}

/// One user/partner stream over a two-person `magnet` model (made by `Magnet::partner`, or
/// boxed in a [`crate::Session`] by `Model::session`). `Send`, not `Sync`.
#[derive(Debug)]
pub struct LivePartner {
    nets: Arc<Networks>,
    settings: LiveSettings,
    state: LiveState,
}

/// Everything a stream accumulates; `reset()` returns it to `LiveState::new`.
#[derive(Debug, Clone)]
struct LiveState {
    /// User frames from index `user_base` on, row-major.
    user: Vec<f32>,
    user_base: u64,
    received: u64,
    /// The user's raw betas (from the first frame).
    user_betas: Vec<f32>,
    chunks: u64,
    /// The last chunk's window `[1, Tm, P, D]`.
    window: Option<Array4<f32>>,
    /// The partner's opening tokens `[Tc, D]`, encoded with the user's first frames.
    opening_tokens: Option<Array2<f32>>,
    /// The last tokens sent, for the decoder's left context.
    sent: VecDeque<Vec<f32>>,
    frames_out: u64,
    tokens_out: u64,
    /// The partner's canonical frame in the world at the last frame sent (past the opening).
    world: Option<Mat4>,
    draws: Draws,
}

impl LiveState {
    fn new(seed: u64) -> Self {
        Self {
            user: Vec::new(),
            user_base: 0,
            received: 0,
            user_betas: Vec::new(),
            chunks: 0,
            window: None,
            opening_tokens: None,
            sent: VecDeque::new(),
            frames_out: 0,
            tokens_out: 0,
            world: None,
            draws: Draws::seeded(seed),
        }
    }
}

/// A token a stream sent.
#[derive(Debug, Clone)]
pub(crate) struct SentToken {
    /// Its index in the stream.
    pub index: u64,
    /// The user's token at the same place.
    pub user: Vec<f32>,
    /// The partner's.
    pub partner: Vec<f32>,
}

/// What one step of one stream returns.
#[derive(Debug, Clone)]
pub(crate) struct LiveOutput {
    /// Partner frames `[n, 145]`.
    pub frames: Array2<f32>,
    /// The tokens they decode from, in order.
    pub tokens: Vec<SentToken>,
}

/// What one chunk of one stream starts from.
struct ChunkInput {
    x: Array4<f32>,
    gt: Array4<f32>,
    inject: Array3<bool>,
    ctx: Array3<bool>,
    /// Normalised betas `[P, 10]`: the user's, the partner's.
    betas: Array2<f32>,
}

impl LivePartner {
    /// A fresh stream; `settings.sampling` must be a checked `motion_control_live` configuration
    /// of a two-person model.
    pub(crate) fn new(nets: Arc<Networks>, settings: LiveSettings) -> Result<Self> {
        check_settings(&nets, &settings)?;
        Ok(Self {
            state: LiveState::new(settings.seed),
            nets,
            settings,
        })
    }

    /// Window, context and stride in tokens.
    fn geometry(&self) -> (usize, usize, usize) {
        let tm = self.nets.spec.model.window;
        let tc = self.settings.sampling.context_len / FRAMES_PER_TOKEN;
        (tm, tc, tm - tc)
    }

    /// Replaces the settings (checked); the stream goes on. Callers change only what a running
    /// stream can take (steps, and before the first frame the opening and the emission).
    pub(crate) fn configure(&mut self, settings: LiveSettings) -> Result<()> {
        check_settings(&self.nets, &settings)?;
        self.settings = settings;
        Ok(())
    }

    /// Runs the configuration `name` (a released name or JSON; one sample, this stream's seed)
    /// from the next reset or first frame on.
    pub(crate) fn set_config(&mut self, name: &str) -> Result<()> {
        let options = super::generate::MagnetOptions {
            samples: Some(1),
            seed: Some(self.settings.seed),
            ..Default::default()
        };
        let mut settings = self.settings.clone();
        settings.sampling = super::generate::configuration(&self.nets, name, &options)?;
        self.configure(settings)
    }

    /// Floats per token.
    pub(crate) fn token_dim(&self) -> usize {
        self.nets.spec.model.token_dim
    }

    /// Chunks that `total` user frames complete.
    fn chunks_for(&self, total: u64) -> u64 {
        let (tm, _, st) = self.geometry();
        let tokens = total / FRAMES_PER_TOKEN as u64;
        if tokens < tm as u64 {
            0
        } else {
            (tokens - tm as u64) / st as u64 + 1
        }
    }

    /// Partner frames out after `chunks` chunks.
    fn frames_after(&self, chunks: u64) -> u64 {
        let (tm, _, st) = self.geometry();
        let (tm, st, f) = (tm as u64, st as u64, FRAMES_PER_TOKEN as u64);
        match (chunks, self.settings.early) {
            (0, _) => 0,
            (c, true) => f * (tm + st * (c - 1)),
            (c, false) => f * st * c,
        }
    }

    /// The user's tokens `[Tm, D]` of the window from token `w0`, encoded from the user's frames
    /// alone, the partner-relative slots left zero.
    fn user_tokens(&self, state: &LiveState, w0: usize) -> Result<Array2<f32>> {
        let (tm, _, _) = self.geometry();
        let f = FRAMES_PER_TOKEN;
        let b = f * (w0 + tm);
        let a = f * w0.saturating_sub(ENCODER_CONTEXT_TOKENS);
        let first = a.saturating_sub(1); // one frame more: the true transition into frame a
        let base = state.user_base as usize;
        let frames = &state.user[(first - base) * FRAME_DIM..(b - base) * FRAME_DIM];
        let frames = ArrayView2::from_shape((b - first, FRAME_DIM), frames).expect("sized");
        let frames = frames.insert_axis(Axis(1));
        let clip = motion::clip_from_frames(frames, Array2::from_elem((b - first, 1), true).view());
        let tokens = motion::encode(&self.nets, &clip, a - first, b - a)?;
        let n = tokens.dim().0;
        Ok(tokens.slice(s![n - tm.., 0, ..]).to_owned())
    }

    /// The partner's opening tokens `[Tc, D]`: the opening frames with the user's first frames,
    /// encoded as a two-person clip.
    fn opening_tokens(&self, state: &LiveState) -> Result<Array2<f32>> {
        let (_, tc, _) = self.geometry();
        let n = tc * FRAMES_PER_TOKEN;
        let opening = self
            .settings
            .opening
            .as_ref()
            .expect("checked at the first step");
        let mut frames = Array3::<f32>::zeros((n, 2, FRAME_DIM));
        let user = ArrayView2::from_shape((n, FRAME_DIM), &state.user[..n * FRAME_DIM]);
        frames
            .slice_mut(s![.., 0, ..])
            .assign(&user.expect("sized"));
        let partner = ArrayView2::from_shape((n, FRAME_DIM), &opening[..]).expect("checked");
        frames.slice_mut(s![.., 1, ..]).assign(&partner);
        let clip = motion::clip_from_frames(frames.view(), Array2::from_elem((n, 2), true).view());
        let tokens = motion::encode(&self.nets, &clip, 0, n)?;
        Ok(tokens.slice(s![.., 1, ..]).to_owned())
    }

    /// Chunk `state.chunks`'s window, masks and betas; draws its starting noise.
    fn prepare(&self, state: &mut LiveState) -> Result<ChunkInput> {
        let (tm, tc, st) = self.geometry();
        let nets = &self.nets;
        let (p, d, lat) = (2, nets.spec.model.token_dim, nets.spec.model.vq.d_latent);
        let c = state.chunks as usize;
        let w0 = c * st;
        if c == 0 {
            state.opening_tokens = Some(self.opening_tokens(state)?);
        }
        let user = self.user_tokens(state, w0)?;
        let noise = state.draws.normal(tm * p * d)?;
        let mut x = Array4::from_shape_vec((1, tm, p, d), noise).expect("sized");
        if let Some(previous) = &state.window {
            x.slice_mut(s![0, ..tc, 1, ..])
                .assign(&previous.slice(s![0, st.., 1, ..]));
        }
        let given = tc.saturating_sub(w0); // the partner's opening tokens in this window
        if given > 0 {
            let opening = state.opening_tokens.as_ref().expect("set at chunk 0");
            x.slice_mut(s![0, ..given, 1, ..])
                .assign(&opening.slice(s![w0..w0 + given, ..]));
        }
        let mut gt = x.clone();
        let own = lat + TOKEN_TRANSFORMS;
        gt.slice_mut(s![0, .., 0, ..own])
            .assign(&user.slice(s![.., ..own]));
        let slots = self.user_partner_slots(&x, tc);
        gt.slice_mut(s![0, .., 0, own..]).assign(&slots);
        let mut ctx = Array3::from_elem((1, tm, p), false);
        ctx.slice_mut(s![.., .., 0]).fill(true);
        ctx.slice_mut(s![.., ..tc, 1..]).fill(true);
        let mut inject = Array3::from_elem((1, tm, p), false);
        inject.slice_mut(s![.., .., 0]).fill(true);
        inject.slice_mut(s![.., ..given, 1..]).fill(true);
        let opening_frames = self.settings.opening.as_ref().expect("checked");
        let mut betas = Array2::zeros((p, BETAS));
        betas.row_mut(0).assign(&ndarray::ArrayView1::from(
            &motion::normalise_betas(nets, &state.user_betas)[..],
        ));
        betas.row_mut(1).assign(&ndarray::ArrayView1::from(
            &motion::normalise_betas(nets, &opening_frames[FRAME_BETAS])[..],
        ));
        Ok(ChunkInput {
            x,
            gt,
            inject,
            ctx,
            betas,
        })
    }

    /// The user's partner-relative transforms, normalised `[Tm, 36]`: the partner's own slot
    /// inverted over its `context` tokens, the last such frame held after them.
    fn user_partner_slots(&self, window: &Array4<f32>, context: usize) -> Array2<f32> {
        let st = &self.nets.spec.statistics;
        let (mean, std) = (&st.mean[stats::PARTNER], &st.std[stats::PARTNER]);
        let tm = window.dim().1;
        let at = self.nets.spec.model.vq.d_latent + TOKEN_TRANSFORMS;
        let mut out = Array2::<f32>::zeros((tm, TOKEN_TRANSFORMS));
        let mut nine = [0f32; TRANSFORM];
        let mut last = [0f32; TRANSFORM];
        for tau in 0..tm {
            for fr in 0..FRAMES_PER_TOKEN {
                if tau < context {
                    let o = at + fr * TRANSFORM;
                    let theirs = window.slice(s![0, tau, 1, o..o + TRANSFORM]);
                    for i in 0..TRANSFORM {
                        nine[i] = theirs[i] * std[i] + mean[i];
                    }
                    to_9d(&inverse(&from_9d(&nine)), &mut last);
                }
                for i in 0..TRANSFORM {
                    out[[tau, fr * TRANSFORM + i]] = (last[i] - mean[i]) / std[i];
                }
            }
        }
        out
    }

    /// Decodes the chunk's tokens to send with the sent history and `ahead` as context; returns
    /// their frames `[4n, 145]`, roots in the world.
    fn emit(
        &self,
        state: &mut LiveState,
        new: ndarray::ArrayView2<f32>,
        ahead: ndarray::ArrayView2<f32>,
        betas: ndarray::ArrayView1<f32>,
    ) -> Result<Array2<f32>> {
        let (_, tc, _) = self.geometry();
        let d = new.ncols();
        let history: Vec<f32> = state.sent.iter().flatten().copied().collect();
        let history = Array2::from_shape_vec((state.sent.len(), d), history).expect("sized");
        let seq = concatenate![Axis(0), history, new, ahead];
        let n_seq = seq.nrows();
        let x = seq.into_shape_with_order((1, n_seq, 1, d)).expect("sized");
        let decoded = motion::decode(&self.nets, x.view(), betas.insert_axis(Axis(0)))?;
        let f = FRAMES_PER_TOKEN;
        let (a, b) = (f * state.sent.len(), f * (state.sent.len() + new.nrows()));
        let part = Decoded {
            body: decoded.body.slice(s![.., a..b, .., ..]).to_owned(),
            canonical_root: decoded
                .canonical_root
                .slice(s![.., a..b, .., ..])
                .to_owned(),
            tm1_t: decoded.tm1_t.slice(s![.., a..b, .., ..]).to_owned(),
        };
        let opening = self.settings.opening.as_ref().expect("checked");
        let given = f * tc;
        let opening_root = |frame: usize| from_9d(&opening[frame * FRAME_DIM..][FRAME_ROOT]);
        let nine = |v: &Array4<f32>, i: usize| {
            from_9d(v.slice(s![0, i, 0, ..]).as_slice().expect("contiguous"))
        };
        let mut roots = Vec::with_capacity(b - a);
        for i in 0..b - a {
            let frame = state.frames_out as usize + i;
            if frame < given {
                roots.push(opening_root(frame));
                continue;
            }
            let world = state
                .world
                .unwrap_or_else(|| canonical_frame(&opening_root(given - 1)));
            let world = compose(&world, &nine(&part.tm1_t, i));
            state.world = Some(world);
            roots.push(compose(&world, &nine(&part.canonical_root, i)));
        }
        let raw_betas = ArrayView2::from_shape((1, BETAS), &opening[FRAME_BETAS]).expect("sized");
        let frames = motion::frames_out(&part, &roots, raw_betas);
        state.frames_out += (b - a) as u64;
        state.tokens_out += new.nrows() as u64;
        for row in new.outer_iter() {
            state.sent.push_back(row.to_vec());
        }
        while state.sent.len() > DECODER_CONTEXT_TOKENS {
            state.sent.pop_front();
        }
        Ok(frames
            .into_shape_with_order((b - a, FRAME_DIM))
            .expect("one sample, one person"))
    }

    /// Drops user frames no later chunk reads.
    fn trim(&self, state: &mut LiveState) {
        let (_, _, st) = self.geometry();
        let next_w0 = state.chunks as usize * st;
        let keep = (FRAMES_PER_TOKEN * next_w0.saturating_sub(ENCODER_CONTEXT_TOKENS))
            .saturating_sub(1) as u64;
        if keep > state.user_base {
            let drop = (keep - state.user_base) as usize * FRAME_DIM;
            state.user.drain(..drop);
            state.user_base = keep;
        }
    }
}

/// The longest configuration (JSON) a snapshot may carry.
const MAX_CONFIG_BYTES: usize = 1 << 16;

impl LivePartner {
    /// The stream's snapshot (`Session::snapshot`): its settings (the configuration as JSON, the
    /// seed, the emission, the opening frames) and everything its chunks carry forward.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) -> Result<()> {
        let config = serde_json::to_string(&self.settings.sampling)
            .map_err(|e| Error::InvalidInput(format!("snapshot: the configuration: {e}")))?;
        w.str(&config)
            .u64(self.settings.seed)
            .bool(self.settings.early);
        w.bool(self.settings.opening.is_some());
        if let Some(opening) = &self.settings.opening {
            w.f32s(opening);
        }
        let st = &self.state;
        w.u64(st.received).u64(st.user_base).f32s(&st.user);
        w.f32s(&st.user_betas).u64(st.chunks);
        w.bool(st.window.is_some());
        if let Some(window) = &st.window {
            w.f32s(&window.iter().copied().collect::<Vec<_>>());
        }
        w.bool(st.opening_tokens.is_some());
        if let Some(tokens) = &st.opening_tokens {
            w.f32s(&tokens.iter().copied().collect::<Vec<_>>());
        }
        w.u64(st.sent.len() as u64);
        for token in &st.sent {
            w.f32s(token);
        }
        w.u64(st.frames_out).u64(st.tokens_out);
        w.bool(st.world.is_some());
        if let Some(world) = &st.world {
            w.f32s(world.as_flattened());
        }
        save_draws(w, &st.draws)
    }

    /// The stream a snapshot's payload holds, over `nets` (the model it was checked to come
    /// from): the settings checked as a new stream's, the state's counts against each other.
    pub(crate) fn restore(nets: Arc<Networks>, r: &mut SnapshotReader) -> Result<Self> {
        let config = r.str("the configuration", MAX_CONFIG_BYTES)?;
        let sampling: SamplingSpec = serde_json::from_str(&config)
            .map_err(|e| snapshot::bad(format!("the configuration: {e}")))?;
        let seed = r.u64("the seed")?;
        let early = r.bool("the emission")?;
        let opening = if r.bool("whether opening frames are set")? {
            Some(r.f32s(
                "the opening frames",
                sampling.context_len.saturating_mul(FRAME_DIM),
            )?)
        } else {
            None
        };
        let settings = LiveSettings {
            sampling,
            seed,
            early,
            opening,
        };
        let mut live = LivePartner::new(nets, settings)?;
        let (tm, tc, st) = live.geometry();
        let d = live.token_dim();
        let received = r.u64("the frames received")?;
        let chunks_due = live.chunks_for(received);
        let user_base = r.u64("the first user frame held")?;
        let keep = (FRAMES_PER_TOKEN as u64
            * (chunks_due * st as u64).saturating_sub(ENCODER_CONTEXT_TOKENS as u64))
        .saturating_sub(1);
        if user_base != keep || user_base > received {
            return Err(snapshot::bad(format!(
                "user frames held from {user_base}, after {received} frames received"
            )));
        }
        if received > 0 && live.settings.opening.is_none() {
            return Err(snapshot::bad(
                "user frames without the partner's opening frames",
            ));
        }
        let held = ((received - user_base) as usize)
            .checked_mul(FRAME_DIM)
            .ok_or_else(|| snapshot::bad("user frames held"))?;
        let user = r.f32s_exact("the user frames held", held)?;
        let user_betas = r.f32s_exact(
            "the user's betas",
            if received == 0 { 0 } else { FRAME_BETAS.len() },
        )?;
        let chunks = r.u64("the chunks run")?;
        if chunks != chunks_due {
            return Err(snapshot::bad(format!(
                "{chunks} chunks run after {received} frames received (not {chunks_due})"
            )));
        }
        let ran = chunks > 0;
        let window = match (r.bool("whether a window is held")?, ran) {
            (true, true) => Some(
                Array4::from_shape_vec((1, tm, 2, d), r.f32s_exact("the last window", tm * 2 * d)?)
                    .map_err(|e| snapshot::bad(format!("the last window: {e}")))?,
            ),
            (false, false) => None,
            _ => return Err(snapshot::bad("a window that disagrees with the chunks run")),
        };
        let opening_tokens = match (r.bool("whether opening tokens are held")?, ran) {
            (true, true) => Some(
                Array2::from_shape_vec((tc, d), r.f32s_exact("the opening tokens", tc * d)?)
                    .map_err(|e| snapshot::bad(format!("the opening tokens: {e}")))?,
            ),
            (false, false) => None,
            _ => {
                return Err(snapshot::bad(
                    "opening tokens that disagree with the chunks run",
                ))
            }
        };
        let n = r.count("the tokens sent held", DECODER_CONTEXT_TOKENS)?;
        let sent = (0..n)
            .map(|_| r.f32s_exact("a token sent", d))
            .collect::<Result<VecDeque<_>>>()?;
        let frames_out = r.u64("the frames sent")?;
        let tokens_out = r.u64("the tokens sent")?;
        if frames_out != live.frames_after(chunks)
            || tokens_out * FRAMES_PER_TOKEN as u64 != frames_out
            || n as u64 != tokens_out.min(DECODER_CONTEXT_TOKENS as u64)
        {
            return Err(snapshot::bad(format!(
                "{frames_out} frames and {tokens_out} tokens sent after {chunks} chunks"
            )));
        }
        let world = if r.bool("whether the partner is placed")? {
            let v = r.f32s_exact("the partner's frame", 16)?;
            let mut m: Mat4 = [[0.0; 4]; 4];
            for (i, x) in v.into_iter().enumerate() {
                m[i / 4][i % 4] = x;
            }
            Some(m)
        } else {
            None
        };
        let draws = load_draws(r, seed)?;
        live.state = LiveState {
            user,
            user_base,
            received,
            user_betas,
            chunks,
            window,
            opening_tokens,
            sent,
            frames_out,
            tokens_out,
            world,
            draws,
        };
        Ok(live)
    }
}

/// Writes a live stream's draws: seeded, with queued normals in front or not.
fn save_draws(w: &mut SnapshotWriter, draws: &Draws) -> Result<()> {
    match draws {
        Draws::Seeded { seed, count } => {
            w.bool(false).u64(*seed).u64(*count);
        }
        Draws::Queued { queue, used, then } => {
            let Draws::Seeded { seed, count } = **then else {
                return Err(Error::Unsupported(
                    "snapshot: draws other than seeded behind a queue".into(),
                ));
            };
            w.bool(true).f32s(&queue[*used..]).u64(seed).u64(count);
        }
        _ => {
            return Err(Error::Unsupported(
                "snapshot: a live stream's draws are seeded or queued".into(),
            ))
        }
    }
    Ok(())
}

/// The draws [`save_draws`] wrote; their seed must be the stream's.
fn load_draws(r: &mut SnapshotReader, stream_seed: u64) -> Result<Draws> {
    let queued = r.bool("whether normals are queued")?;
    let queue = if queued {
        Some(r.f32s(
            "the queued normals",
            crate::shared::limits::LIMITS.max_tensor_elements as usize,
        )?)
    } else {
        None
    };
    let (seed, count) = (r.u64("the draws' seed")?, r.u64("the draws made")?);
    if seed != stream_seed {
        return Err(snapshot::bad("draws of another seed than the stream's"));
    }
    let seeded = Draws::Seeded { seed, count };
    Ok(match queue {
        Some(queue) => Draws::Queued {
            queue,
            used: 0,
            then: Box::new(seeded),
        },
        None => seeded,
    })
}

/// Checks settings against the model: a two-person `motion_control_live` configuration the
/// manifest's rules accept, one sample, and opening frames of the right size when given.
fn check_settings(nets: &Networks, settings: &LiveSettings) -> Result<()> {
    let cfg = &settings.sampling;
    let m = &nets.spec.model;
    check_persons(nets)?;
    if cfg.task != Task::MotionControlLive {
        return Err(Error::InvalidOption(format!(
            "a live partner stream runs a motion_control_live configuration, not {}",
            cfg.task.name()
        )));
    }
    if cfg.samples != 1 {
        return Err(Error::InvalidOption(format!(
            "a live partner stream generates one sample, not {}",
            cfg.samples
        )));
    }
    nets.spec
        .validate_sampling(cfg)
        .map_err(Error::InvalidOption)?;
    let tc = cfg.context_len / FRAMES_PER_TOKEN;
    if tc == 0 || tc >= m.window {
        return Err(Error::InvalidOption(format!(
            "context of {tc} tokens: a live partner window of {} tokens needs 1 to {}",
            m.window,
            m.window - 1
        )));
    }
    if let Some(opening) = &settings.opening {
        let want = cfg.context_len * FRAME_DIM;
        if opening.len() != want {
            return Err(Error::InvalidInput(format!(
                "the partner's opening frames hold {} floats; this configuration needs {} \
                 frames of {FRAME_DIM} ({want} floats)",
                opening.len(),
                cfg.context_len
            )));
        }
        check_input("the partner's opening frames", opening)?;
    }
    Ok(())
}

/// A live partner stream is one user and one partner.
pub(crate) fn check_persons(nets: &Networks) -> Result<()> {
    let persons = nets.spec.model.persons;
    if persons != 2 {
        return Err(Error::InvalidInput(format!(
            "a live partner stream takes a two-person model; bundle `{}` has {persons} people",
            nets.io.name
        )));
    }
    Ok(())
}

/// Advances streams of one model: `frames[i]` (the user's, row-major) goes to `sessions[i]`,
/// and entry `i` of the result holds the partner frames that became ready for it. Streams that
/// need a chunk in the same round run it together when their configurations agree. Fails,
/// changing no stream, on bad input or when stream `i` would return more than `max_frames[i]`
/// frames (missing: unbounded). With `indexed`, messages name the stream by its index.
pub(crate) fn advance(
    sessions: &mut [&mut LivePartner],
    frames: &[&[f32]],
    finish: Finish<'_>,
    indexed: bool,
) -> Result<Vec<StepOutput>> {
    let whose = |i: usize, e: Error| match (e, indexed) {
        (Error::InvalidInput(m), true) => Error::InvalidInput(format!("session {i}: {m}")),
        (e, _) => e,
    };
    for (i, (session, chunk)) in sessions.iter().zip(frames).enumerate() {
        check_frames("user frames", chunk, FRAME_DIM).map_err(|e| whose(i, e))?;
        if session.settings.opening.is_none() && !chunk.is_empty() {
            return Err(whose(
                i,
                Error::InvalidInput(
                    "a live partner stream needs the partner's opening frames before the user's \
                     (SessionOptions::partner_opening, troupe_magnet_session_set_partner_opening)"
                        .into(),
                ),
            ));
        }
    }
    // All work on copies, committed at the end.
    let mut states: Vec<LiveState> = sessions.iter().map(|s| s.state.clone()).collect();
    let mut outputs: Vec<Vec<(Array2<f32>, Vec<SentToken>)>> = vec![Vec::new(); sessions.len()];
    for (state, chunk) in states.iter_mut().zip(frames) {
        if state.received == 0 && !chunk.is_empty() {
            state.user_betas = chunk[FRAME_BETAS].to_vec();
        }
        state.user.extend_from_slice(chunk);
        state.received += (chunk.len() / FRAME_DIM) as u64;
    }
    loop {
        let due: Vec<usize> = (0..sessions.len())
            .filter(|&i| sessions[i].chunks_for(states[i].received) > states[i].chunks)
            .collect();
        if due.is_empty() {
            break;
        }
        // Streams whose chunk runs the same matrices and smoothing run together.
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for &i in &due {
            let key = |j: usize| {
                let s = &sessions[j].settings.sampling;
                (s, (states[j].chunks as usize) >= s.smoothing_start)
            };
            match groups.iter_mut().find(|g| {
                Arc::ptr_eq(&sessions[g[0]].nets, &sessions[i].nets) && key(g[0]) == key(i)
            }) {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        for group in groups {
            run_chunk(sessions, &mut states, &mut outputs, &group).map_err(|e| {
                if group.len() == 1 {
                    whose(group[0], e)
                } else {
                    e
                }
            })?;
        }
    }
    let mut result = outputs
        .into_iter()
        .map(|parts| {
            let views: Vec<_> = parts.iter().map(|(f, _)| f.view()).collect();
            let frames = if views.is_empty() {
                Array2::zeros((0, FRAME_DIM))
            } else {
                concatenate(Axis(0), &views).expect("frames of one width")
            };
            let tokens = parts.into_iter().flat_map(|(_, t)| t).collect();
            StepOutput::from(LiveOutput { frames, tokens })
        })
        .collect::<Vec<_>>();
    for (i, output) in result.iter_mut().enumerate() {
        finish(i, output)?;
    }
    for (session, mut state) in sessions.iter_mut().zip(states) {
        session.trim(&mut state);
        session.state = state;
    }
    Ok(result)
}

/// Runs the next chunk of the streams in `group` (same model and configuration) as one batch.
fn run_chunk(
    sessions: &[&mut LivePartner],
    states: &mut [LiveState],
    outputs: &mut [Vec<(Array2<f32>, Vec<SentToken>)>],
    group: &[usize],
) -> Result<()> {
    let lead = &sessions[group[0]];
    let nets = &*lead.nets;
    let (_, tc, st) = lead.geometry();
    let mut inputs = Vec::with_capacity(group.len());
    for &i in group {
        inputs.push(sessions[i].prepare(&mut states[i])?);
    }
    let stack4 = |f: &dyn Fn(&ChunkInput) -> &Array4<f32>| {
        let views: Vec<_> = inputs.iter().map(|c| f(c).view()).collect();
        concatenate(Axis(0), &views).expect("one window shape")
    };
    let stack3 = |f: &dyn Fn(&ChunkInput) -> &Array3<bool>| {
        let views: Vec<_> = inputs.iter().map(|c| f(c).view()).collect();
        concatenate(Axis(0), &views).expect("one window shape")
    };
    let mut x = stack4(&|c| &c.x);
    let gt = stack4(&|c| &c.gt);
    let inject = stack3(&|c| &c.inject);
    let mut ctx = stack3(&|c| &c.ctx);
    let betas_views: Vec<_> = inputs
        .iter()
        .map(|c| c.betas.view().insert_axis(Axis(0)))
        .collect();
    let betas = concatenate(Axis(0), &betas_views).expect("[1, P, 10] each");
    let draws = group
        .iter()
        .map(|&i| std::mem::replace(&mut states[i].draws, Draws::seeded(0)))
        .collect();
    let mut cfg = lead.settings.sampling.clone();
    cfg.samples = group.len();
    let spec = cfg.guidance.clone();
    let chunk = states[group[0]].chunks as usize;
    let mut run = Run {
        nets,
        schedule: &nets.schedule,
        draws: Draws::PerRun(draws),
        guidance: Guidance {
            nets,
            spec: &spec,
            schedule: &nets.schedule,
            betas,
            total: 0,
            counter: 0,
            runs: group.len(),
        },
        window: nets.spec.model.window,
        persons: 2,
        latent: nets.spec.model.vq.d_latent,
        cfg,
    };
    let m = live_matrix(&run, Task::MotionControlLive);
    run.start(m.rows() - 1);
    let done = rolling_chunk(
        &mut run,
        &mut x,
        0,
        &m,
        gt.view(),
        inject.view(),
        &mut ctx,
        chunk,
    );
    let Draws::PerRun(draws) = run.draws else {
        unreachable!("built as PerRun above")
    };
    for (&i, d) in group.iter().zip(draws) {
        states[i].draws = d;
    }
    done?;
    let early = lead.settings.early;
    for (row, &i) in group.iter().enumerate() {
        let session = &sessions[i];
        let state = &mut states[i];
        let window = x.slice(s![row..row + 1, .., .., ..]).to_owned();
        let mut sent = window.slice(s![0, .., 1, ..]).to_owned();
        for tau in 0..sent.nrows() {
            if inject[[row, tau, 1]] {
                sent.row_mut(tau).assign(&gt.slice(s![row, tau, 1, ..]));
            }
        }
        let c = state.chunks as usize;
        let tm = window.dim().1;
        let (first, last) = match early {
            true => (if c == 0 { 0 } else { tc }, tm),
            false => (0, st),
        };
        let betas = inputs[row].betas.row(1).to_owned();
        let tokens = (first..last)
            .map(|tau| SentToken {
                index: state.tokens_out + (tau - first) as u64,
                user: gt.slice(s![row, tau, 0, ..]).to_vec(),
                partner: sent.row(tau).to_vec(),
            })
            .collect();
        let frames = session.emit(
            state,
            sent.slice(s![first..last, ..]),
            sent.slice(s![last.., ..]),
            betas.view(),
        )?;
        outputs[i].push((frames, tokens));
        state.window = Some(window);
        state.chunks += 1;
    }
    Ok(())
}

impl LivePartner {
    /// Sets the partner's opening frames (`[context frames, 145]`, row-major), kept across
    /// resets. Only before the first frame or after a reset.
    pub fn set_partner_opening(&mut self, frames: &[f32]) -> Result<()> {
        if self.frames_received() > 0 {
            return Err(Error::InvalidInput(
                "the partner's opening frames are set before the first step or after a reset"
                    .into(),
            ));
        }
        let mut settings = self.settings.clone();
        settings.opening = Some(frames.to_vec());
        self.configure(settings)
    }

    /// [`LivePartner::set_partner_opening`], under its 0.1 name.
    #[deprecated(
        since = "0.2.0",
        note = "use set_partner_opening, the name every binding uses"
    )]
    pub fn set_opening(&mut self, frames: &[f32]) -> Result<()> {
        self.set_partner_opening(frames)
    }

    /// Runs the sampling configuration `config` (a released name or JSON). Only before the
    /// first frame or after a reset; opening frames set before must match its context.
    pub fn set_live_config(&mut self, config: &str) -> Result<()> {
        if self.frames_received() > 0 {
            return Err(Error::InvalidInput(
                "the live configuration is set before the first step or after a reset".into(),
            ));
        }
        self.set_config(config)
    }

    /// Emit each chunk's frames as soon as they are generated (see
    /// `PartnerOptions::early_emission`). Only before the first frame or after a reset.
    pub fn set_early_emission(&mut self, early: bool) -> Result<()> {
        if self.frames_received() > 0 {
            return Err(Error::InvalidInput(
                "early emission is set before the first step or after a reset".into(),
            ));
        }
        let mut settings = self.settings.clone();
        settings.early = early;
        self.configure(settings)
    }

    /// The sampling configuration in force.
    pub fn sampling(&self) -> &SamplingSpec {
        &self.settings.sampling
    }
}

impl Stream for LivePartner {
    fn family(&self) -> &'static str {
        "magnet"
    }
    fn frame_dim(&self) -> usize {
        FRAME_DIM
    }
    fn latent_dim(&self) -> usize {
        self.token_dim()
    }
    fn io(&self) -> &BundleIo {
        &self.nets.io
    }
    fn capabilities(&self) -> Capabilities {
        Capabilities::of(&[Capability::QueuedNormals])
    }
    fn save(&self, w: &mut SnapshotWriter) -> Result<()> {
        LivePartner::save(self, w)
    }
    fn step(&mut self, frames: &[f32], finish: Finish<'_>) -> Result<StepOutput> {
        let mut out = advance(&mut [self], &[frames], finish, false)?;
        Ok(out.pop().expect("one stream, one output"))
    }
    fn step_together(&self) -> StepTogether {
        |streams, frames, finish| {
            let mut partners = downcast_all::<LivePartner>(streams);
            advance(&mut partners, frames, finish, true)
        }
    }
    fn same_model(&self, other: &dyn Stream) -> bool {
        other
            .as_any()
            .downcast_ref::<LivePartner>()
            .is_some_and(|o| Arc::ptr_eq(&self.nets, &o.nets))
    }
    /// Back to a fresh stream with the same settings.
    fn reset(&mut self) {
        self.state = LiveState::new(self.settings.seed);
    }
    /// User frames after frame `t` that arrive before the partner's frame `t` is out, at worst
    /// (compute time not counted).
    fn latency_frames(&self) -> usize {
        let (tm, _, st) = self.geometry();
        FRAMES_PER_TOKEN * if self.settings.early { st } else { tm } - 1
    }
    /// Sets the seed; applies to chunks not yet run (the draws continue from their count).
    fn set_seed(&mut self, seed: u64) {
        self.settings.seed = seed;
        self.state.draws.reseed(seed);
    }
    fn queue_normals(&mut self, normals: &[f32]) -> Result<()> {
        self.state.draws.enqueue(normals)
    }
    fn set_steps(&mut self, steps: u32) -> Result<()> {
        let mut settings = self.settings.clone();
        settings.sampling.steps = steps as usize;
        self.configure(settings)
    }
    /// Exactly how many partner frames a step with `n` more user frames returns.
    fn frames_ready_after(&self, n: usize) -> usize {
        let total = self.state.received.saturating_add(n as u64);
        (self.frames_after(self.chunks_for(total)) - self.state.frames_out) as usize
    }
    fn frames_received(&self) -> u64 {
        self.state.received
    }
    fn frames_emitted(&self) -> u64 {
        self.state.frames_out
    }
    fn tokens_generated(&self) -> u64 {
        self.state.tokens_out
    }
    /// Bytes this stream holds (the model's weights, shared, not counted).
    fn memory_bytes(&self) -> usize {
        let st = &self.state;
        let floats = st.user.capacity()
            + st.sent.iter().map(Vec::capacity).sum::<usize>()
            + st.window.as_ref().map_or(0, Array4::len)
            + st.opening_tokens.as_ref().map_or(0, Array2::len)
            + self.settings.opening.as_ref().map_or(0, Vec::capacity);
        std::mem::size_of::<Self>() + floats * std::mem::size_of::<f32>()
    }
    /// Partner tokens held as the next window's context.
    fn context_len(&self) -> usize {
        self.state.window.as_ref().map_or(0, |_| self.geometry().1)
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// A live step's output as a neutral one: the partner's tokens as traces (`actor_latent` the
/// user's token at the same place, `reactor_latent` the partner's, no context vector).
impl From<LiveOutput> for StepOutput {
    fn from(out: LiveOutput) -> Self {
        StepOutput {
            frames: out.frames,
            tokens: out
                .tokens
                .into_iter()
                .map(|t| TokenTrace {
                    index: t.index,
                    actor_latent: t.user,
                    reactor_latent: t.partner,
                    context: Vec::new(),
                })
                .collect(),
        }
    }
}

impl From<LivePartner> for Session {
    fn from(partner: LivePartner) -> Self {
        Self::new(partner)
    }
}
