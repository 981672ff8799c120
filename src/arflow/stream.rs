//! ARFlow's online variant as a stream, [`OnlineStream`] (also boxed in a [`crate::Session`]):
//! the actor's frames in, the reactor's out, each frame as soon as it arrives.
//!
//! With the causal network, frame `n` of every step's x̂_1 depends only on frames ≤ `n` of that
//! step's `x`, and the guidance and the update act frame by frame. So a stream runs the whole
//! sampler for each new frame: for step `m`, the bundle's one-frame graph sees the frame's
//! `x_m` with the keys and values its self-attention computed for the earlier frames at step
//! `m` (one cache per step), and the sampler's update (`sampler::euler_step`) moves it on. The
//! reactor's frame `n` is out with the actor's frame `n`: no algorithmic latency.
//!
//! With η = 0 and σ = 0 a stream gives what `Arflow::generate` gives for the whole
//! clip (tested). The draws differ: a stream draws per frame (frame `n`'s start noise is token
//! `n (M + 1)`, its step `m`'s ε token `n (M + 1) + m + 1`), the whole-clip sampler per step.
//! The position encoding covers `model.max_frames` frames: a stream ends there (reset it).
//!
//! Crowds of streams run each step of each round's frame as one batch, shorter caches padded.

use std::sync::Arc;

use ndarray::Array2;

use super::networks::Networks;
use super::sampler::{euler_step, loss_of, times};
use super::spec::{ArflowSampling, Mixing, FRAME_DIM};
use crate::family::session::Session;
use crate::family::stream::{
    downcast_all, Capabilities, Capability, Finish, StepOutput, StepTogether, Stream,
};
use crate::shared::bundle_io::BundleIo;
use crate::shared::checks::check_frames;
use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, LIMITS};
use crate::shared::noise::{fill_normals, NormalSource};
use crate::shared::snapshot::{self, SnapshotReader, SnapshotWriter};

/// One actor/reactor stream over an online `arflow` model (made by `Arflow::online`, or boxed
/// in a [`crate::Session`] by `Model::session`). `Send`, not `Sync`.
#[derive(Debug)]
pub struct OnlineStream {
    nets: Arc<Networks>,
    sampling: ArflowSampling,
    seed: u64,
    /// Frames received (and sent).
    frames: u64,
    /// Per step: the earlier frames' keys and values, frame-major `[n, L, H, W/H]`.
    keys: Vec<Vec<f32>>,
    values: Vec<Vec<f32>>,
    /// Normals the caller queued ([`crate::Session::queue_normals`]), and how many are taken.
    queued: Vec<f32>,
    queued_used: usize,
}

impl OnlineStream {
    /// A fresh stream; fails unless the bundle streams (the online variant with its one-frame
    /// graph) and the settings are in range.
    pub(crate) fn new(nets: Arc<Networks>, sampling: ArflowSampling, seed: u64) -> Result<Self> {
        if !nets.streams() {
            return Err(Error::InvalidInput(format!(
                "bundle `{}` is not ARFlow's online variant with a denoiser_step graph: it \
                 generates whole clips (Arflow::generate), it does not stream",
                nets.io.name
            )));
        }
        sampling.validate().map_err(Error::InvalidOption)?;
        let steps = sampling.steps;
        Ok(Self {
            nets,
            sampling,
            seed,
            frames: 0,
            keys: vec![Vec::new(); steps],
            values: vec![Vec::new(); steps],
            queued: Vec::new(),
            queued_used: 0,
        })
    }

    /// This frame's draws, in order: the start noise when σ > 0, then one ε per step when
    /// η > 0 (token `frames (M + 1) + k` of the seed's stream, or the next queued normals).
    fn frame_draws(&mut self, s: &ArflowSampling) -> Result<Vec<Vec<f32>>> {
        let tokens = s.steps as u64 + 1;
        let start = (s.sigma > 0.0).then_some(0);
        let steps = (s.eta > 0.0).then_some(1..tokens).into_iter().flatten();
        start
            .into_iter()
            .chain(steps)
            .map(|k| {
                if self.queued_used == self.queued.len() {
                    let mut e = vec![0f32; FRAME_DIM];
                    fill_normals(self.seed, self.frames * tokens + k, s.stream, &mut e);
                    return Ok(e);
                }
                let mut queue = NormalSource::Queue {
                    normals: &self.queued,
                    used: self.queued_used,
                    draws: k as usize,
                };
                let e = queue.draw(FRAME_DIM)?;
                self.queued_used = queue.used();
                Ok(e)
            })
            .collect()
    }

    /// Floats of one frame's keys (or values) over the layers.
    fn kv_floats(&self) -> usize {
        let m = &self.nets.spec.model;
        m.layers * m.width
    }

    /// The bundle's settings.
    pub(crate) fn bundle_sampling(&self) -> &ArflowSampling {
        &self.nets.spec.sampler
    }

    /// The settings in force.
    pub(crate) fn sampling(&self) -> &ArflowSampling {
        &self.sampling
    }

    /// Replaces the settings; the step count only before the first frame or after a reset.
    pub(crate) fn set_sampling(&mut self, sampling: ArflowSampling) -> Result<()> {
        sampling.validate().map_err(Error::InvalidOption)?;
        if sampling.steps != self.sampling.steps {
            if self.frames > 0 {
                return Err(Error::InvalidInput(
                    "an ARFlow stream's step count changes before its first frame or after a \
                     reset (each step keeps its own cache)"
                        .into(),
                ));
            }
            self.keys = vec![Vec::new(); sampling.steps];
            self.values = vec![Vec::new(); sampling.steps];
        }
        self.sampling = sampling;
        Ok(())
    }

    pub(crate) fn frames(&self) -> u64 {
        self.frames
    }

    /// The stream's snapshot (`Session::snapshot`): its settings, seed, frame count, every
    /// step's cache and the queued normals not yet taken.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        let s = &self.sampling;
        w.u64(s.steps as u64)
            .f32(s.guidance)
            .f32(s.weight)
            .f32(s.eta)
            .f32(s.d_safe)
            .bool(s.squared)
            .bool(s.guided_backprojection)
            .bool(s.mixing == Mixing::VariancePreserving)
            .f32(s.sigma)
            .u32(s.stream);
        w.u64(self.seed).u64(self.frames);
        for (k, v) in self.keys.iter().zip(&self.values) {
            w.f32s(k).f32s(v);
        }
        w.f32s(&self.queued[self.queued_used..]);
    }

    /// The stream a snapshot's payload holds, over `nets` (the model it was checked to come
    /// from): the settings checked as a new stream's, each cache of exactly the frames' size.
    pub(crate) fn restore(nets: Arc<Networks>, r: &mut SnapshotReader) -> Result<Self> {
        let steps = r.count("the steps", LIMITS.max_steps as usize)?;
        let sampling = ArflowSampling {
            steps,
            guidance: r.f32("the guidance")?,
            weight: r.f32("the weight")?,
            eta: r.f32("the eta")?,
            d_safe: r.f32("the safe distance")?,
            squared: r.bool("the hinge")?,
            guided_backprojection: r.bool("the back-projection")?,
            mixing: if r.bool("the mixing")? {
                Mixing::VariancePreserving
            } else {
                Mixing::Linear
            },
            sigma: r.f32("the start noise")?,
            stream: r.u32("the noise stream")?,
        };
        let seed = r.u64("the seed")?;
        let mut stream = Self::new(nets, sampling, seed)?;
        let frames = r.u64("the frames")?;
        let end = stream.nets.spec.model.max_frames as u64;
        if frames > end {
            return Err(snapshot::bad(format!(
                "{frames} frames, beyond the stream's end at {end}"
            )));
        }
        stream.frames = frames;
        let floats = frames as usize * stream.kv_floats();
        for m in 0..steps {
            stream.keys[m] = r.f32s_exact("a step's keys", floats)?;
            stream.values[m] = r.f32s_exact("a step's values", floats)?;
        }
        stream.queued = r.f32s("the queued normals", LIMITS.max_tensor_elements as usize)?;
        Ok(stream)
    }

    /// Checks one call's actor frames against the stream's end.
    fn check(&self, actor: &[f32]) -> Result<()> {
        check_frames("actor frames", actor, FRAME_DIM)?;
        let end = self.nets.spec.model.max_frames as u64;
        let n = (actor.len() / FRAME_DIM) as u64;
        if self.frames + n > end {
            return Err(Error::InvalidInput(format!(
                "bundle `{}` streams {end} frames (its position encoding's length); this stream \
                 has {} and was given {n} more: reset it",
                self.nets.io.name, self.frames
            )));
        }
        Ok(())
    }
}

/// Advances streams of one model: `actor[i]` goes to `streams[i]`; entry `i` of the result is
/// its reactor frames `[n_i, 262]`. Round `r` runs every stream's `r`-th new frame, each step one
/// batch. On error every stream is as it was (caches cut back to their length before the call).
pub(crate) fn advance(
    streams: &mut [&mut OnlineStream],
    actor: &[&[f32]],
    finish: Finish<'_>,
    indexed: bool,
) -> Result<Vec<StepOutput>> {
    let whose = |i: usize, e: Error| match (e, indexed) {
        (Error::InvalidInput(m), true) => Error::InvalidInput(format!("session {i}: {m}")),
        (e, _) => e,
    };
    for (i, (s, chunk)) in streams.iter().zip(actor).enumerate() {
        s.check(chunk).map_err(|e| whose(i, e))?;
    }
    let before: Vec<(u64, usize, usize)> = streams
        .iter()
        .map(|s| (s.frames, s.keys.first().map_or(0, Vec::len), s.queued_used))
        .collect();
    let result = run(streams, actor).and_then(|frames| {
        let mut outputs: Vec<StepOutput> =
            frames.into_iter().map(StepOutput::frames_only).collect();
        for (i, output) in outputs.iter_mut().enumerate() {
            finish(i, output)?;
        }
        Ok(outputs)
    });
    if result.is_err() {
        for (s, &(frames, kept, queued_used)) in streams.iter_mut().zip(&before) {
            s.frames = frames;
            s.queued_used = queued_used;
            for cache in s.keys.iter_mut().chain(s.values.iter_mut()) {
                cache.truncate(kept);
            }
        }
    }
    result
}

fn run(streams: &mut [&mut OnlineStream], actor: &[&[f32]]) -> Result<Vec<Array2<f32>>> {
    let mut out: Vec<Vec<f32>> = vec![Vec::new(); streams.len()];
    let rounds = actor.iter().map(|a| a.len() / FRAME_DIM).max().unwrap_or(0);
    for round in 0..rounds {
        let rows: Vec<usize> = (0..streams.len())
            .filter(|&i| round * FRAME_DIM < actor[i].len())
            .collect();
        // Streams whose settings agree run their steps as one batch.
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for &i in &rows {
            match groups
                .iter_mut()
                .find(|g| streams[g[0]].sampling == streams[i].sampling)
            {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        for group in groups {
            let frames: Vec<&[f32]> = group
                .iter()
                .map(|&i| &actor[i][round * FRAME_DIM..(round + 1) * FRAME_DIM])
                .collect();
            let reactor = frame(streams, &group, &frames)?;
            for (row, &i) in group.iter().enumerate() {
                out[i].extend(reactor.row(row).iter());
            }
        }
    }
    Ok(out
        .into_iter()
        .map(|v| Array2::from_shape_vec((v.len() / FRAME_DIM, FRAME_DIM), v).expect("frames"))
        .collect())
}

/// The reactor's next frame for each stream of `group` (same settings), given the actor's.
fn frame(
    streams: &mut [&mut OnlineStream],
    group: &[usize],
    actor: &[&[f32]],
) -> Result<Array2<f32>> {
    let lead = &streams[group[0]];
    let (nets, s, kv) = (
        Arc::clone(&lead.nets),
        lead.sampling.clone(),
        lead.kv_floats(),
    );
    let norm = &nets.spec.normalizer;
    let (mean, std) = (&norm.mean[..], &norm.std[..]);
    let b = group.len();
    let raw = Array2::from_shape_fn((b, FRAME_DIM), |(r, i)| actor[r][i]);
    let a = Array2::from_shape_fn((b, FRAME_DIM), |(r, i)| (raw[[r, i]] - mean[i]) / std[i]);
    let steps = s.steps;
    // Every draw of the frame first, so that a failed frame gives queued normals back.
    let mut draws = Vec::with_capacity(b);
    for &i in group {
        draws.push(streams[i].frame_draws(&s)?.into_iter());
    }
    let mut x = a.clone();
    if s.sigma > 0.0 {
        for (row, draws) in draws.iter_mut().enumerate() {
            let e = draws.next().expect("the start noise");
            for (v, e) in x.row_mut(row).iter_mut().zip(e) {
                *v += s.sigma * e;
            }
        }
    }
    let loss = loss_of(&s);
    let m = &nets.spec.model;
    let dh = m.width / m.heads;
    for step in 0..steps {
        let (t, t_next) = times(step, steps);
        let cached = group
            .iter()
            .map(|&i| streams[i].frames as usize)
            .max()
            .unwrap_or(0)
            .max(1);
        let (cache, mask) = pack(streams, group, step, cached, (m.layers, m.heads, dh));
        let position: Vec<i64> = group.iter().map(|&i| streams[i].frames as i64).collect();
        let out = nets.denoise_step(x.view(), &vec![t; b], &position, cache, mask, cached)?;
        let eps: Option<Vec<f32>> = (s.eta > 0.0).then(|| {
            draws
                .iter_mut()
                .flat_map(|d| d.next().expect("one eps per step"))
                .collect()
        });
        euler_step(
            &mut x,
            &out.x1,
            a.view(),
            raw.view(),
            (mean, std),
            &s,
            &loss,
            (t, t_next),
            eps.as_deref(),
        )?;
        for (row, &i) in group.iter().enumerate() {
            streams[i].keys[step].extend_from_slice(&out.k[row * kv..(row + 1) * kv]);
            streams[i].values[step].extend_from_slice(&out.v[row * kv..(row + 1) * kv]);
        }
    }
    for &i in group {
        streams[i].frames += 1;
    }
    for mut row in x.outer_iter_mut() {
        for (i, v) in row.iter_mut().enumerate() {
            *v = *v * std[i] + mean[i];
        }
    }
    Ok(x)
}

/// Step `step`'s caches of `group` as the graph takes them: `[B, L, H, cached, W/H]` with each
/// row's frames at the end (padded in front), and the mask `[B, cached]`. The graph's keys come
/// out `[B, L, H, 1, W/H]`, one frame's `L · W` floats per row in that order, which is how each
/// stream keeps them, frame after frame.
fn pack(
    streams: &[&mut OnlineStream],
    group: &[usize],
    step: usize,
    cached: usize,
    (layers, heads, dh): (usize, usize, usize),
) -> ((Vec<f32>, Vec<f32>), Vec<f32>) {
    let b = group.len();
    let per_row = layers * heads * cached * dh;
    let mut k = vec![0f32; b * per_row];
    let mut v = vec![0f32; b * per_row];
    let mut mask = vec![0f32; b * cached];
    let frame_floats = layers * heads * dh;
    for (row, &i) in group.iter().enumerate() {
        let s = &streams[i];
        let have = s.frames as usize;
        let pad = cached - have;
        for n in 0..have {
            mask[row * cached + pad + n] = 1.0;
            let src = n * frame_floats;
            for l in 0..layers {
                for h in 0..heads {
                    let from = src + (l * heads + h) * dh;
                    let to = row * per_row + ((l * heads + h) * cached + pad + n) * dh;
                    k[to..to + dh].copy_from_slice(&s.keys[step][from..from + dh]);
                    v[to..to + dh].copy_from_slice(&s.values[step][from..from + dh]);
                }
            }
        }
    }
    ((k, v), mask)
}

impl OnlineStream {
    /// Sets the sampler's settings: the bundle's with `options`' changes (its seed too). A new
    /// step count only before the first frame or after a reset.
    pub fn set_options(&mut self, options: &super::sampler::ArflowOptions) -> Result<()> {
        let sampling = options.apply(self.bundle_sampling())?;
        self.set_sampling(sampling)?;
        self.set_seed(options.seed);
        Ok(())
    }
}

impl Stream for OnlineStream {
    fn family(&self) -> &'static str {
        "arflow"
    }
    fn frame_dim(&self) -> usize {
        FRAME_DIM
    }
    /// ARFlow has no latent: a frame.
    fn latent_dim(&self) -> usize {
        FRAME_DIM
    }
    fn io(&self) -> &BundleIo {
        &self.nets.io
    }
    fn capabilities(&self) -> Capabilities {
        Capabilities::of(&[Capability::QueuedNormals])
    }
    fn save(&self, w: &mut SnapshotWriter) -> Result<()> {
        OnlineStream::save(self, w);
        Ok(())
    }
    fn step(&mut self, frames: &[f32], finish: Finish<'_>) -> Result<StepOutput> {
        let mut out = advance(&mut [self], &[frames], finish, false)?;
        Ok(out.pop().expect("one stream, one output"))
    }
    fn step_together(&self) -> StepTogether {
        |streams, frames, finish| {
            let mut online = downcast_all::<OnlineStream>(streams);
            advance(&mut online, frames, finish, true)
        }
    }
    fn same_model(&self, other: &dyn Stream) -> bool {
        other
            .as_any()
            .downcast_ref::<OnlineStream>()
            .is_some_and(|o| Arc::ptr_eq(&self.nets, &o.nets))
    }
    fn reset(&mut self) {
        self.frames = 0;
        self.queued.clear();
        self.queued_used = 0;
        for cache in self.keys.iter_mut().chain(self.values.iter_mut()) {
            cache.clear();
        }
    }
    /// The reactor's frame `n` is out with the actor's frame `n`.
    fn latency_frames(&self) -> usize {
        0
    }
    fn set_seed(&mut self, seed: u64) {
        self.seed = seed;
    }
    fn queue_normals(&mut self, normals: &[f32]) -> Result<()> {
        let total = (self.queued.len() - self.queued_used) as u64 + normals.len() as u64;
        at_most("queued normals", total, LIMITS.max_tensor_elements, false)?;
        self.queued.drain(..self.queued_used);
        self.queued_used = 0;
        self.queued.extend_from_slice(normals);
        Ok(())
    }
    fn set_steps(&mut self, steps: u32) -> Result<()> {
        let mut sampling = self.sampling().clone();
        sampling.steps = steps as usize;
        self.set_sampling(sampling)
    }
    /// Frames a step with `n` more actor frames returns: all of them, up to the stream's end.
    fn frames_ready_after(&self, n: usize) -> usize {
        n
    }
    fn frames_received(&self) -> u64 {
        self.frames()
    }
    fn frames_emitted(&self) -> u64 {
        self.frames()
    }
    /// Bytes held: the caches (the model's weights, shared, not counted).
    fn memory_bytes(&self) -> usize {
        let floats: usize = self
            .keys
            .iter()
            .chain(&self.values)
            .map(Vec::capacity)
            .sum();
        std::mem::size_of::<Self>() + floats * std::mem::size_of::<f32>()
    }
    fn context_len(&self) -> usize {
        self.frames() as usize
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

impl From<OnlineStream> for Session {
    fn from(stream: OnlineStream) -> Self {
        Self::new(stream)
    }
}
