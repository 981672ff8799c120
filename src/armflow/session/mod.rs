//! [`Reactor`]: one actor/reactor stream. Frames in, reactor frames out, one token at a time.
//!
//! Per token `j` (frames `4j .. 4j+3` with 4 frames per token):
//! 1. **Actor token**: the VAE encoder runs on the window of actor frames
//!    `[max(0, 4j - context_frames), 4j + 4 + lookahead_frames)` and its token for `j` is
//!    `a_j = (mean + sqrt(exp(logvar)) * xi_j) * scale` (or `mean * scale`).
//! 2. **Context**: the context encoder appends `<sos>` (for `j = 0`) or the previous pair
//!    `(a_{j-1} || b_{j-1})` at position `j` to its key/value cache and gives `c_j`.
//! 3. **MeanFlow**: from `z = eps_j`, for `k = 0..steps`:
//!    `z <- z - (tau_k - tau_{k+1}) * u(z, r = tau_{k+1}, t = tau_k)` with `tau` =
//!    [`meanflow_grid`](crate::meanflow_grid); one step is `b_j = eps_j - u(eps_j, 0, 1)`. With
//!    CFG scale `s != 1`, `u = u_null + s * (u_cond - u_null)` where the null branch zeroes actor
//!    token and context.
//! 4. **Frames**: once token `j + lookahead_tokens` exists, the decoder runs on the reactor
//!    tokens `[max(0, j - context_tokens), j + 1 + lookahead_tokens)` divided by `scale`, and the
//!    frames of token `j` are returned.
//!
//! A step either completes or leaves the session exactly as it was: all work happens on a copy
//! of the stream state, committed at the end.

use std::collections::VecDeque;
use std::sync::Arc;

use crate::armflow::kv_cache::KvCache;
use crate::armflow::meanflow::meanflow_grid;
use crate::armflow::networks::{Conditioning, Networks, VaeState};
use crate::armflow::spec::{ActorLatent, ArmFlowSpec};
use crate::family::stream::{
    downcast_all, Capabilities, Capability, Finish, StepOutput, StepTogether, Stream, TokenTrace,
};
use crate::shared::bundle_io::BundleIo;
use crate::shared::checks::{check_frames, check_input};
use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, check_cfg, check_steps, LIMITS};
use crate::shared::noise::{fill_normals, STREAM_ACTOR_POSTERIOR, STREAM_REACTOR_NOISE};
use crate::shared::snapshot::SnapshotWriter;
use crate::shared::text::prompt::no_prompts;

mod feedback;
mod lane;
mod lanes;
mod recentre;
mod snapshot;
use lane::Lane;
use recentre::History;
pub use recentre::{Recentring, HISTORY_TOKENS};

/// Options of a session. Fields left `None` take the bundle's defaults (`sampler` and
/// `context` sections of the manifest).
#[derive(Debug, Clone, Default)]
pub struct ReactorOptions {
    /// Seed of the portable noise generator ([`crate::noise`]).
    pub seed: u64,
    /// MeanFlow steps per token (>= 1).
    pub steps: Option<u32>,
    /// Classifier-free guidance scale; guides above 1 (two network rows per step), as the
    /// official sampler does; 1 and below run the conditional velocity alone.
    pub cfg_scale: Option<f32>,
    /// Conditioning vector of `condition_dim` floats; `None` is the bundle's null condition.
    pub condition: Option<Vec<f32>>,
    /// A text prompt to condition on instead of `condition` (bundles that take prompts, see
    /// [`crate::Model::encode_prompt`]); giving both is an error.
    pub prompt: Option<String>,
    /// Tokens kept in the context cache, `<sos>` included (>= 2). See `armflow/kv_cache.rs`.
    pub context_capacity: Option<usize>,
    /// Posterior sample (default) or mean for the actor's latent tokens.
    pub actor_latent: Option<ActorLatent>,
    /// Run the VAE over windows even when the bundle has per-token step graphs. Slower; the two
    /// agree to float rounding. For comparisons and for debugging a bundle.
    pub vae_windows: bool,
    /// Move the networks' frame under the actor when it wanders from where the stream began
    /// (`recentre.rs`); off when `None`.
    pub recentring: Option<Recentring>,
}

/// The noise of one token, for reproducing a run exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct TokenNoise {
    /// Standard normals for the actor's posterior sample (`latent_dim` floats).
    pub actor: Vec<f32>,
    /// The reactor's starting noise `eps` (`latent_dim` floats).
    pub reactor: Vec<f32>,
}

/// Settings in force; changed by the setters, kept by `reset()`.
#[derive(Debug, Clone)]
struct Settings {
    seed: u64,
    steps: u32,
    cfg_scale: f32,
    condition: Option<Vec<f32>>,
    capacity: usize,
    actor_latent: ActorLatent,
    recentring: Option<Recentring>,
}

/// Everything a stream accumulates; `reset()` returns it to `StreamState::new`.
#[derive(Debug, Clone)]
struct StreamState {
    /// Actor frames received so far.
    frames_received: u64,
    /// Actor frames from index `actor_base` on, row-major.
    actor_frames: Vec<f32>,
    actor_base: u64,
    /// Tokens generated so far.
    tokens: u64,
    cache: KvCache,
    /// `(a_{j-1} || b_{j-1})`, fed to the context encoder with token j; empty before token 0.
    last_pair: Vec<f32>,
    /// Reactor latents (scaled) from token `reactor_base` on.
    reactor_latents: VecDeque<Vec<f32>>,
    reactor_base: u64,
    /// Reactor frames returned so far.
    frames_emitted: u64,
    /// Noise queued by `queue_noise`, used before the seeded generator.
    injected: VecDeque<TokenNoise>,
    /// The VAE steps' convolution state; `None` when the VAE runs over windows.
    vae: Option<VaeState>,
    /// Both people's last tokens of motion, in the stream's frame, while recentring is on.
    history: Option<History>,
    /// Where the networks' frame is centred on the stream's floor: they see positions less
    /// this (`recentre.rs`; zero unless recentring moved it).
    centre: [f64; 2],
    /// In a feedback bundle, the reactor's placement at the last frame decoded
    /// (`feedback.rs`): what the next token's condition carries. Zeros before any.
    feedback: [f32; feedback::DIM],
}

/// One actor/reactor stream over a loaded ARMFlow model (made by `Armflow::reactor`, or boxed
/// in a [`crate::Session`] by `Model::session`). `Send`, not `Sync`: use it from one thread at
/// a time.
#[derive(Debug)]
pub struct Reactor {
    /// The model's networks, shared with it and with its other sessions.
    nets: Arc<Networks>,
    settings: Settings,
    conditioning: Conditioning,
    grid: Vec<f32>,
    state: StreamState,
    /// The VAE steps' zero state, when the session uses step graphs rather than windows.
    vae_start: Option<VaeState>,
}

impl Reactor {
    /// A fresh stream over `nets` (the family was checked by [`crate::Model::session`]).
    pub(crate) fn new(nets: Arc<Networks>, options: ReactorOptions) -> Result<Self> {
        let m = &nets.spec;
        let settings = Settings {
            seed: options.seed,
            steps: options.steps.unwrap_or(m.sampler.steps),
            cfg_scale: options.cfg_scale.unwrap_or(m.sampler.cfg_scale),
            capacity: options
                .context_capacity
                .unwrap_or(m.context.capacity_tokens),
            actor_latent: options.actor_latent.unwrap_or(m.sampler.actor_latent),
            recentring: options.recentring,
            condition: match (options.condition, &options.prompt) {
                (Some(_), Some(_)) => {
                    return Err(Error::InvalidOption(
                        "a session takes a condition or a prompt, not both".into(),
                    ))
                }
                (None, Some(prompt)) => Some(encode_prompt(&nets, prompt)?),
                (condition, None) => condition,
            },
        };
        check_steps("sampler steps", settings.steps)?;
        check_cfg(settings.cfg_scale)?;
        if settings.capacity < 2 {
            return Err(Error::InvalidOption(format!(
                "context capacity {} is below 2 (<sos> and the newest token)",
                settings.capacity
            )));
        }
        at_most(
            "context capacity",
            settings.capacity as u64,
            LIMITS.max_context_capacity,
            true,
        )?;
        let vae_start = if options.vae_windows {
            None
        } else {
            nets.vae_state()
        };
        let mut reactor = Self {
            conditioning: nets.conditioning(settings.condition.as_deref())?,
            grid: meanflow_grid(settings.steps),
            state: StreamState::new(m, settings.capacity, vae_start.clone()),
            vae_start,
            settings,
            nets,
        };
        if let Some(recentring) = options.recentring {
            reactor.set_recentring(Some(recentring))?;
        }
        Ok(reactor)
    }

    /// The bundle's `armflow` fields.
    fn spec(&self) -> &ArmFlowSpec {
        &self.nets.spec
    }

    // What the token loop and recentring (`lanes.rs`, `lane.rs`, `recentre.rs`, `feedback.rs`)
    // read of the session, so that they never reach into its fields.

    /// MeanFlow steps per token in force.
    fn steps(&self) -> u32 {
        self.settings.steps
    }

    /// The CFG scale in force.
    fn cfg_scale(&self) -> f32 {
        self.settings.cfg_scale
    }

    /// MeanFlow's time grid for the steps in force.
    fn grid(&self) -> &[f32] {
        &self.grid
    }

    /// Posterior sample or mean for the actor's tokens.
    fn actor_latent(&self) -> ActorLatent {
        self.settings.actor_latent
    }

    /// The context cache's capacity in tokens.
    fn capacity(&self) -> usize {
        self.settings.capacity
    }

    /// The condition's modulation and start token, as the networks computed them.
    fn conditioning(&self) -> &Conditioning {
        &self.conditioning
    }

    /// The state a step starts from (the lanes work on a copy).
    fn state(&self) -> &StreamState {
        &self.state
    }

    /// Whether this session runs the bundle's per-token VAE steps (O(1) per token) rather than
    /// VAE windows: true when the bundle has them and `vae_windows` was not asked for.
    pub fn uses_vae_steps(&self) -> bool {
        self.vae_start.is_some()
    }

    /// Floats per motion frame, in and out.
    pub(crate) fn frame_dim(&self) -> usize {
        self.nets.frame_dim()
    }

    /// Floats per latent token (the length of each [`TokenNoise`] vector).
    pub(crate) fn latent_dim(&self) -> usize {
        self.nets.latent_dim()
    }

    /// Floats in the conditioning vector [`Reactor::set_condition`] takes.
    pub(crate) fn condition_dim(&self) -> usize {
        self.nets.io.condition.dim
    }

    /// Feeds row-major actor frames (`n * frame_dim` floats, n may be 0) and returns the reactor
    /// frames that became ready, `finish` run on them before the step is committed (the
    /// session's motion stages). On error the stream is unchanged.
    fn step_finished(&mut self, actor: &[f32], finish: Finish<'_>) -> Result<StepOutput> {
        let dim = self.nets.frame_dim();
        check_actor_chunk(actor, dim)?;
        let nets = Arc::clone(&self.nets);
        let mut outputs = advance_sessions(&nets, &mut [&mut *self], &[actor], finish, false)?;
        Ok(outputs.pop().expect("one session, one output"))
    }

    /// Returns the session to the state of a fresh session with the current settings (seed,
    /// steps, CFG, condition, capacity). Queued noise is dropped.
    pub(crate) fn reset(&mut self) {
        self.state = StreamState::new(self.spec(), self.settings.capacity, self.vae_start.clone());
        if self.settings.recentring.is_some() {
            self.state.history = Some(History::starting_at(0));
        }
    }

    /// Algorithmic latency in frames (as [`crate::Model::latency_frames`]): how many actor
    /// frames after frame `t` arrive before the reactor frame `t` is out.
    pub(crate) fn latency_frames(&self) -> usize {
        self.spec().latency_frames()
    }

    /// Turns recentring on (with its distance) or off (`None`): before each token, when the
    /// actor's root is farther than the distance from the networks' centre, the centre moves to
    /// it and the networks' state is rebuilt around it from the last [`HISTORY_TOKENS`] tokens
    /// of both people's motion (`recentre.rs`); what the session returns stays in the stream's
    /// frame. The history starts when it is turned on; turning it off keeps the centre where it
    /// is. [`Error::Unsupported`] for a session that runs the VAE over windows or a bundle whose
    /// VAE looks ahead.
    pub fn set_recentring(&mut self, recentring: Option<Recentring>) -> Result<()> {
        if let Some(r) = &recentring {
            r.check()?;
            self.can_recentre()?;
        }
        if recentring.is_none() {
            self.state.history = None;
        } else if self.state.history.is_none() {
            self.state.history = Some(History::starting_at(self.state.tokens));
        }
        self.settings.recentring = recentring;
        Ok(())
    }

    /// The recentring's setting, when it is on.
    pub fn recentring(&self) -> Option<Recentring> {
        self.settings.recentring
    }

    /// Sets the noise seed; applies to tokens generated from now on.
    pub(crate) fn set_seed(&mut self, seed: u64) {
        self.settings.seed = seed;
    }

    /// Sets the number of MeanFlow steps per token (>= 1).
    pub(crate) fn set_steps(&mut self, steps: u32) -> Result<()> {
        check_steps("sampler steps", steps)?;
        self.settings.steps = steps;
        self.grid = meanflow_grid(steps);
        Ok(())
    }

    /// Sets the classifier-free guidance scale (finite; guides only above 1, as the official
    /// sampler does).
    pub(crate) fn set_cfg_scale(&mut self, scale: f32) -> Result<()> {
        check_cfg(scale)?;
        self.settings.cfg_scale = scale;
        Ok(())
    }

    /// Sets the conditioning vector (`None`: the null condition). Runs the conditioning graph
    /// once; applies to tokens generated from now on.
    pub(crate) fn set_condition(&mut self, condition: Option<&[f32]>) -> Result<()> {
        self.conditioning = self.nets.conditioning(condition)?;
        self.settings.condition = condition.map(<[f32]>::to_vec);
        Ok(())
    }

    /// Conditions the tokens generated from now on on a text prompt: [`Reactor::set_condition`]
    /// with [`crate::Model::encode_prompt`]'s condition (cached per prompt in the model).
    pub(crate) fn set_prompt(&mut self, prompt: &str) -> Result<()> {
        let condition = encode_prompt(&self.nets, prompt)?;
        self.set_condition(Some(&condition))
    }

    /// Queues the noise of the next token not yet generated; queued noise is used in order
    /// before the seeded generator. Both vectors hold `latent_dim` finite floats; at most
    /// [`LIMITS`]`.max_queued_noise_tokens` tokens wait at once.
    pub fn queue_noise(&mut self, noise: TokenNoise) -> Result<()> {
        let lat = self.nets.latent_dim();
        for (what, v) in [
            ("actor noise", &noise.actor),
            ("reactor noise", &noise.reactor),
        ] {
            if v.len() != lat {
                return Err(Error::InvalidInput(format!(
                    "{what} has {} floats, the bundle's latent dim is {lat}",
                    v.len()
                )));
            }
            check_input(what, v)?;
        }
        at_most(
            "queued noise (tokens)",
            self.state.injected.len() as u64 + 1,
            LIMITS.max_queued_noise_tokens,
            false,
        )?;
        self.state.injected.push_back(noise);
        Ok(())
    }

    /// Queues whole tokens of standard normals in the order the sampler draws them: per token
    /// the actor's posterior noise, then the reactor's start noise (`latent_dim` each), as
    /// [`Reactor::queue_noise`] does token by token.
    pub(crate) fn queue_normals(&mut self, normals: &[f32]) -> Result<()> {
        check_input("queued normals", normals)?;
        let lat = self.nets.latent_dim();
        if !normals.len().is_multiple_of(2 * lat) {
            return Err(Error::InvalidInput(format!(
                "{} queued normals are not whole tokens: an armflow token draws {} (the actor's \
                 posterior noise, then the reactor's start noise, {lat} each)",
                normals.len(),
                2 * lat
            )));
        }
        at_most(
            "queued noise (tokens)",
            (self.state.injected.len() + normals.len() / (2 * lat)) as u64,
            LIMITS.max_queued_noise_tokens,
            false,
        )?;
        for token in normals.chunks_exact(2 * lat) {
            self.queue_noise(TokenNoise {
                actor: token[..lat].to_vec(),
                reactor: token[lat..].to_vec(),
            })?;
        }
        Ok(())
    }

    /// The noise the seeded generator gives token `index` with the current seed.
    pub fn seeded_noise(&self, index: u64) -> TokenNoise {
        let lat = self.nets.latent_dim();
        let mut noise = TokenNoise {
            actor: vec![0.0; lat],
            reactor: vec![0.0; lat],
        };
        let seed = self.settings.seed;
        fill_normals(seed, index, STREAM_ACTOR_POSTERIOR, &mut noise.actor);
        fill_normals(seed, index, STREAM_REACTOR_NOISE, &mut noise.reactor);
        noise
    }

    /// Exactly how many reactor frames a `step` with `n_actor_frames` new frames will return.
    pub(crate) fn frames_ready_after(&self, n_actor_frames: usize) -> usize {
        let m = self.spec();
        let fpt = m.latent.frames_per_token as u64;
        let received = self
            .state
            .frames_received
            .saturating_add(n_actor_frames as u64);
        let tokens = received.saturating_sub(m.vae.encoder.lookahead_frames as u64) / fpt;
        let decodable = tokens.saturating_sub(m.vae.decoder.lookahead_tokens as u64);
        (decodable * fpt).saturating_sub(self.state.frames_emitted) as usize
    }

    /// Actor frames received since the start (or the last reset).
    pub(crate) fn frames_received(&self) -> u64 {
        self.state.frames_received
    }

    /// Reactor frames returned since the start (or the last reset).
    pub(crate) fn frames_emitted(&self) -> u64 {
        self.state.frames_emitted
    }

    /// Tokens generated since the start (or the last reset).
    pub(crate) fn tokens_generated(&self) -> u64 {
        self.state.tokens
    }

    /// Bytes this stream holds: its context cache, VAE state, buffered frames and latents, and
    /// its conditioning. Bounded by the context capacity however long the stream runs (allocator
    /// overhead and the model's weights, shared by all sessions, are not counted).
    pub(crate) fn memory_bytes(&self) -> usize {
        let st = &self.state;
        let floats = st.actor_frames.capacity()
            + st.last_pair.capacity()
            + st.reactor_latents.iter().map(Vec::capacity).sum::<usize>()
            + st.injected.len() * 2 * self.nets.latent_dim()
            + self.conditioning.modulation.len()
            + self.conditioning.start_token.len();
        std::mem::size_of::<Self>()
            + st.cache.bytes()
            + st.vae.as_ref().map_or(0, VaeState::bytes)
            + st.history.as_ref().map_or(0, History::bytes)
            + floats * std::mem::size_of::<f32>()
    }

    /// Entries held in the context cache (`<sos>` included); never above the capacity.
    pub(crate) fn context_len(&self) -> usize {
        self.state.cache.len()
    }
}

impl StreamState {
    fn new(spec: &ArmFlowSpec, capacity: usize, vae: Option<VaeState>) -> Self {
        Self {
            vae,
            frames_received: 0,
            actor_frames: Vec::new(),
            actor_base: 0,
            tokens: 0,
            cache: KvCache::empty(&spec.context, capacity),
            last_pair: Vec::new(),
            reactor_latents: VecDeque::new(),
            reactor_base: 0,
            frames_emitted: 0,
            injected: VecDeque::new(),
            history: None,
            centre: [0.0, 0.0],
            feedback: [0.0; feedback::DIM],
        }
    }

    /// Drops actor frames and reactor latents no future window reads: memory stays bounded.
    fn trim(&mut self, m: &ArmFlowSpec, frame_dim: usize) {
        let fpt = m.latent.frames_per_token as u64;
        // Step graphs carry the past in their state: only the unfinished token's frames and the
        // undecoded latents are kept.
        let (context_frames, context_tokens) = match self.vae {
            Some(_) => (0, 0),
            None => (
                m.vae.encoder.context_frames as u64,
                m.vae.decoder.context_tokens as u64,
            ),
        };
        let keep_from = (self.tokens * fpt).saturating_sub(context_frames);
        if keep_from > self.actor_base {
            let drop = (keep_from - self.actor_base) as usize * frame_dim;
            self.actor_frames.drain(..drop);
            self.actor_base = keep_from;
        }
        let next_decode = self.frames_emitted / fpt;
        let keep_from = next_decode.saturating_sub(context_tokens);
        while self.reactor_base < keep_from {
            self.reactor_latents.pop_front();
            self.reactor_base += 1;
        }
    }
}

/// Advances many reactors of one model in one call (what `step_sessions` runs for ARMFlow):
/// `actor[i]` (row-major frames, any number) goes to `sessions[i]`, `finish` runs on each output
/// before the step is committed (the sessions' motion stages). Each round of the loop runs every
/// graph once for all the sessions that have a token to generate, so the weights are read once
/// per round rather than once per session; each session's outputs equal stepping it alone up to
/// float rounding (<= 1e-5 in the tests).
///
/// Sessions may differ in everything but their model (same [`crate::Model`] or a clone): seed,
/// steps, CFG, condition, capacity, history length, and how many frames they are given. On error
/// every session is unchanged.
fn step_reactors_finished(
    sessions: &mut [&mut Reactor],
    actor: &[&[f32]],
    finish: Finish<'_>,
) -> Result<Vec<StepOutput>> {
    if actor.len() != sessions.len() {
        return Err(Error::InvalidInput(format!(
            "{} sessions but {} chunks of actor frames",
            sessions.len(),
            actor.len()
        )));
    }
    let Some(first) = sessions.first() else {
        return Ok(Vec::new());
    };
    let nets = Arc::clone(&first.nets);
    let dim = nets.frame_dim();
    for (i, (session, chunk)) in sessions.iter().zip(actor).enumerate() {
        if !Arc::ptr_eq(&session.nets, &nets) {
            return Err(Error::InvalidInput(format!(
                "session {i} runs another model: sessions stepped together must share one"
            )));
        }
        check_actor_chunk(chunk, dim).map_err(|e| match e {
            Error::InvalidInput(m) => Error::InvalidInput(format!("session {i}: {m}")),
            other => other,
        })?;
    }
    advance_sessions(&nets, sessions, actor, finish, true)
}

/// Runs the token loop over `sessions` (validated, all of `nets`), one lane each. Each session's
/// cache moves into its lane (written in place, no copy) and comes back committed when every
/// lane succeeded and `finish` accepted its output, rolled back otherwise, every session then
/// unchanged. With `indexed`, messages name the session by its index.
fn advance_sessions(
    nets: &Networks,
    sessions: &mut [&mut Reactor],
    actor: &[&[f32]],
    finish: Finish<'_>,
    indexed: bool,
) -> Result<Vec<StepOutput>> {
    let dim = nets.frame_dim();
    let caches: Vec<KvCache> = sessions
        .iter_mut()
        .map(|s| std::mem::take(&mut s.state.cache))
        .collect();
    let mut lanes: Vec<Lane> = sessions
        .iter()
        .zip(caches)
        .enumerate()
        .map(|(i, (s, cache))| Lane::new(s, indexed.then_some(i), cache))
        .collect();
    if let Err(e) = lanes::advance(nets, &mut lanes, actor) {
        let caches: Vec<KvCache> = lanes.into_iter().map(Lane::rolled_back_cache).collect();
        for (session, cache) in sessions.iter_mut().zip(caches) {
            session.state.cache = cache;
        }
        return Err(e);
    }
    let mut finished: Vec<_> = lanes.into_iter().map(|l| l.finish(dim)).collect();
    let checked = finished
        .iter_mut()
        .enumerate()
        .try_for_each(|(i, (_, output, _))| finish(i, output));
    if let Err(e) = checked {
        for (session, (state, _, set_aside)) in sessions.iter_mut().zip(finished) {
            let mut cache = set_aside.unwrap_or(state.cache);
            cache.rollback();
            session.state.cache = cache;
        }
        return Err(e);
    }
    Ok(sessions
        .iter_mut()
        .zip(finished)
        .map(|(session, (mut state, output, _))| {
            state.cache.commit();
            session.state = state;
            output
        })
        .collect())
}

fn check_actor_chunk(actor: &[f32], dim: usize) -> Result<()> {
    check_frames("actor frames", actor, dim)
}

/// The condition of `prompt` through the bundle's prompt encoder.
fn encode_prompt(nets: &Networks, prompt: &str) -> Result<Vec<f32>> {
    let encoder = nets
        .prompt_encoder()
        .ok_or_else(|| no_prompts(&nets.io.name))?;
    encoder.encode(prompt)
}

impl Stream for Reactor {
    fn family(&self) -> &'static str {
        "armflow"
    }
    fn io(&self) -> &BundleIo {
        &self.nets.io
    }
    fn capabilities(&self) -> Capabilities {
        let mut caps = vec![
            Capability::Condition,
            Capability::CfgScale,
            Capability::QueuedNormals,
        ];
        if self.nets.prompt_encoder().is_some() {
            caps.push(Capability::Prompt);
        }
        Capabilities::of(&caps)
    }
    fn set_cfg_scale(&mut self, scale: f32) -> Result<()> {
        Reactor::set_cfg_scale(self, scale)
    }
    fn set_condition(&mut self, condition: Option<&[f32]>) -> Result<()> {
        Reactor::set_condition(self, condition)
    }
    fn set_prompt(&mut self, prompt: &str) -> Result<()> {
        Reactor::set_prompt(self, prompt)
    }
    fn queue_normals(&mut self, normals: &[f32]) -> Result<()> {
        Reactor::queue_normals(self, normals)
    }
    fn save(&self, w: &mut SnapshotWriter) -> Result<()> {
        Reactor::save(self, w)
    }
    fn frame_dim(&self) -> usize {
        Reactor::frame_dim(self)
    }
    fn latent_dim(&self) -> usize {
        Reactor::latent_dim(self)
    }
    fn condition_dim(&self) -> usize {
        Reactor::condition_dim(self)
    }
    fn step(&mut self, frames: &[f32], finish: Finish<'_>) -> Result<StepOutput> {
        self.step_finished(frames, finish)
    }
    fn step_together(&self) -> StepTogether {
        |streams, frames, finish| {
            step_reactors_finished(&mut downcast_all::<Reactor>(streams), frames, finish)
        }
    }
    fn same_model(&self, other: &dyn Stream) -> bool {
        other
            .as_any()
            .downcast_ref::<Reactor>()
            .is_some_and(|o| Arc::ptr_eq(&self.nets, &o.nets))
    }
    fn reset(&mut self) {
        Reactor::reset(self)
    }
    fn latency_frames(&self) -> usize {
        Reactor::latency_frames(self)
    }
    fn set_seed(&mut self, seed: u64) {
        Reactor::set_seed(self, seed)
    }
    fn set_steps(&mut self, steps: u32) -> Result<()> {
        Reactor::set_steps(self, steps)
    }
    fn frames_ready_after(&self, n: usize) -> usize {
        Reactor::frames_ready_after(self, n)
    }
    fn frames_received(&self) -> u64 {
        Reactor::frames_received(self)
    }
    fn frames_emitted(&self) -> u64 {
        Reactor::frames_emitted(self)
    }
    fn tokens_generated(&self) -> u64 {
        Reactor::tokens_generated(self)
    }
    fn memory_bytes(&self) -> usize {
        Reactor::memory_bytes(self)
    }
    fn context_len(&self) -> usize {
        Reactor::context_len(self)
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

impl From<Reactor> for crate::family::session::Session {
    fn from(reactor: Reactor) -> Self {
        Self::new(reactor)
    }
}
