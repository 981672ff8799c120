//! Recentring of an ARMFlow stream: the networks' frame follows the actor across the floor.
//!
//! A stream's frame is fixed by where it starts (a joint stream's by the actor's first frame,
//! its root over the origin), and the networks see absolute positions in it. Trained on windows
//! whose actor stays within a metre or two of the origin, they degrade as the actor wanders: on
//! a held-out take whose actor ends 7 m from where it started, the demo model's error over the
//! last 10 s of a minute is 116 cm, against 32 cm for a stream restarted 10 s before
//! (docs/DEMO.md). Recentring keeps the networks near the origin instead.
//!
//! The stream keeps a *centre* on the floor: the networks see every position less the centre
//! (the actor's frames before the encoder, the reactor's frames as decoded plus the centre
//! before anything else sees them). Everything outside the networks (the caller, the joint
//! stream's placement, the guard, the smoothing, the foot lock) stays in the stream's frame. Before
//! token `j` is generated, if the actor's root at the token's first frame is farther than
//! `distance` metres from the centre, the centre moves to it and the networks' state is rebuilt
//! around the new centre from the last [`HISTORY_TOKENS`] tokens of both people's motion, which
//! the stream keeps (in its own frame) while recentring is on:
//!
//! 1. from the VAE's zero state the encoder runs over the kept actor frames, less the centre
//!    (its tokens sampled with the seeded generator's noise for their index, or their means, as
//!    the session's setting says), and, from another zero state, over the kept reactor frames,
//!    less the centre (the posterior means);
//! 2. the decoder runs over those reactor tokens from the zero state (its frames, already sent,
//!    are dropped): the encoder's and decoder's state are now the new centre's;
//! 3. the context cache is rebuilt from `<sos>` and the new pairs in one causal pass, at the
//!    positions the old pairs had (at most the capacity's worth, as the cache would hold), each
//!    under the condition it had (a feedback bundle's placements are read again from the kept
//!    frames: they are relative, so the move does not change them).
//!
//! The check falls on token boundaries of the stream, so how a caller splits its frames into
//! calls does not change the result. Recentring needs the bundle's per-token VAE graphs with no
//! lookahead (every token decoded as soon as it is generated); each time it costs `HISTORY_TOKENS`
//! encoder steps (both people batched), as many decoder steps, and one context pass.

use super::feedback;
use super::lane::{actor_token, Lane};
use super::Reactor;
use crate::armflow::kv_cache::KvCache;
use crate::armflow::networks::{Networks, VaeState};
use crate::family::motion::layout::FrameLayout;
use crate::motion::features::POSITIONS;
use crate::shared::checks::{check_output, check_output_counted};
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{bad, SnapshotReader, SnapshotWriter};

/// Tokens of both people's motion a recentring stream keeps to rebuild its state from (1.1 s at
/// 4 frames per token and 30 fps): as many as the demo model's training windows that stand for
/// the middle of a stream begin with. 4, 8 and 16 measured alike on the held-out takes
/// (docs/DEMO.md); the cost of a rebuild grows with it.
pub const HISTORY_TOKENS: usize = 8;

/// The recentring's setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recentring {
    /// How far (metres, on the floor, in [0.1, 100]) the actor's root may be from the networks'
    /// centre before the centre moves to it.
    pub distance: f64,
}

impl Default for Recentring {
    fn default() -> Self {
        // Measured on the demo model's held-out streams (docs/DEMO.md): 0.5 m and 1 m alike in
        // error; 1 m rebuilds half as often.
        Recentring { distance: 1.0 }
    }
}

impl Recentring {
    /// Checks the setting's range.
    pub fn check(&self) -> Result<()> {
        if !(self.distance.is_finite() && (0.1..=100.0).contains(&self.distance)) {
            return Err(Error::InvalidOption(format!(
                "recentring: distance {} m is not in [0.1, 100] m",
                self.distance
            )));
        }
        Ok(())
    }
}

/// The last tokens' frames of both people, in the stream's frame, while recentring is on.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct History {
    /// The first token kept.
    base: u64,
    /// The actor's frames of tokens `base..`, as received, row-major.
    actor: Vec<f32>,
    /// The reactor's decoded frames of tokens `base..` (before any clean-up), row-major.
    reactor: Vec<f32>,
}

impl History {
    /// An empty history whose first token will be `token`.
    pub(super) fn starting_at(token: u64) -> Self {
        History {
            base: token,
            ..Default::default()
        }
    }

    /// Keeps the actor frames of the token just encoded.
    pub(super) fn push_actor(&mut self, frames: &[f32]) {
        keep(&mut self.actor, frames);
    }

    /// Keeps the reactor frames of the token just decoded, dropping the oldest token once both
    /// people have more than [`HISTORY_TOKENS`].
    pub(super) fn push_reactor(&mut self, frames: &[f32]) {
        keep(&mut self.reactor, frames);
        let per = frames.len();
        while self.reactor.len() > HISTORY_TOKENS * per && self.actor.len() >= self.reactor.len() {
            self.actor.drain(..per);
            self.reactor.drain(..per);
            self.base += 1;
        }
    }

    /// Bytes held.
    pub(super) fn bytes(&self) -> usize {
        (self.actor.capacity() + self.reactor.capacity()) * std::mem::size_of::<f32>()
    }

    /// Tokens held, when both people's frames cover the same whole tokens ending at token
    /// `tokens` (what every generated and decoded token leaves).
    fn whole_tokens(&self, tokens: u64, token_floats: usize) -> Option<usize> {
        let n = self.reactor.len() / token_floats;
        (self.actor.len() == self.reactor.len()
            && self.reactor.len() == n * token_floats
            && self.base + n as u64 == tokens)
            .then_some(n)
    }

    /// Writes the first token and both people's frames.
    pub(super) fn save(&self, w: &mut SnapshotWriter) {
        w.u64(self.base).f32s(&self.actor).f32s(&self.reactor);
    }

    /// The history [`History::save`] wrote for a stream that has generated (and decoded)
    /// `tokens` tokens of `token_floats` floats of frames each.
    pub(super) fn load(r: &mut SnapshotReader, tokens: u64, token_floats: usize) -> Result<Self> {
        let base = r.u64("the first token of the history")?;
        let held = tokens
            .checked_sub(base)
            .filter(|&n| n <= HISTORY_TOKENS as u64)
            .ok_or_else(|| bad(format!("a history from token {base} after {tokens} tokens")))?;
        let floats = held as usize * token_floats;
        Ok(History {
            base,
            actor: r.f32s_exact("the history's actor frames", floats)?,
            reactor: r.f32s_exact("the history's reactor frames", floats)?,
        })
    }
}

/// Appends a token's `frames` to `held`, which never holds more than `HISTORY_TOKENS + 1`
/// tokens: room for that many is made once, so the history's memory stays fixed.
fn keep(held: &mut Vec<f32>, frames: &[f32]) {
    let most = (HISTORY_TOKENS + 1) * frames.len();
    if held.capacity() < most {
        held.reserve_exact(most - held.len());
    }
    held.extend_from_slice(frames);
}

/// Moves every position of feature rows (`frame_dim` floats each) by `by` on the floor.
pub(super) fn shift_rows(rows: &mut [f32], frame_dim: usize, by: [f64; 2]) {
    for row in rows.chunks_exact_mut(frame_dim) {
        FrameLayout::Features.shift_on_floor(row, by, by);
    }
}

/// `[-x, -z]`.
pub(super) fn negated(v: [f64; 2]) -> [f64; 2] {
    [-v[0], -v[1]]
}

impl Reactor {
    /// Recentring can run on this session: per-token VAE graphs without lookahead.
    pub(super) fn can_recentre(&self) -> Result<()> {
        let m = self.spec();
        if !self.uses_vae_steps()
            || m.vae.encoder.lookahead_frames != 0
            || m.vae.decoder.lookahead_tokens != 0
        {
            return Err(Error::Unsupported(
                "recentring needs the bundle's per-token VAE graphs without lookahead (a session \
                 that runs the VAE over windows cannot recentre)"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// Where the lane's centre should move before its next token: the actor's root (x, z) at the
/// token's first frame, when recentring is on, the history covers the tokens generated (at
/// least one of them, once there are any: turned on mid-stream, it waits for a token), and the
/// root is farther than the distance from the centre.
pub(super) fn due(lane: &Lane, frame_dim: usize) -> Option<[f64; 2]> {
    let setting = lane.session.recentring()?;
    let st = &lane.state;
    let fpt = lane.session.spec().latent.frames_per_token;
    let history = st.history.as_ref()?;
    let held = history.whole_tokens(st.tokens, fpt * frame_dim)?;
    if held == 0 && st.tokens > 0 {
        return None;
    }
    let first = st.tokens * fpt as u64;
    let row = lane.actor_frames(first, first + 1, frame_dim);
    let root = [f64::from(row[POSITIONS]), f64::from(row[POSITIONS + 2])];
    let off = [root[0] - st.centre[0], root[1] - st.centre[1]];
    (off[0].hypot(off[1]) > setting.distance).then_some(root)
}

/// Moves the lane's centre to `centre` and rebuilds its networks' state there (the module's
/// steps), on the lane's working state; the session's cache is set aside for a rollback.
pub(super) fn recentre(nets: &Networks, lane: &mut Lane, centre: [f64; 2]) -> Result<()> {
    let session = lane.session;
    let (dim, lat) = (nets.frame_dim(), nets.latent_dim());
    let m = session.spec();
    let (fpt, scale) = (m.latent.frames_per_token, m.latent.scale);
    let zero = session
        .vae_start
        .as_ref()
        .ok_or_else(|| Error::Unsupported("recentring needs per-token VAE graphs".into()))?;
    let st = &lane.state;
    let history = st.history.as_ref().expect("due() checked the history");
    let tokens = history
        .whole_tokens(st.tokens, fpt * dim)
        .expect("due() checked the history");
    let first = history.base;
    let (mut actor, mut reactor) = (history.actor.clone(), history.reactor.clone());
    shift_rows(&mut actor, dim, negated(centre));
    shift_rows(&mut reactor, dim, negated(centre));
    // 1-2. The VAE's state around the new centre, and the pairs of the kept tokens.
    let (mut vae, mut reactor_vae) = (zero.clone(), zero.clone());
    let mut pairs = Vec::with_capacity(tokens * 2 * lat);
    let mut both = Vec::with_capacity(2 * fpt * dim);
    for k in 0..tokens {
        // Both people's token in one encoder call, a batch of two streams.
        let rows = k * fpt * dim..(k + 1) * fpt * dim;
        both.clear();
        both.extend_from_slice(&actor[rows.clone()]);
        both.extend_from_slice(&reactor[rows]);
        let (means, logvars) = nets.encode_step(&both, &mut [&mut vae, &mut reactor_vae])?;
        let (mean, logvar, b_mean) = (&means[..lat], &logvars[..lat], &means[lat..]);
        let mut a = vec![0f32; lat];
        let xi = session.seeded_noise(first + k as u64).actor;
        actor_token(session, mean, logvar, &xi, &mut a);
        nets.decode_step(b_mean, &mut [&mut vae])?;
        let b: Vec<f32> = b_mean.iter().map(|m| m * scale).collect();
        lane.in_token(check_output("vae_encoder", "recentred actor latent", &a))?;
        lane.in_token(check_output("vae_encoder", "recentred reactor latent", &b))?;
        pairs.extend_from_slice(&a);
        pairs.extend_from_slice(&b);
    }
    check_vae(lane, &vae)?;
    // 3. The context: <sos> at 0, the pair of token k at position k + 1 (where the token loop
    // put it), the newest pair left for the next token to append; no more pairs than the cache
    // holds beside <sos>.
    let mut cache = KvCache::empty(&m.context, session.capacity());
    if lane.state.tokens > 0 {
        let mut feed = session.conditioning().start_token.clone();
        let mut positions = vec![0i64];
        let mut fed = Vec::new();
        let newest = tokens - 1;
        for k in newest - newest.min(session.capacity() - 1)..newest {
            feed.extend_from_slice(&pairs[k * 2 * lat..(k + 1) * 2 * lat]);
            positions.push((first + k as u64 + 1) as i64);
            if nets.io.condition.feedback.is_some() {
                // The pair of token k went in with the placement at token k's last frame.
                let last = ((k + 1) * fpt - 1) * dim..(k + 1) * fpt * dim;
                let placement = feedback::partner_placement(
                    &history.reactor[last.clone()],
                    &history.actor[last],
                );
                fed.push(feedback::conditioning(nets, session, &placement)?);
            }
        }
        let mut modulations = vec![&session.conditioning().modulation];
        if !fed.is_empty() {
            modulations.extend(fed.iter().map(|c| &c.modulation));
        }
        nets.context
            .step(&mut [&mut cache], &feed, &positions, &modulations)?;
    }
    cache.commit();
    lane.set_aside_cache(cache);
    let st = &mut lane.state;
    st.last_pair = match tokens {
        0 => Vec::new(),
        n => pairs[(n - 1) * 2 * lat..].to_vec(),
    };
    st.vae = Some(vae);
    st.centre = centre;
    Ok(())
}

fn check_vae(lane: &Lane, vae: &VaeState) -> Result<()> {
    for (encoder, graph, what) in [
        (true, "vae_encoder", "recentred encoder state"),
        (false, "vae_decoder", "recentred decoder state"),
    ] {
        let (bad, total) = vae.non_finite(encoder);
        lane.in_token(check_output_counted(graph, what, bad, total))?;
    }
    Ok(())
}
