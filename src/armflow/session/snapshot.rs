//! A reactor's snapshot: its settings and everything its stream has accumulated, written field
//! by field (`shared/snapshot.rs` frames and checks the bytes), and read back into a reactor
//! that continues bit for bit.
//!
//! Restoring builds a fresh reactor from the saved settings, so every setting is checked as a
//! new session checks it (and the conditioning is recomputed from the saved condition, exactly
//! as the saved session computed it), then puts the stream back. The stream's counts are checked
//! against each other (tokens against frames received, latents against frames sent, the cache
//! against tokens) before anything sized by them is read: a snapshot that passes its checksum
//! but lies cannot drive the token loop out of its invariants.

use std::collections::VecDeque;
use std::sync::Arc;

use super::recentre::History;
use super::{Reactor, ReactorOptions, Recentring, StreamState, TokenNoise};
use crate::armflow::kv_cache::KvCache;
use crate::armflow::networks::{Networks, VaeState};
use crate::armflow::spec::ActorLatent;
use crate::motion::world::MAX_WORLD_METRES;
use crate::shared::error::Result;
use crate::shared::limits::LIMITS;
use crate::shared::snapshot::{bad, SnapshotReader, SnapshotWriter};

impl Reactor {
    /// Writes the reactor's snapshot payload (`Session::snapshot` frames it).
    pub(crate) fn save(&self, w: &mut SnapshotWriter) -> Result<()> {
        let s = &self.settings;
        w.u64(s.seed).u32(s.steps).f32(s.cfg_scale);
        w.bool(s.condition.is_some());
        if let Some(c) = &s.condition {
            w.f32s(c);
        }
        w.u64(s.capacity as u64).u32(match s.actor_latent {
            ActorLatent::Sample => 0,
            ActorLatent::Mean => 1,
        });
        w.bool(s.recentring.is_some());
        if let Some(r) = &s.recentring {
            w.f64(r.distance);
        }
        w.bool(self.uses_vae_steps());
        self.state
            .save(w, self.nets.io.condition.feedback.is_some())
    }

    /// The reactor a snapshot's payload holds, over `nets` (the model the snapshot was checked
    /// to come from).
    pub(crate) fn restore(nets: Arc<Networks>, r: &mut SnapshotReader) -> Result<Self> {
        let seed = r.u64("the seed")?;
        let steps = r.u32("the steps")?;
        let cfg_scale = r.f32("the CFG scale")?;
        let condition = if r.bool("whether a condition is set")? {
            Some(r.f32s("the condition", nets.io.condition.dim)?)
        } else {
            None
        };
        let capacity = r.count("the context capacity", LIMITS.max_context_capacity as usize)?;
        let actor_latent = match r.u32("the actor latent")? {
            0 => ActorLatent::Sample,
            1 => ActorLatent::Mean,
            v => return Err(bad(format!("actor latent {v}"))),
        };
        let recentring = if r.bool("whether recentring is on")? {
            Some(Recentring {
                distance: r.f64("the recentring distance")?,
            })
        } else {
            None
        };
        let vae_steps = r.bool("whether the VAE runs in steps")?;
        if vae_steps && nets.vae_state().is_none() {
            return Err(bad("VAE steps, which this bundle does not have"));
        }
        let options = ReactorOptions {
            seed,
            steps: Some(steps),
            cfg_scale: Some(cfg_scale),
            condition,
            context_capacity: Some(capacity),
            actor_latent: Some(actor_latent),
            vae_windows: !vae_steps,
            recentring,
            ..ReactorOptions::default()
        };
        let mut reactor = Reactor::new(nets, options)?;
        reactor.state = StreamState::load(&reactor, r)?;
        Ok(reactor)
    }
}

impl StreamState {
    /// Writes the stream (between steps: the cache is committed); `fed`: the bundle feeds the
    /// reactor's placement back.
    fn save(&self, w: &mut SnapshotWriter, fed: bool) -> Result<()> {
        w.u64(self.frames_received).u64(self.actor_base);
        w.f32s(&self.actor_frames);
        w.u64(self.tokens);
        self.cache.save(w);
        w.f32s(&self.last_pair);
        w.u64(self.reactor_base)
            .u64(self.reactor_latents.len() as u64);
        for latent in &self.reactor_latents {
            w.f32s(latent);
        }
        w.u64(self.frames_emitted);
        w.u64(self.injected.len() as u64);
        for noise in &self.injected {
            w.f32s(&noise.actor).f32s(&noise.reactor);
        }
        w.bool(self.vae.is_some());
        if let Some(vae) = &self.vae {
            vae.save(w)?;
        }
        w.f64(self.centre[0]).f64(self.centre[1]);
        if let Some(history) = &self.history {
            history.save(w);
        }
        if fed {
            w.f32s(&self.feedback);
        }
        Ok(())
    }

    /// The stream [`StreamState::save`] wrote, for `reactor` (restored with the saved settings).
    fn load(reactor: &Reactor, r: &mut SnapshotReader) -> Result<Self> {
        let m = reactor.spec();
        let (dim, lat) = (reactor.frame_dim(), reactor.latent_dim());
        let fpt = m.latent.frames_per_token as u64;
        let steps = reactor.uses_vae_steps();
        // What the token loop and `trim` leave after every step, from the frames received.
        let received = r.u64("the frames received")?;
        let tokens_due = received.saturating_sub(m.vae.encoder.lookahead_frames as u64) / fpt;
        let decoded = tokens_due.saturating_sub(m.vae.decoder.lookahead_tokens as u64);
        let (context_frames, context_tokens) = if steps {
            (0, 0)
        } else {
            (
                m.vae.encoder.context_frames as u64,
                m.vae.decoder.context_tokens as u64,
            )
        };
        let actor_base = r.u64("the first actor frame held")?;
        if actor_base != (tokens_due * fpt).saturating_sub(context_frames) {
            return Err(bad(format!(
                "actor frames held from {actor_base}, after {received} frames received"
            )));
        }
        let held = ((received - actor_base) as usize)
            .checked_mul(dim)
            .ok_or_else(|| bad("actor frames held"))?;
        let actor_frames = r.f32s_exact("the actor frames held", held)?;
        let tokens = r.u64("the tokens generated")?;
        if tokens != tokens_due {
            return Err(bad(format!(
                "{tokens} tokens generated after {received} frames received (not {tokens_due})"
            )));
        }
        let cache = KvCache::load(&m.context, reactor.settings.capacity, r)?;
        if !cache.holds_tokens(tokens) {
            return Err(bad(format!(
                "the context cache does not hold what {tokens} tokens leave"
            )));
        }
        let last_pair = r.f32s_exact(
            "the last pair of tokens",
            if tokens == 0 { 0 } else { 2 * lat },
        )?;
        let reactor_base = r.u64("the first reactor latent held")?;
        if reactor_base != decoded.saturating_sub(context_tokens) {
            return Err(bad(format!(
                "reactor latents held from {reactor_base}, after {tokens} tokens"
            )));
        }
        let n = r.count("the reactor latents held", (tokens - reactor_base) as usize)?;
        if n as u64 != tokens - reactor_base {
            return Err(bad(format!(
                "{n} reactor latents held, not {}",
                tokens - reactor_base
            )));
        }
        let reactor_latents = (0..n)
            .map(|_| r.f32s_exact("a reactor latent", lat))
            .collect::<Result<VecDeque<_>>>()?;
        let frames_emitted = r.u64("the frames sent")?;
        if frames_emitted != decoded * fpt {
            return Err(bad(format!(
                "{frames_emitted} frames sent after {tokens} tokens"
            )));
        }
        let queued = r.count("the queued noise", LIMITS.max_queued_noise_tokens as usize)?;
        let injected = (0..queued)
            .map(|_| {
                Ok(TokenNoise {
                    actor: r.f32s_exact("queued actor noise", lat)?,
                    reactor: r.f32s_exact("queued reactor noise", lat)?,
                })
            })
            .collect::<Result<VecDeque<_>>>()?;
        let vae = match (r.bool("whether a VAE state is held")?, &reactor.vae_start) {
            (true, Some(zero)) => Some(VaeState::load(zero, r)?),
            (false, None) => None,
            _ => return Err(bad("a VAE state that disagrees with the VAE's mode")),
        };
        let centre = [r.finite("the centre")?, r.finite("the centre")?];
        if centre.iter().any(|c| c.abs() > MAX_WORLD_METRES) {
            return Err(bad(format!(
                "a centre {centre:?} beyond {MAX_WORLD_METRES} m"
            )));
        }
        // Recentring (checked on when the settings were restored) keeps a history; nothing else.
        let history = match reactor.settings.recentring {
            Some(_) => Some(History::load(r, tokens, fpt as usize * dim)?),
            None => None,
        };
        // A feedback bundle's placement (only its streams write one): a relative offset on the
        // floor and a unit facing, zeros before the first token is decoded.
        let mut feedback = [0f32; super::feedback::DIM];
        if reactor.nets.io.condition.feedback.is_some() {
            let read = r.f32s_exact("the fed-back placement", feedback.len())?;
            feedback.copy_from_slice(&read);
            let offset = f64::from(read[1]).hypot(f64::from(read[2]));
            let facing = f64::from(read[3]).hypot(f64::from(read[4]));
            let plausible = if decoded == 0 {
                read.iter().all(|&v| v == 0.0)
            } else {
                // (a degenerate decoded body has no facing: zero)
                read[0] == 1.0 && offset <= 2.0 * MAX_WORLD_METRES && facing <= 1.0 + 1e-3
            };
            if !plausible {
                return Err(bad(format!(
                    "a fed-back placement {read:?} after {decoded} tokens decoded"
                )));
            }
        }
        Ok(StreamState {
            feedback,
            history,
            centre,
            frames_received: received,
            actor_frames,
            actor_base,
            tokens,
            cache,
            last_pair,
            reactor_latents,
            reactor_base,
            frames_emitted,
            injected,
            vae,
        })
    }
}
