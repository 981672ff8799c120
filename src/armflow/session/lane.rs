//! [`Lane`]: one stream's part in a step of the token loop (`lanes.rs`) — its session and a
//! working copy of its state, committed only when the whole step succeeds — and the actor
//! token its posterior gives. Recentring (`recentre.rs`) rebuilds a lane; the loop advances it.

use super::{Reactor, StepOutput, StreamState, TokenTrace};
use crate::armflow::kv_cache::KvCache;
use crate::armflow::spec::{ActorLatent, ArmFlowSpec};
use crate::shared::error::{Error, Result};

/// One stream's part in a step.
pub(super) struct Lane<'s> {
    pub(super) session: &'s Reactor,
    /// The session's index in a batched call (for messages); `None` when stepped alone.
    pub(super) index: Option<usize>,
    /// Committed to the session only when the whole step succeeds.
    pub(super) state: StreamState,
    /// Reactor frames produced so far in this step, row-major.
    pub(super) frames: Vec<f32>,
    pub(super) tokens: Vec<TokenTrace>,
    /// The session's cache, when recentring replaced the lane's during the step: what a failed
    /// step gives back (rolled back), since the replacement never was the session's.
    set_aside: Option<KvCache>,
}

impl<'s> Lane<'s> {
    /// A lane over `session` that owns `cache`, the session's cache moved out for the step (so
    /// the step writes it in place rather than into a copy).
    pub(super) fn new(session: &'s Reactor, index: Option<usize>, cache: KvCache) -> Self {
        let mut state = session.state().clone();
        state.cache = cache;
        Self {
            session,
            index,
            state,
            frames: Vec::new(),
            tokens: Vec::new(),
            set_aside: None,
        }
    }

    /// Replaces the lane's cache by `cache` (recentring), keeping the session's own for a
    /// rollback.
    pub(super) fn set_aside_cache(&mut self, cache: KvCache) {
        let old = std::mem::replace(&mut self.state.cache, cache);
        self.set_aside.get_or_insert(old);
    }

    /// The lane's cache with this step's writes undone, to give back to a session whose step
    /// failed.
    pub(super) fn rolled_back_cache(self) -> KvCache {
        let mut cache = self.set_aside.unwrap_or(self.state.cache);
        cache.rollback();
        cache
    }

    /// Splits the lane into the state to commit (its cache's writes not yet committed), what
    /// the step returns, and the session's cache if recentring set it aside (what to give back,
    /// rolled back, if the step fails after all).
    pub(super) fn finish(self, frame_dim: usize) -> (StreamState, StepOutput, Option<KvCache>) {
        let n = self.frames.len() / frame_dim;
        let frames =
            ndarray::Array2::from_shape_vec((n, frame_dim), self.frames).expect("whole frames");
        let output = StepOutput {
            frames,
            tokens: self.tokens,
        };
        (self.state, output, self.set_aside)
    }

    pub(super) fn spec(&self) -> &'s ArmFlowSpec {
        self.session.spec()
    }

    /// Whether the frames received cover the next token (and the encoder's lookahead).
    pub(super) fn token_ready(&self) -> bool {
        let m = self.spec();
        let fpt = m.latent.frames_per_token as u64;
        let st = &self.state;
        st.frames_received >= (st.tokens + 1) * fpt + m.vae.encoder.lookahead_frames as u64
    }

    /// Whether a generated token waits to be decoded (its lookahead tokens exist).
    pub(super) fn decode_due(&self) -> bool {
        let m = self.spec();
        let fpt = m.latent.frames_per_token as u64;
        let st = &self.state;
        st.tokens > st.frames_emitted / fpt + m.vae.decoder.lookahead_tokens as u64
    }

    /// A failed output check of this lane's current token, with the session and token named.
    pub(super) fn in_token(&self, checked: Result<()>) -> Result<()> {
        checked.map_err(|e| match e {
            Error::Inference { graph, message } => {
                let whose = self
                    .index
                    .map_or(String::new(), |i| format!("session {i}: "));
                Error::Inference {
                    graph,
                    message: format!(
                        "{whose}token {}: {message}; the session is unchanged",
                        self.state.tokens
                    ),
                }
            }
            other => other,
        })
    }

    /// Actor frames `[start, end)` (absolute indices), row-major.
    pub(super) fn actor_frames(&self, start: u64, end: u64, dim: usize) -> &[f32] {
        let base = self.state.actor_base;
        &self.state.actor_frames[(start - base) as usize * dim..(end - base) as usize * dim]
    }
}

/// An actor token from its posterior, as the session's setting says: the sample
/// `(mean + sqrt(exp(logvar)) * xi) * scale`, or `mean * scale`.
pub(super) fn actor_token(
    session: &Reactor,
    mean: &[f32],
    logvar: &[f32],
    xi: &[f32],
    out: &mut [f32],
) {
    let scale = session.spec().latent.scale;
    for (((a, m), lv), x) in out.iter_mut().zip(mean).zip(logvar).zip(xi) {
        *a = match session.actor_latent() {
            ActorLatent::Sample => (m + lv.exp().sqrt() * x) * scale,
            ActorLatent::Mean => m * scale,
        };
    }
}
