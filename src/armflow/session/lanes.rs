//! The token loop, for one stream or many at once.
//!
//! Every stream taking part in a step is a [`Lane`]: its session (settings, conditioning) and a
//! working copy of its state. The loop runs in rounds; each round generates the next token of
//! every lane that has the frames for one, with one network call per graph for all of them, so
//! the weights are read once per round however many streams there are. A single
//! A session's step ([`crate::Session::step`]) is a batch of one lane through the same code.
//!
//! Every token's actor latent, context, reactor latent, VAE state and decoded frames are checked
//! to be finite before the loop goes on: extreme settings or inputs can overflow a network, and
//! a non-finite value must fail the step (leaving the session as it was) rather than be returned
//! or carried into the next token.

use super::feedback;
use super::lane::{actor_token, Lane};
use super::recentre::{self, negated, shift_rows};
use super::{Reactor, TokenNoise, TokenTrace};
use crate::armflow::meanflow::guided;
use crate::armflow::networks::{Networks, VaeState};

use crate::shared::checks::{check_output, check_output_counted};
use crate::shared::error::Result;

/// Appends each lane's new actor frames (`chunks[i]`, already validated) and generates and
/// decodes every token they complete.
pub(super) fn advance(nets: &Networks, lanes: &mut [Lane], chunks: &[&[f32]]) -> Result<()> {
    let dim = nets.frame_dim();
    for (lane, chunk) in lanes.iter_mut().zip(chunks) {
        lane.state.actor_frames.extend_from_slice(chunk);
        lane.state.frames_received += (chunk.len() / dim) as u64;
    }
    loop {
        let mut ready: Vec<&mut Lane> = lanes.iter_mut().filter(|l| l.token_ready()).collect();
        if ready.is_empty() {
            break;
        }
        for lane in ready.iter_mut() {
            if let Some(centre) = recentre::due(lane, dim) {
                recentre::recentre(nets, lane, centre)?;
            }
        }
        generate_tokens(nets, &mut ready)?;
        loop {
            let mut due: Vec<&mut Lane> = lanes.iter_mut().filter(|l| l.decode_due()).collect();
            if due.is_empty() {
                break;
            }
            decode_tokens(nets, &mut due)?;
        }
    }
    for lane in lanes {
        lane.state.trim(lane.session.spec(), dim);
    }
    Ok(())
}

/// The next token of every lane: actor posterior, context, MeanFlow.
fn generate_tokens(nets: &Networks, lanes: &mut [&mut Lane]) -> Result<()> {
    let lat = nets.latent_dim();
    let noise: Vec<TokenNoise> = lanes
        .iter_mut()
        .map(|l| {
            let j = l.state.tokens;
            l.state
                .injected
                .pop_front()
                .unwrap_or_else(|| l.session.seeded_noise(j))
        })
        .collect();

    // 1. actor tokens `(mean + sqrt(exp(logvar)) * xi) * scale`, or `mean * scale`
    let (mean, logvar) = posteriors(nets, lanes)?;
    let mut actor = vec![0f32; lanes.len() * lat];
    for (i, lane) in lanes.iter().enumerate() {
        let row = i * lat..(i + 1) * lat;
        actor_token(
            lane.session,
            &mean[row.clone()],
            &logvar[row.clone()],
            &noise[i].actor,
            &mut actor[row],
        );
    }

    for (i, lane) in lanes.iter().enumerate() {
        let latent = &actor[i * lat..(i + 1) * lat];
        lane.in_token(check_output("vae_encoder", "actor latent", latent))?;
        if let Some(vae) = &lane.state.vae {
            let (bad, total) = vae.non_finite(true);
            lane.in_token(check_output_counted(
                "vae_encoder",
                "encoder state",
                bad,
                total,
            ))?;
        }
    }

    // 2. context over [<sos>, pairs...]: append token j (<sos> or the last pair) to each cache
    let sessions: Vec<&Reactor> = lanes.iter().map(|l| l.session).collect();
    let mut tokens = Vec::new();
    let mut positions = Vec::with_capacity(lanes.len());
    for lane in lanes.iter_mut() {
        let j = lane.state.tokens;
        tokens.extend_from_slice(if j == 0 {
            &lane.session.conditioning().start_token
        } else {
            &lane.state.last_pair
        });
        positions.push(j as i64);
    }
    // A feedback bundle's token after the first is conditioned on where the reactor stands.
    let fed = lanes
        .iter()
        .map(|l| {
            let fed = nets.io.condition.feedback.is_some() && l.state.tokens > 0;
            fed.then(|| feedback::conditioning(nets, l.session, &l.state.feedback))
                .transpose()
        })
        .collect::<Result<Vec<_>>>()?;
    let modulations: Vec<_> = sessions
        .iter()
        .zip(&fed)
        .map(|(s, f)| &f.as_ref().unwrap_or(s.conditioning()).modulation)
        .collect();
    let mut caches: Vec<_> = lanes.iter_mut().map(|l| &mut l.state.cache).collect();
    let context = nets
        .context
        .step(&mut caches, &tokens, &positions, &modulations)?;

    // 3. MeanFlow from the noise
    let z: Vec<f32> = noise
        .iter()
        .flat_map(|n| n.reactor.iter().copied())
        .collect();
    let reactor = sample(nets, &sessions, &actor, &context, z)?;

    let c = context.len() / lanes.len();
    for (i, lane) in lanes.iter().enumerate() {
        let (ci, bi) = (
            &context[i * c..(i + 1) * c],
            &reactor[i * lat..(i + 1) * lat],
        );
        lane.in_token(check_output("context_layers", "context", ci))?;
        lane.in_token(check_output("velocity", "reactor latent", bi))?;
    }
    let (dim, fpt) = (nets.frame_dim(), nets.spec.latent.frames_per_token as u64);
    for (i, lane) in lanes.iter_mut().enumerate() {
        let (a, b) = (
            &actor[i * lat..(i + 1) * lat],
            &reactor[i * lat..(i + 1) * lat],
        );
        let st = &mut lane.state;
        if let Some(history) = &mut st.history {
            // The token's actor frames, as received (`Lane::actor_frames`, borrowed apart).
            let from = (st.tokens * fpt - st.actor_base) as usize * dim;
            history.push_actor(&st.actor_frames[from..from + fpt as usize * dim]);
        }
        st.last_pair = [a, b].concat();
        st.reactor_latents.push_back(b.to_vec());
        lane.tokens.push(TokenTrace {
            index: st.tokens,
            actor_latent: a.to_vec(),
            reactor_latent: b.to_vec(),
            context: context[i * c..(i + 1) * c].to_vec(),
        });
        st.tokens += 1;
    }
    Ok(())
}

/// The posterior `(mean, logvar)` of each lane's next actor token, `[lanes, latent_dim]` each:
/// one encoder step for all lanes that stream the VAE, a window for each lane that does not.
fn posteriors(nets: &Networks, lanes: &mut [&mut Lane]) -> Result<(Vec<f32>, Vec<f32>)> {
    let (dim, lat) = (nets.frame_dim(), nets.latent_dim());
    let mut mean = vec![0f32; lanes.len() * lat];
    let mut logvar = vec![0f32; lanes.len() * lat];
    let fpt = nets.spec.latent.frames_per_token as u64;
    let token_start = |l: &Lane| l.state.tokens * fpt;

    let stepping: Vec<usize> = (0..lanes.len())
        .filter(|&i| lanes[i].state.vae.is_some())
        .collect();
    if !stepping.is_empty() {
        let mut frames = Vec::with_capacity(stepping.len() * fpt as usize * dim);
        for &i in &stepping {
            let first = token_start(lanes[i]);
            let from = frames.len();
            frames.extend_from_slice(lanes[i].actor_frames(first, first + fpt, dim));
            // The networks see positions less the centre (recentring; zero otherwise).
            shift_rows(&mut frames[from..], dim, negated(lanes[i].state.centre));
        }
        let mut states: Vec<&mut VaeState> = lanes
            .iter_mut()
            .filter_map(|l| l.state.vae.as_mut())
            .collect();
        let (m, lv) = nets.encode_step(&frames, &mut states)?;
        for (row, &i) in stepping.iter().enumerate() {
            mean[i * lat..(i + 1) * lat].copy_from_slice(&m[row * lat..(row + 1) * lat]);
            logvar[i * lat..(i + 1) * lat].copy_from_slice(&lv[row * lat..(row + 1) * lat]);
        }
    }
    for (i, lane) in lanes.iter().enumerate() {
        if lane.state.vae.is_some() {
            continue;
        }
        let enc = &lane.spec().vae.encoder;
        let first = token_start(lane);
        let start = first.saturating_sub(enc.context_frames as u64);
        let end = first + fpt + enc.lookahead_frames as u64;
        let (m, lv) = nets.encode(lane.actor_frames(start, end, dim))?;
        let row = (first - start) as usize / fpt as usize * lat;
        mean[i * lat..(i + 1) * lat].copy_from_slice(&m[row..row + lat]);
        logvar[i * lat..(i + 1) * lat].copy_from_slice(&lv[row..row + lat]);
    }
    Ok((mean, logvar))
}

/// MeanFlow for every lane at once, `z <- z - (tau_k - tau_{k+1}) * u(z, tau_{k+1}, tau_k)`, each
/// lane with its own steps and CFG scale. A guided lane adds a null row right after its
/// conditional row (zero actor token and context): `u = u_null + s * (u_cond - u_null)`.
fn sample(
    nets: &Networks,
    sessions: &[&Reactor],
    actor: &[f32],
    context: &[f32],
    mut z: Vec<f32>,
) -> Result<Vec<f32>> {
    let lat = nets.latent_dim();
    let c = context.len() / sessions.len();
    let most_steps = sessions.iter().map(|s| s.steps()).max().unwrap_or(0);
    for k in 0..most_steps as usize {
        let (mut a, mut noisy, mut ctx, mut r, mut t) = (vec![], vec![], vec![], vec![], vec![]);
        let active = |s: &&Reactor| k < s.steps() as usize;
        for (i, s) in sessions.iter().enumerate().filter(|(_, s)| active(s)) {
            let rows = if guided(s.cfg_scale()) { 2 } else { 1 };
            for row in 0..rows {
                if row == 0 {
                    a.extend_from_slice(&actor[i * lat..(i + 1) * lat]);
                    ctx.extend_from_slice(&context[i * c..(i + 1) * c]);
                } else {
                    a.resize(a.len() + lat, 0.0);
                    ctx.resize(ctx.len() + c, 0.0);
                }
                noisy.extend_from_slice(&z[i * lat..(i + 1) * lat]);
                r.push(s.grid()[k + 1]);
                t.push(s.grid()[k]);
            }
        }
        let u = nets.velocity(&a, &noisy, &ctx, &r, &t)?;
        let mut row = 0;
        for (i, s) in sessions.iter().enumerate().filter(|(_, s)| active(s)) {
            let scale = s.cfg_scale();
            let dt = s.grid()[k] - s.grid()[k + 1];
            let cond = &u[row * lat..(row + 1) * lat];
            let zi = &mut z[i * lat..(i + 1) * lat];
            if guided(scale) {
                let null = &u[(row + 1) * lat..(row + 2) * lat];
                for ((zv, uc), un) in zi.iter_mut().zip(cond).zip(null) {
                    *zv -= dt * (un + scale * (uc - un));
                }
                row += 2;
            } else {
                for (zv, uc) in zi.iter_mut().zip(cond) {
                    *zv -= dt * uc;
                }
                row += 1;
            }
        }
    }
    Ok(z)
}

/// Decodes the oldest undecoded token of every lane: one decoder step for all lanes that stream
/// the VAE, a window for each lane that does not.
fn decode_tokens(nets: &Networks, lanes: &mut [&mut Lane]) -> Result<()> {
    let (dim, fpt) = (nets.frame_dim(), nets.spec.latent.frames_per_token);
    let next = |l: &Lane| l.state.frames_emitted / fpt as u64;
    let latent = |l: &Lane, k: u64| -> Vec<f32> {
        let scale = l.spec().latent.scale;
        l.state.reactor_latents[(k - l.state.reactor_base) as usize]
            .iter()
            .map(|v| v / scale)
            .collect()
    };
    let stepping: Vec<usize> = (0..lanes.len())
        .filter(|&i| lanes[i].state.vae.is_some())
        .collect();
    if !stepping.is_empty() {
        let latents: Vec<f32> = stepping
            .iter()
            .flat_map(|&i| latent(lanes[i], next(lanes[i])))
            .collect();
        let mut states: Vec<&mut VaeState> = lanes
            .iter_mut()
            .filter_map(|l| l.state.vae.as_mut())
            .collect();
        let frames = nets.decode_step(&latents, &mut states)?;
        let per = fpt * dim;
        for (row, &i) in stepping.iter().enumerate() {
            let lane = &mut lanes[i];
            let mine = &frames[row * per..(row + 1) * per];
            lane.in_token(check_output("vae_decoder", "decoded frames", mine))?;
            if let Some(vae) = &lane.state.vae {
                let (bad, total) = vae.non_finite(false);
                lane.in_token(check_output_counted(
                    "vae_decoder",
                    "decoder state",
                    bad,
                    total,
                ))?;
            }
            // Back from the networks' frame to the stream's (recentring; zero otherwise).
            let from = lane.frames.len();
            lane.frames.extend_from_slice(mine);
            shift_rows(&mut lane.frames[from..], dim, lane.state.centre);
            if let Some(history) = &mut lane.state.history {
                history.push_reactor(&lane.frames[from..]);
            }
        }
    }
    for lane in lanes.iter_mut() {
        if lane.state.vae.is_none() {
            let dec = &lane.spec().vae.decoder;
            let k = next(lane);
            let start = k.saturating_sub(dec.context_tokens as u64);
            let end = k + 1 + dec.lookahead_tokens as u64;
            let latents: Vec<f32> = (start..end).flat_map(|j| latent(lane, j)).collect();
            let motion = nets.decode(&latents)?;
            let row = (k - start) as usize * fpt * dim;
            let mine = &motion[row..row + fpt * dim];
            lane.in_token(check_output("vae_decoder", "decoded frames", mine))?;
            lane.frames.extend_from_slice(mine);
        }
        if nets.io.condition.feedback.is_some() {
            // The token's last frame, both people in the stream's frame.
            let last = lane.state.frames_emitted + fpt as u64 - 1;
            let reactor = &lane.frames[lane.frames.len() - dim..];
            let fed = feedback::partner_placement(reactor, lane.actor_frames(last, last + 1, dim));
            lane.state.feedback = fed;
        }
        lane.state.frames_emitted += fpt as u64;
    }
    Ok(())
}
