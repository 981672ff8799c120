//! [`Session`]: one stream, whatever the family. Frames in, the other person's frames out.
//!
//! - over an `armflow` model: the actor's frames in, the reactor's out, one token at a time
//!   (`armflow/session`);
//! - over an online `arflow` model: the actor's frames in, the reactor's out, frame by frame
//!   (`arflow/stream.rs`);
//! - over a `magnet` model: the user's frames in, the live partner's out, one chunk of the
//!   official rolling window at a time (`magnet/live.rs`).
//!
//! All share the shape callers program against: `step` / `step_flat` / `reset` / the setters,
//! [`step_sessions`] for crowds (one batched pass per round), and the C ABI's `troupe_session_*`.
//! A step either completes or leaves the session as it was.

use ndarray::{Array2, ArrayView2, ArrayView3};

use crate::arflow::spec::ArflowSampling;
use crate::arflow::stream::{self, ArflowStream};
use crate::arflow::ArflowOptions;
use crate::armflow::spec::ActorLatent;
use crate::armflow::{self, PenetrationGuard, StepOutput, TokenNoise, TokenTrace};
use crate::magnet::live::{self, LiveSession};
use crate::magnet::LiveSettings;
use crate::motion::{JointsFormat, Placement, Pose};
use crate::shared::error::{Error, Result};

/// Options of a session. Fields left `None` take the bundle's defaults. The first group applies
/// to both families where it says so; the `partner_*`/`live_*` fields only to `magnet` models.
#[derive(Debug, Clone, Default)]
pub struct SessionOptions {
    /// Seed of the portable noise generator ([`crate::noise`]).
    pub seed: u64,
    /// Sampler steps: MeanFlow steps per token (armflow), DDIM steps per chunk (magnet).
    pub steps: Option<u32>,
    /// Classifier-free guidance scale (armflow); 1 disables guidance. A magnet stream takes
    /// only 1 (its released configuration has none).
    pub cfg_scale: Option<f32>,
    /// Conditioning vector of `condition_dim` floats (armflow); `None` is the null condition.
    pub condition: Option<Vec<f32>>,
    /// A text prompt to condition on instead of `condition` (armflow bundles that take prompts).
    pub prompt: Option<String>,
    /// Context tokens: the armflow context cache's capacity, `<sos>` included (>= 2); a magnet
    /// stream's context tokens per window (`Tc`, 1 to window - 1; the stride is the rest).
    pub context_capacity: Option<usize>,
    /// Posterior sample (default) or mean for the actor's latent tokens (armflow).
    pub actor_latent: Option<ActorLatent>,
    /// Run the VAE over windows even when the bundle has per-token step graphs (armflow).
    pub vae_windows: bool,
    /// Pull the reactor's frames out of the actor's body as they are sent (armflow; off when
    /// `None`; `armflow/session/guard.rs` states the rule).
    pub penetration_guard: Option<PenetrationGuard>,
    /// The partner's opening frames, `[context frames, 145]` row-major (magnet; also
    /// [`Session::set_partner_opening`]). A stream needs them before the user's first frame.
    pub partner_opening: Option<Vec<f32>>,
    /// The sampling configuration of a magnet stream: a released name or JSON; `None` is the
    /// bundle's first `motion_control_live` configuration.
    pub live_config: Option<String>,
    /// Emit each chunk's partner frames as soon as they are generated (magnet): `4 (Tm - Tc)`
    /// frames less latency, but the next chunk's smoothing no longer reaches them.
    pub early_emission: bool,
    /// ARFlow's sampler settings for an online `arflow` bundle's stream (`None`: the bundle's;
    /// the seed is `seed`'s).
    pub arflow: Option<ArflowOptions>,
}

/// One stream over a shared [`crate::Model`] (made by [`crate::Model::session`]). `Send`, not
/// `Sync`: use it from one thread at a time.
#[derive(Debug)]
pub struct Session {
    stream: Stream,
}

#[derive(Debug)]
enum Stream {
    // Boxed: the variants differ in size by a few hundred bytes, and sessions move.
    Reaction(Box<armflow::Session>),
    Partner(Box<LiveSession>),
    Flow(Box<ArflowStream>),
}

impl SessionOptions {
    /// The armflow session's options; fails on a magnet-only field.
    pub(crate) fn for_reaction(self) -> Result<armflow::SessionOptions> {
        if self.partner_opening.is_some() || self.live_config.is_some() || self.early_emission {
            return Err(unsupported(
                "armflow",
                "magnet",
                "partner_opening, live_config and early_emission",
            ));
        }
        if self.arflow.is_some() {
            return Err(unsupported("armflow", "arflow", "ARFlow's settings"));
        }
        Ok(armflow::SessionOptions {
            seed: self.seed,
            steps: self.steps,
            cfg_scale: self.cfg_scale,
            condition: self.condition,
            prompt: self.prompt,
            context_capacity: self.context_capacity,
            actor_latent: self.actor_latent,
            vae_windows: self.vae_windows,
            penetration_guard: self.penetration_guard,
        })
    }

    /// Refuses what neither MAGNet's nor ARFlow's streams take: a condition, a prompt, a CFG
    /// scale other than 1, the actor's posterior mean, VAE windows, the penetration guard.
    fn refuse_armflow_settings(&self, stream: &str) -> Result<()> {
        let refuse = |what: &str| {
            Err(Error::Unsupported(format!(
                "{what}: {stream} has no conditioning, guidance scale or ARMFlow settings"
            )))
        };
        if self.condition.is_some() || self.prompt.is_some() {
            return refuse("a condition or prompt");
        }
        if self.cfg_scale.is_some_and(|s| s != 1.0) {
            return refuse("a CFG scale other than 1");
        }
        if self.actor_latent == Some(ActorLatent::Mean)
            || self.vae_windows
            || self.penetration_guard.is_some()
        {
            return refuse("actor_latent = mean, vae_windows or the penetration guard");
        }
        Ok(())
    }

    /// What a magnet stream reads: fails on a field the stream cannot honour.
    pub(crate) fn check_for_partner(&self) -> Result<()> {
        self.refuse_armflow_settings("a magnet live partner session")?;
        if self.arflow.is_some() {
            return Err(unsupported("magnet", "arflow", "ARFlow's settings"));
        }
        Ok(())
    }

    /// What an ARFlow stream reads: its sampler settings (the bundle's with `arflow`'s changes,
    /// `steps` applied); fails on a field the stream cannot honour.
    pub(crate) fn for_flow(&self, base: &ArflowSampling) -> Result<ArflowSampling> {
        self.refuse_armflow_settings("an ARFlow stream")?;
        if self.partner_opening.is_some() || self.live_config.is_some() || self.early_emission {
            return Err(unsupported(
                "arflow",
                "magnet",
                "partner_opening, live_config and early_emission",
            ));
        }
        let mut changes = self.arflow.clone().unwrap_or_default();
        if let Some(steps) = self.steps {
            changes.steps = Some(steps as usize);
        }
        changes.apply(base)
    }
}

impl Session {
    pub(crate) fn flow(stream: ArflowStream) -> Self {
        Self {
            stream: Stream::Flow(Box::new(stream)),
        }
    }

    pub(crate) fn reaction(session: armflow::Session) -> Self {
        Self {
            stream: Stream::Reaction(Box::new(session)),
        }
    }

    pub(crate) fn partner(session: LiveSession) -> Self {
        Self {
            stream: Stream::Partner(Box::new(session)),
        }
    }

    /// The family this session streams: `"armflow"`, `"magnet"` or `"arflow"`.
    pub fn family(&self) -> &'static str {
        match self.stream {
            Stream::Reaction(_) => "armflow",
            Stream::Partner(_) => "magnet",
            Stream::Flow(_) => "arflow",
        }
    }

    /// The armflow stream, for what only it has.
    fn reaction_mut(&mut self, what: &str) -> Result<&mut armflow::Session> {
        let family = self.family();
        match &mut self.stream {
            Stream::Reaction(s) => Ok(s),
            Stream::Partner(_) | Stream::Flow(_) => Err(unsupported(family, "armflow", what)),
        }
    }

    fn partner_mut(&mut self, what: &str) -> Result<&mut LiveSession> {
        let family = self.family();
        match &mut self.stream {
            Stream::Partner(s) => Ok(s),
            Stream::Reaction(_) | Stream::Flow(_) => Err(unsupported(family, "magnet", what)),
        }
    }

    /// Floats per motion frame, in and out.
    pub fn frame_dim(&self) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.frame_dim(),
            Stream::Partner(_) => crate::magnet::layout::FRAME_DIM,
            Stream::Flow(_) => crate::arflow::spec::FRAME_DIM,
        }
    }

    /// Floats per latent token (armflow: each [`TokenNoise`] vector; magnet: a motion token;
    /// arflow, which has no latent: a frame).
    pub fn latent_dim(&self) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.latent_dim(),
            Stream::Partner(s) => s.token_dim(),
            Stream::Flow(_) => crate::arflow::spec::FRAME_DIM,
        }
    }

    /// Floats in the conditioning vector [`Session::set_condition`] takes (0: none).
    pub fn condition_dim(&self) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.condition_dim(),
            Stream::Partner(_) | Stream::Flow(_) => 0,
        }
    }

    /// Whether this session runs the bundle's per-token VAE steps (armflow; false otherwise).
    pub fn uses_vae_steps(&self) -> bool {
        matches!(&self.stream, Stream::Reaction(s) if s.uses_vae_steps())
    }

    /// Feeds any number of frames (`[n, frame_dim]`, n may be 0) and returns the other person's
    /// frames that became ready. On error the session is unchanged.
    pub fn step(&mut self, frames: ArrayView2<f32>) -> Result<Array2<f32>> {
        Ok(self.step_detailed(frames)?.frames)
    }

    /// [`Session::step`], also returning the latent tokens it computed (armflow: with their
    /// contexts; magnet: the partner's tokens sent, with the user's at the same place).
    pub fn step_detailed(&mut self, frames: ArrayView2<f32>) -> Result<StepOutput> {
        match &mut self.stream {
            Stream::Reaction(s) => s.step_detailed(frames),
            Stream::Partner(_) | Stream::Flow(_) => {
                let dim = self.frame_dim();
                if frames.ncols() != dim {
                    return Err(Error::InvalidInput(format!(
                        "frames have {} features, this {} stream takes {dim}",
                        frames.ncols(),
                        self.family()
                    )));
                }
                let owned = frames.as_standard_layout();
                self.step_flat(owned.as_slice().expect("standard layout"))
            }
        }
    }

    /// [`Session::step_detailed`] on row-major frames (`n * frame_dim` floats).
    pub fn step_flat(&mut self, frames: &[f32]) -> Result<StepOutput> {
        self.step_bounded(frames, usize::MAX)
    }

    /// [`Session::step_flat`] that fails, leaving the session unchanged, when more than
    /// `max_frames` frames would come out (the C ABI's caller-sized buffer).
    pub(crate) fn step_bounded(&mut self, frames: &[f32], max_frames: usize) -> Result<StepOutput> {
        match &mut self.stream {
            Stream::Reaction(s) => s.step_bounded(frames, max_frames),
            Stream::Partner(s) => {
                let mut out = live::advance(&mut [s], &[frames], &[max_frames], false)?;
                Ok(partner_output(out.pop().expect("one stream, one output")))
            }
            Stream::Flow(s) => {
                let mut out = stream::advance(&mut [s], &[frames], &[max_frames], false)?;
                Ok(flow_output(out.pop().expect("one stream, one output")))
            }
        }
    }

    /// Returns the session to the state of a fresh session with the current settings. Queued
    /// noise is dropped.
    pub fn reset(&mut self) {
        match &mut self.stream {
            Stream::Reaction(s) => s.reset(),
            Stream::Partner(s) => s.reset(),
            Stream::Flow(s) => s.reset(),
        }
    }

    /// Algorithmic latency in frames: how many input frames after frame `t` arrive before the
    /// output frame `t` is out (at worst, compute time not counted).
    pub fn latency_frames(&self) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.latency_frames(),
            Stream::Partner(s) => s.latency_frames(),
            Stream::Flow(_) => 0,
        }
    }

    /// Sets the noise seed; applies to what is generated from now on.
    pub fn set_seed(&mut self, seed: u64) {
        match &mut self.stream {
            Stream::Reaction(s) => s.set_seed(seed),
            Stream::Partner(s) => s.set_seed(seed),
            Stream::Flow(s) => s.set_seed(seed),
        }
    }

    /// Sets the sampler's steps (>= 1): MeanFlow steps per token, or DDIM steps per chunk.
    /// Applies from the next token or chunk.
    pub fn set_steps(&mut self, steps: u32) -> Result<()> {
        match &mut self.stream {
            Stream::Reaction(s) => s.set_steps(steps),
            Stream::Partner(s) => {
                let mut settings = s.settings().clone();
                settings.sampling.steps = steps as usize;
                s.configure(settings)
            }
            Stream::Flow(s) => {
                let mut sampling = s.sampling().clone();
                sampling.steps = steps as usize;
                s.set_sampling(sampling)
            }
        }
    }

    /// Sets the classifier-free guidance scale (finite; 1 disables guidance). A magnet stream
    /// takes only 1.
    pub fn set_cfg_scale(&mut self, scale: f32) -> Result<()> {
        match &mut self.stream {
            Stream::Reaction(s) => s.set_cfg_scale(scale),
            Stream::Partner(_) | Stream::Flow(_) if scale == 1.0 => Ok(()),
            Stream::Partner(_) | Stream::Flow(_) => Err(unsupported(
                self.family(),
                "armflow",
                "a CFG scale other than 1",
            )),
        }
    }

    /// Sets the conditioning vector (`None`: the null condition; armflow).
    pub fn set_condition(&mut self, condition: Option<&[f32]>) -> Result<()> {
        match (&mut self.stream, condition) {
            (Stream::Reaction(s), c) => s.set_condition(c),
            (Stream::Partner(_) | Stream::Flow(_), None) => Ok(()),
            (Stream::Partner(_) | Stream::Flow(_), Some(_)) => {
                Err(unsupported(self.family(), "armflow", "a condition"))
            }
        }
    }

    /// Conditions what is generated from now on on a text prompt (armflow bundles that take
    /// prompts).
    pub fn set_prompt(&mut self, prompt: &str) -> Result<()> {
        self.reaction_mut("a prompt")?.set_prompt(prompt)
    }

    /// Turns the penetration guard on (with its settings) or off (`None`) for the frames sent
    /// from now on (armflow).
    pub fn set_penetration_guard(&mut self, guard: Option<PenetrationGuard>) -> Result<()> {
        self.reaction_mut("the penetration guard")?
            .set_penetration_guard(guard)
    }

    /// Queues the noise of the next token not yet generated (armflow).
    pub fn queue_noise(&mut self, noise: TokenNoise) -> Result<()> {
        self.reaction_mut("queued noise")?.queue_noise(noise)
    }

    /// The noise the seeded generator gives token `index` with the current seed (armflow).
    pub fn seeded_noise(&self, index: u64) -> Result<TokenNoise> {
        match &self.stream {
            Stream::Reaction(s) => Ok(s.seeded_noise(index)),
            Stream::Partner(_) | Stream::Flow(_) => {
                Err(unsupported(self.family(), "armflow", "per-token noise"))
            }
        }
    }

    /// An ARFlow stream's bundle sampler settings (what its options change); `None` for other
    /// families.
    pub(crate) fn arflow_bundle_sampling(&self) -> Option<&ArflowSampling> {
        match &self.stream {
            Stream::Flow(s) => Some(s.bundle_sampling()),
            _ => None,
        }
    }

    /// Sets an ARFlow stream's sampler settings: the bundle's with `options`' changes (its seed
    /// too). A new step count only before the first frame or after a reset.
    pub fn set_arflow_options(&mut self, options: &ArflowOptions) -> Result<()> {
        match &mut self.stream {
            Stream::Flow(s) => {
                let sampling = options.apply(s.bundle_sampling())?;
                s.set_sampling(sampling)?;
                s.set_seed(options.seed);
                Ok(())
            }
            _ => Err(unsupported(self.family(), "arflow", "ARFlow's settings")),
        }
    }

    /// Sets the partner's opening frames (`[context frames, 145]`, row-major) of a magnet
    /// stream, kept across resets. Only before the first frame or after a reset.
    pub fn set_partner_opening(&mut self, frames: &[f32]) -> Result<()> {
        let s = self.partner_mut("the partner's opening frames")?;
        if s.frames_received() > 0 {
            return Err(Error::InvalidInput(
                "the partner's opening frames are set before the first step or after a reset"
                    .into(),
            ));
        }
        let mut settings = s.settings().clone();
        settings.opening = Some(frames.to_vec());
        s.configure(settings)
    }

    /// Runs the sampling configuration `config` (a released name or JSON) in this magnet
    /// stream. Only before the first frame or after a reset; opening frames set before must
    /// match its context.
    pub fn set_live_config(&mut self, config: &str) -> Result<()> {
        let s = self.partner_mut("a live configuration")?;
        if s.frames_received() > 0 {
            return Err(Error::InvalidInput(
                "the live configuration is set before the first step or after a reset".into(),
            ));
        }
        s.set_config(config)
    }

    /// Emit each chunk's frames as soon as they are generated (magnet; see
    /// [`SessionOptions::early_emission`]). Only before the first frame or after a reset.
    pub fn set_early_emission(&mut self, early: bool) -> Result<()> {
        let s = self.partner_mut("early emission")?;
        if s.frames_received() > 0 {
            return Err(Error::InvalidInput(
                "early emission is set before the first step or after a reset".into(),
            ));
        }
        let mut settings = s.settings().clone();
        settings.early = early;
        s.configure(settings)
    }

    /// Exactly how many frames a `step` with `n` new input frames will return.
    pub fn frames_ready_after(&self, n: usize) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.frames_ready_after(n),
            Stream::Partner(s) => s.frames_ready_after(n),
            Stream::Flow(s) => s.frames_ready_after(n),
        }
    }

    /// Input frames received since the start (or the last reset).
    pub fn frames_received(&self) -> u64 {
        match &self.stream {
            Stream::Reaction(s) => s.frames_received(),
            Stream::Partner(s) => s.frames_received(),
            Stream::Flow(s) => s.frames(),
        }
    }

    /// Output frames returned since the start (or the last reset).
    pub fn frames_emitted(&self) -> u64 {
        match &self.stream {
            Stream::Reaction(s) => s.frames_emitted(),
            Stream::Partner(s) => s.frames_emitted(),
            Stream::Flow(s) => s.frames(),
        }
    }

    /// Tokens generated (armflow) or sent (magnet) since the start (or the last reset).
    pub fn tokens_generated(&self) -> u64 {
        match &self.stream {
            Stream::Reaction(s) => s.tokens_generated(),
            Stream::Partner(s) => s.tokens_generated(),
            Stream::Flow(_) => 0,
        }
    }

    /// Bytes this stream holds, bounded however long it runs (the model's weights, shared by
    /// all sessions, not counted).
    pub fn memory_bytes(&self) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.memory_bytes(),
            Stream::Partner(s) => s.memory_bytes(),
            Stream::Flow(s) => s.memory_bytes(),
        }
    }

    /// Context tokens held: the armflow cache's entries (`<sos>` included, never above the
    /// capacity), or the magnet stream's context tokens for its next window.
    pub fn context_len(&self) -> usize {
        match &self.stream {
            Stream::Reaction(s) => s.context_len(),
            Stream::Partner(s) => s.context_len(),
            Stream::Flow(s) => s.frames() as usize,
        }
    }

    /// Sets how [`Session::step_joints`] reads actor positions (armflow with a joints layout).
    pub fn set_joints_format(&mut self, format: JointsFormat) -> Result<()> {
        self.reaction_mut("joint positions")?
            .set_joints_format(format)
    }

    /// The joint stream's placement (armflow; `None` before the first joint frame).
    pub fn joints_placement(&self) -> Option<&Placement> {
        match &self.stream {
            Stream::Reaction(s) => s.joints_placement(),
            Stream::Partner(_) | Stream::Flow(_) => None,
        }
    }

    /// Frames of latency from an actor joint frame to the reactor pose it completes (armflow).
    pub fn joints_latency_frames(&self) -> Result<usize> {
        match &self.stream {
            Stream::Reaction(s) => Ok(s.joints_latency_frames()),
            Stream::Partner(_) | Stream::Flow(_) => {
                Err(unsupported(self.family(), "armflow", "joint positions"))
            }
        }
    }

    /// Feeds actor joint positions (`[n, 22, 3]`) and returns the reactor poses that became
    /// ready (armflow with a joints layout).
    pub fn step_joints(&mut self, actor: ArrayView3<f32>) -> Result<Vec<Pose>> {
        self.reaction_mut("joint positions")?.step_joints(actor)
    }

    /// How many poses [`Session::step_joints`] returns for the next `n` joint frames (armflow).
    pub fn joints_ready_after(&self, n: usize) -> Result<usize> {
        match &self.stream {
            Stream::Reaction(s) => s.joints_ready_after(n),
            Stream::Partner(_) | Stream::Flow(_) => {
                Err(unsupported(self.family(), "armflow", "joint positions"))
            }
        }
    }
}

/// The error for a setting only `needed` streams take, asked of a `family` stream.
fn unsupported(family: &str, needed: &str, what: &str) -> Error {
    let article = if family.starts_with('a') { "an" } else { "a" };
    Error::Unsupported(format!(
        "{what}: only {needed} streams take this; this session runs {article} `{family}` model"
    ))
}

/// An ARFlow step's output: the reactor's frames (no tokens).
fn flow_output(frames: Array2<f32>) -> StepOutput {
    StepOutput {
        frames,
        tokens: Vec::new(),
    }
}

/// A magnet step's output: the partner's tokens as traces (`actor_latent` the user's token at
/// the same place, `reactor_latent` the partner's, no context vector).
fn partner_output(out: live::LiveOutput) -> StepOutput {
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

/// Advances many sessions of one model in one call: `frames[i]` (row-major, any number) goes to
/// `sessions[i]`, and the result's entry `i` is what [`Session::step_flat`] would have returned
/// for it. Each round runs the networks once for all the sessions that have work (a token, or a
/// chunk), so the weights are read once per round rather than once per session; each session's
/// output equals stepping it alone up to float rounding (<= 1e-5 in the tests). On error every
/// session is unchanged.
pub fn step_sessions(sessions: &mut [&mut Session], frames: &[&[f32]]) -> Result<Vec<StepOutput>> {
    step_sessions_bounded(sessions, frames, &[])
}

/// [`step_sessions`] that fails, changing no session, when session `i` would return more than
/// `max_frames[i]` frames (the C ABI's caller-sized buffers; empty: unbounded).
pub(crate) fn step_sessions_bounded(
    sessions: &mut [&mut Session],
    frames: &[&[f32]],
    max_frames: &[usize],
) -> Result<Vec<StepOutput>> {
    let family = sessions.first().map(|s| s.family());
    if let Some(i) = sessions.iter().position(|s| Some(s.family()) != family) {
        return Err(Error::InvalidInput(format!(
            "session {i} runs another model: sessions stepped together must share one"
        )));
    }
    let mut reactions = Vec::new();
    let mut partners = Vec::new();
    let mut flows = Vec::new();
    for s in sessions.iter_mut() {
        match &mut s.stream {
            Stream::Reaction(r) => reactions.push(&mut **r),
            Stream::Partner(p) => partners.push(&mut **p),
            Stream::Flow(f) => flows.push(&mut **f),
        }
    }
    if !reactions.is_empty() {
        return armflow::step_sessions_bounded(&mut reactions, frames, max_frames);
    }
    let count = partners.len() + flows.len();
    if frames.len() != count {
        return Err(Error::InvalidInput(format!(
            "{count} sessions but {} chunks of frames",
            frames.len()
        )));
    }
    if !flows.is_empty() {
        if let Some(i) = (1..flows.len()).find(|&i| !flows[i].same_model(flows[0])) {
            return Err(Error::InvalidInput(format!(
                "session {i} runs another model: sessions stepped together must share one"
            )));
        }
        return Ok(stream::advance(&mut flows, frames, max_frames, true)?
            .into_iter()
            .map(flow_output)
            .collect());
    }
    if let Some(i) = (1..partners.len()).find(|&i| !partners[i].same_model(partners[0])) {
        return Err(Error::InvalidInput(format!(
            "session {i} runs another model: sessions stepped together must share one"
        )));
    }
    Ok(live::advance(&mut partners, frames, max_frames, true)?
        .into_iter()
        .map(partner_output)
        .collect())
}

/// [`Session::step_joints`] for many armflow sessions of one model at once.
pub fn step_sessions_joints(
    sessions: &mut [&mut Session],
    actor: &[ArrayView3<f32>],
) -> Result<Vec<Vec<Pose>>> {
    let mut reactions = Vec::with_capacity(sessions.len());
    for s in sessions.iter_mut() {
        let family = s.family();
        match &mut s.stream {
            Stream::Reaction(r) => reactions.push(&mut **r),
            Stream::Partner(_) | Stream::Flow(_) => {
                return Err(unsupported(family, "armflow", "joint positions"))
            }
        }
    }
    armflow::step_sessions_joints(&mut reactions, actor)
}

/// The live settings a magnet model's session starts with.
pub(crate) fn partner_settings(
    nets: &crate::magnet::Networks,
    options: &SessionOptions,
) -> Result<LiveSettings> {
    live::check_persons(nets)?;
    options.check_for_partner()?;
    let name = match &options.live_config {
        Some(name) => name.clone(),
        None => crate::magnet::default_live_config(nets)?,
    };
    let mut sampling = crate::magnet::configuration(
        nets,
        &name,
        &crate::magnet::MagnetOptions {
            samples: Some(1),
            steps: options.steps.map(|s| s as usize),
            seed: Some(options.seed),
            ..Default::default()
        },
    )?;
    if let Some(tc) = options.context_capacity {
        sampling.context_len = tc.saturating_mul(crate::magnet::layout::FRAMES_PER_TOKEN);
    }
    Ok(LiveSettings {
        sampling,
        seed: options.seed,
        early: options.early_emission,
        opening: options.partner_opening.clone(),
    })
}
