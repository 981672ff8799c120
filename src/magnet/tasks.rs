//! MAGNet's sampling entry points (`docs/spec/magnet.md` §5) over motion tokens, operation for
//! operation as the reference (`onnx/troupe_onnx/magnet/tasks.py`), the official index
//! conventions included (§11 A3, A4).
//!
//! Every task works on tokens `[S, T, P, D]`: `S` samples, `T` tokens of 4 frames, `P` people,
//! `D` floats per token. [`Run`] holds what every step shares: the networks, the schedule, the
//! guidance wrapper and the draws.

use ndarray::{s, Array3, Array4, ArrayView3, ArrayView4, Axis};

use super::draws::Draws;
use super::guidance::Guidance;
use super::layout::{stats, FRAMES_PER_TOKEN, TOKEN_TRANSFORMS, TRANSFORM};
use super::matrices::{level_matrix, Levels};
use super::networks::Networks;
use super::schedule::{Schedule, CLEAN};
use super::spec::{RootMode, SamplingSpec, ScheduleKind, Task};
use super::transforms::{compose, from_9d, inverse, to_9d, Mat4, IDENTITY};
use crate::motion::rotation::{matrix_from_6d, matrix_to_6d, SixD};
use crate::shared::error::Result;
use crate::shared::progress;

/// The state one sampler call works on (§5.0, "Common pieces").
pub(crate) struct Run<'a> {
    pub nets: &'a Networks,
    pub cfg: SamplingSpec,
    pub schedule: &'a Schedule,
    pub draws: Draws,
    pub guidance: Guidance<'a>,
    pub window: usize,
    pub persons: usize,
    pub latent: usize,
}

impl Run<'_> {
    fn samples(&self) -> usize {
        self.cfg.samples
    }

    fn context_tokens(&self) -> usize {
        self.cfg.context_len / FRAMES_PER_TOKEN
    }

    fn ar_stride(&self) -> usize {
        self.cfg.ar_seq_stride / FRAMES_PER_TOKEN
    }

    /// A fresh progress counter for a sampler of `total` iterations.
    pub(crate) fn start(&mut self, total: usize) {
        self.guidance.total = total;
        self.guidance.counter = 0;
    }

    /// [`Run::start`] for a generation, refused when `total` is above the call budget.
    fn start_task(&mut self, total: usize) -> Result<()> {
        progress::check_work("the MAGNet generation", total as u64, "sampler iterations")?;
        self.start(total);
        Ok(())
    }

    fn matrix(&self, group: usize, context_tokens: usize, prune: bool) -> Levels {
        let c = &self.cfg;
        level_matrix(
            c.schedule,
            c.steps,
            self.nets.spec.model.max_t,
            self.window,
            self.persons,
            group,
            context_tokens,
            c.offset_proportion,
            prune,
        )
    }

    /// One network call + DDIM on window(ts), written back where `protect` `[S, T, P]` is false.
    fn step(
        &mut self,
        x: &mut Array4<f32>,
        ts: usize,
        k: &[i64],
        k_next: &[i64],
        ctx_len: usize,
        protect: ArrayView3<bool>,
    ) -> Result<()> {
        let tm = self.window;
        let win = x.slice(s![.., ts..ts + tm, .., ..]).to_owned();
        // A person protected at every token of the window in every sample keeps its tokens
        // whatever x0 says: the corrections need not be taken for it.
        let given: Vec<bool> = (0..win.dim().2)
            .map(|person| {
                protect
                    .slice(s![.., ts..ts + tm, person])
                    .iter()
                    .all(|&kept| kept)
            })
            .collect();
        let x0 = self
            .guidance
            .x0(win.view(), k, ctx_len, &given, &mut self.draws)?;
        let z = self.draws.normal(win.len())?;
        let (s, _, p, d) = win.dim();
        let mut new = vec![0f32; d];
        for sample in 0..s {
            for t in 0..tm {
                for person in 0..p {
                    let f = t * p + person;
                    let at = ((sample * tm + t) * p + person) * d;
                    let xv = win.slice(s![sample, t, person, ..]);
                    let x0v = x0.slice(s![sample, t, person, ..]);
                    self.schedule.ddim_token(
                        (k[f], k_next[f]),
                        self.cfg.eta,
                        xv.as_slice().expect("contiguous"),
                        x0v.as_slice().expect("contiguous"),
                        &z[at..at + d],
                        &mut new,
                    );
                    if !protect[[sample, ts + t, person]] {
                        x.slice_mut(s![sample, ts + t, person, ..])
                            .assign(&ndarray::ArrayView1::from(&new[..]));
                    }
                }
            }
        }
        let (done, total) = (
            self.guidance.counter,
            self.guidance.total.max(self.guidance.counter),
        );
        progress::report("generating", done as u64, total as u64)
    }

    /// Context-mask growth (§5.0): window tokens from `tcc` on that are clean now become context.
    fn grow(&self, ctx: &mut Array3<bool>, ts: usize, tcc: usize, k: &[i64]) {
        let p = self.persons;
        for tau in tcc..self.window {
            for person in 0..p {
                if k[tau * p + person] == CLEAN {
                    ctx.slice_mut(s![.., ts + tau, person]).fill(true);
                }
            }
        }
    }

    /// The post-window Laplacian smoothing of every interior token of window(ts) (§5.0).
    fn smooth(&self, x: &mut Array4<f32>, ts: usize, chunk: usize) {
        let Some(lambda) = self.cfg.temporal_smoothing else {
            return;
        };
        if chunk < self.cfg.smoothing_start || self.window < 3 {
            return;
        }
        let tm = self.window;
        let old = x.slice(s![.., ts..ts + tm, .., ..]).to_owned();
        for tau in 1..tm - 1 {
            let mut target = x.slice_mut(s![.., ts + tau, .., ..]);
            let (prev, centre, next) = (
                old.index_axis(Axis(1), tau - 1),
                old.index_axis(Axis(1), tau),
                old.index_axis(Axis(1), tau + 1),
            );
            ndarray::Zip::from(&mut target)
                .and(&prev)
                .and(&centre)
                .and(&next)
                .for_each(|t, &a, &c, &b| *t = c - lambda * (c - 0.5 * (a + b)));
        }
    }

    /// §5.0's transform post-processing of window(ts): heights zeroed and rotations
    /// re-orthonormalised; in `temporal` mode the partner relations rebuilt from chained frame-0
    /// transitions, anchored at token `cl - 1` (Python's index when `cl = 0`).
    fn postprocess(&self, x: &mut Array4<f32>, ts: usize, cl: usize) {
        if !self.cfg.update_history_transforms {
            return;
        }
        let st = &self.nets.spec.statistics;
        let (p, lat, tm) = (self.persons, self.latent, self.window);
        let field = |r: std::ops::Range<usize>| (st.mean[r.clone()].to_vec(), st.std[r].to_vec());
        let (tm_mean, tm_std) = field(stats::TM1_T);
        let (pa_mean, pa_std) = field(stats::PARTNER);
        let s = x.dim().0;
        let slots = TOKEN_TRANSFORMS / TRANSFORM * p; // 4 per kind, own + partners
                                                      // A token's first 4 transforms are its own transitions, the rest its partners'.
        let stats_of = |slot: usize| {
            if slot < FRAMES_PER_TOKEN {
                (&tm_mean, &tm_std)
            } else {
                (&pa_mean, &pa_std)
            }
        };
        // [S, Tm, P, slots, 9] of de-normalised, cleaned transforms
        let mut tr = vec![0f32; s * tm * p * slots * TRANSFORM];
        let at = |sample: usize, t: usize, person: usize, slot: usize| {
            (((sample * tm + t) * p + person) * slots + slot) * TRANSFORM
        };
        for sample in 0..s {
            for t in 0..tm {
                for person in 0..p {
                    let token = x.slice(s![sample, ts + t, person, lat..]);
                    for slot in 0..slots {
                        let (mean, std) = stats_of(slot);
                        let o = at(sample, t, person, slot);
                        let v = &mut tr[o..o + TRANSFORM];
                        for i in 0..TRANSFORM {
                            v[i] = token[slot * TRANSFORM + i] * std[i] + mean[i];
                        }
                        v[7] = 0.0;
                        let layout = SixD::ConcatenatedColumns;
                        let clean = matrix_to_6d(&matrix_from_6d(&v[..6], layout), layout);
                        v[..6].copy_from_slice(&clean);
                    }
                }
            }
        }
        if p > 1 && self.cfg.root_mode == RootMode::Temporal {
            let anchor = (cl + tm - 1) % tm;
            for sample in 0..s {
                let mut worlds: Vec<Mat4> = (0..p)
                    .map(|j| {
                        if j == 0 {
                            IDENTITY
                        } else {
                            let o = at(sample, anchor, 0, 4 + 4 * (j - 1));
                            from_9d(&tr[o..o + TRANSFORM])
                        }
                    })
                    .collect();
                for u in 0..tm.saturating_sub(cl) {
                    if u > 0 {
                        for (q, world) in worlds.iter_mut().enumerate() {
                            let o = at(sample, cl + u, q, 0);
                            *world = compose(world, &from_9d(&tr[o..o + TRANSFORM]));
                        }
                    }
                    for i in 0..p {
                        let inv = inverse(&worlds[i]);
                        for (j, world) in worlds.iter().enumerate() {
                            if j == i {
                                continue;
                            }
                            let slot = if j < i { j } else { j - 1 };
                            let o = at(sample, cl + u, i, 4 + 4 * slot);
                            to_9d(&compose(&inv, world), &mut tr[o..o + TRANSFORM]);
                        }
                    }
                }
            }
        }
        for sample in 0..s {
            for t in 0..tm {
                for person in 0..p {
                    let mut token = x.slice_mut(s![sample, ts + t, person, lat..]);
                    for slot in 0..slots {
                        let (mean, std) = stats_of(slot);
                        let o = at(sample, t, person, slot);
                        for i in 0..TRANSFORM {
                            token[slot * TRANSFORM + i] = (tr[o + i] - mean[i]) / std[i];
                        }
                    }
                }
            }
        }
    }
}

// ------------------------------------------------------------------------------------------------
// Window parameters (§5.1)
// ------------------------------------------------------------------------------------------------

/// `(n_ar, T, Tca)` of the AR samplers.
fn ar_params(cfg: &SamplingSpec, window: usize, persons: usize) -> (usize, usize, usize) {
    let stride = cfg.ar_seq_stride / FRAMES_PER_TOKEN;
    let need = (cfg.seq_len / FRAMES_PER_TOKEN).max(window);
    let n_ar = (need - window).div_ceil(stride);
    // Tca mixes units (tokens minus flat tokens) and may go below 0 in the reference only for
    // P = 4 with stride 16, where it is 0.
    let tca = window.saturating_sub(stride * persons);
    (n_ar, n_ar * stride + window, tca)
}

/// `(stride, n_chunks, T)` of the rolling samplers.
fn rolling_params(t_gt: usize, window: usize, context: usize) -> (usize, usize, usize) {
    let stride = window - context;
    let n_chunks = if t_gt <= window {
        1
    } else {
        (t_gt - window).div_ceil(stride) + 1
    };
    let total = if n_chunks > 1 {
        (n_chunks - 1) * stride + window
    } else {
        t_gt.max(window)
    };
    (stride, n_chunks, total)
}

/// The group size `g` of §4.4, in flat tokens.
fn group_size(task: Task, cfg: &SamplingSpec, persons: usize) -> usize {
    match task {
        Task::PartnerPrediction
        | Task::MotionControlLive
        | Task::PartnerInpainting
        | Task::Inbetweening => persons,
        Task::AgenticTurnTaking | Task::AgenticSync => cfg.subseq_len,
        Task::Joint | Task::Pp2joint => {
            if cfg.schedule == ScheduleKind::Autoregressive {
                1
            } else {
                cfg.subseq_len * persons
            }
        }
    }
}

/// Tokens `[S, t, P, D]` of `a` (`[S, n, P, D]`), zero after `n`.
fn pad_tokens(a: ArrayView4<f32>, t: usize) -> Array4<f32> {
    let (s, n, p, d) = a.dim();
    let mut out = Array4::zeros((s, t, p, d));
    let n = n.min(t);
    out.slice_mut(s![.., ..n, .., ..])
        .assign(&a.slice(s![.., ..n, .., ..]));
    out
}

fn pad_mask(a: ArrayView3<bool>, t: usize) -> Array3<bool> {
    let (s, n, p) = a.dim();
    let mut out = Array3::from_elem((s, t, p), false);
    let n = n.min(t);
    out.slice_mut(s![.., ..n, ..])
        .assign(&a.slice(s![.., ..n, ..]));
    out
}

fn normals(run: &mut Run, shape: (usize, usize, usize, usize)) -> Result<Array4<f32>> {
    let n = run.draws.normal(shape.0 * shape.1 * shape.2 * shape.3)?;
    Ok(Array4::from_shape_vec(shape, n).expect("sized"))
}

fn where_mask(mask: ArrayView3<bool>, yes: ArrayView4<f32>, no: &mut Array4<f32>) {
    for ((idx, v), &y) in no.indexed_iter_mut().zip(yes.iter()) {
        if mask[[idx.0, idx.1, idx.2]] {
            *v = y;
        }
    }
}

// ------------------------------------------------------------------------------------------------
// Tasks
// ------------------------------------------------------------------------------------------------

/// §5.2: everyone's future from everyone's past. `context` `[S, Tc, P, D]`, `mask` `[S, Tc, P]`
/// (false: an absent person). Returns `[S, T, P, D]`, the context included.
pub(crate) fn joint(
    run: &mut Run,
    context: ArrayView4<f32>,
    mask: ArrayView3<bool>,
) -> Result<Array4<f32>> {
    let (tm, p) = (run.window, run.persons);
    let tc = run.context_tokens();
    let (n_ar, t, tca) = ar_params(&run.cfg, tm, p);
    let g = group_size(Task::Joint, &run.cfg, p);
    let (s, d) = (run.samples(), context.dim().3);
    let mut ctx = pad_mask(mask, t);
    let mut x = normals(run, (s, t, p, d))?;
    where_mask(ctx.view(), pad_tokens(context, t).view(), &mut x);
    let first = run.matrix(g, tc, true);
    let later = first.ar_window(run.ar_stride() * p, run.nets.spec.model.max_t as i64 - 1);
    run.start_task((first.rows() - 1) + n_ar * (later.rows() - 1))?;
    for r in 0..first.rows() - 1 {
        run.grow(&mut ctx, 0, tc, first.row(r));
        run.step(
            &mut x,
            0,
            first.row(r),
            first.row(r + 1),
            tc * p,
            ctx.view(),
        )?;
    }
    run.smooth(&mut x, 0, 0);
    run.postprocess(&mut x, 0, tc);
    let mut ts = 0;
    for a in 1..=n_ar {
        ts += run.ar_stride();
        for r in 0..later.rows() - 1 {
            run.grow(&mut ctx, ts, tca, later.row(r));
            run.step(
                &mut x,
                ts,
                later.row(r),
                later.row(r + 1),
                tca * p,
                ctx.view(),
            )?;
        }
        run.smooth(&mut x, ts, a);
        run.postprocess(&mut x, ts, tca);
    }
    Ok(x)
}

/// §5.3: person 0's whole motion given (re-noised to each step's level), the others predicted
/// from their first Tc tokens on. `gt` `[S, T_gt, P, D]`.
pub(crate) fn partner_prediction(run: &mut Run, gt: ArrayView4<f32>) -> Result<Array4<f32>> {
    let (tm, p) = (run.window, run.persons);
    let (tc, s, d) = (run.context_tokens(), run.samples(), gt.dim().3);
    let t_gt = gt.dim().1;
    let (stride, n_chunks, t) = rolling_params(t_gt, tm, tc);
    let gt_b = pad_tokens(gt, t);
    let mut ctx = Array3::from_elem((s, t, p), false);
    let mut inject = ctx.clone();
    ctx.slice_mut(s![.., ..tc, ..]).fill(true);
    inject.slice_mut(s![.., ..tc, ..]).fill(true);
    let noise_a = normals(run, (s, t, 1, d))?;
    let mut x = normals(run, (s, t, p, d))?;
    where_mask(inject.view(), gt_b.view(), &mut x);
    let m = run.matrix(group_size(Task::PartnerPrediction, &run.cfg, p), tc, true);
    run.start_task(n_chunks * (m.rows() - 1))?;
    for c in 0..n_chunks {
        let ts = c * stride;
        if c > 0 {
            ctx.slice_mut(s![.., ts..ts + tc, ..]).fill(true);
            inject.slice_mut(s![.., ts..ts + tc, 0]).fill(true);
        }
        for r in 0..m.rows() - 1 {
            run.grow(&mut ctx, ts, tc, m.row(r));
            where_mask(inject.view(), gt_b.view(), &mut x);
            run.step(&mut x, ts, m.row(r), m.row(r + 1), tc * p, ctx.view())?;
            let next = m.row(r + 1);
            for tau in 0..tm {
                let k_a = next[tau * p];
                let (a, b) = run.schedule.q_coefficients(k_a.max(0));
                for sample in 0..s {
                    let given = ctx[[sample, ts + tau, 0]];
                    for i in 0..d {
                        let ga = gt_b[[sample, ts + tau, 0, i]];
                        x[[sample, ts + tau, 0, i]] = if given || k_a == CLEAN {
                            ga
                        } else {
                            a * ga + b * noise_a[[sample, ts + tau, 0, i]]
                        };
                    }
                }
            }
            where_mask(inject.view(), gt_b.view(), &mut x);
        }
    }
    Ok(x.slice(s![.., ..t_gt, .., ..]).to_owned())
}

/// §5.4 and §5.5: person 0 clean ground truth over each whole window, the others generated in
/// rolling chunks. `gt` `[S, T_gt, P, D]`.
pub(crate) fn live_like(run: &mut Run, gt: ArrayView4<f32>, task: Task) -> Result<Array4<f32>> {
    let (tm, p) = (run.window, run.persons);
    let (tc, s) = (run.context_tokens(), run.samples());
    let t_gt = gt.dim().1;
    let (stride, n_chunks, t) = rolling_params(t_gt, tm, tc);
    let gt_b = pad_tokens(gt, t);
    let mut ctx = Array3::from_elem((s, t, p), false);
    ctx.slice_mut(s![.., .., 0]).fill(true);
    ctx.slice_mut(s![.., ..tc, 1..]).fill(true);
    let inject = ctx.clone();
    let mut x = normals(run, (s, t, p, gt.dim().3))?;
    where_mask(inject.view(), gt_b.view(), &mut x);
    let m = live_matrix(run, task);
    run.start_task(n_chunks * (m.rows() - 1))?;
    for c in 0..n_chunks {
        let ts = c * stride;
        if c > 0 {
            ctx.slice_mut(s![.., ts..ts + tc, 1..]).fill(true);
        }
        rolling_chunk(run, &mut x, ts, &m, gt_b.view(), inject.view(), &mut ctx, c)?;
    }
    Ok(x.slice(s![.., ..t_gt, .., ..]).to_owned())
}

/// The rolling tasks' level matrix: `g = P` (or the configured schedule), person 0 clean.
pub(crate) fn live_matrix(run: &Run, task: Task) -> Levels {
    let p = run.persons;
    let mut m = run.matrix(group_size(task, &run.cfg, p), run.context_tokens(), true);
    for tau in 0..run.window {
        m.set_column(tau * p, CLEAN); // person 0 is given
    }
    m
}

/// One chunk of window(ts) (§5.4): the calls of `m` with the context mask growing and the given
/// tokens (`inject`, values in `gt`) re-injected around each call, then the smoothing and the
/// transform post-processing. Shared by the offline rolling tasks and the live stream.
#[allow(clippy::too_many_arguments)]
pub(crate) fn rolling_chunk(
    run: &mut Run,
    x: &mut Array4<f32>,
    ts: usize,
    m: &Levels,
    gt: ArrayView4<f32>,
    inject: ArrayView3<bool>,
    ctx: &mut Array3<bool>,
    chunk: usize,
) -> Result<()> {
    let (tc, p) = (run.context_tokens(), run.persons);
    for r in 0..m.rows() - 1 {
        run.grow(ctx, ts, tc, m.row(r));
        where_mask(inject, gt, x);
        run.step(x, ts, m.row(r), m.row(r + 1), tc * p, ctx.view())?;
        where_mask(inject, gt, x);
    }
    run.smooth(x, ts, chunk);
    run.postprocess(x, ts, tc);
    Ok(())
}

/// §5.6: one window; the key tokens (`key_mask` `[Tm]`) clean, the rest generated. `keys`
/// `[S, Tm, P, D]` holds the key tokens (other rows unused).
pub(crate) fn inbetweening(
    run: &mut Run,
    keys: ArrayView4<f32>,
    key_mask: &[bool],
) -> Result<Array4<f32>> {
    let (tm, p, s) = (run.window, run.persons, run.samples());
    let mut ctx = Array3::from_elem((s, tm, p), false);
    for (tau, &key) in key_mask.iter().enumerate() {
        if key {
            ctx.slice_mut(s![.., tau, ..]).fill(true);
        }
    }
    let mut x = normals(run, (s, tm, p, keys.dim().3))?;
    where_mask(ctx.view(), keys, &mut x);
    let mut m = run.matrix(group_size(Task::Inbetweening, &run.cfg, p), 0, true);
    for (tau, &key) in key_mask.iter().enumerate() {
        if key {
            for person in 0..p {
                m.set_column(tau * p + person, CLEAN);
            }
        }
    }
    run.start_task(m.rows() - 1)?;
    for r in 0..m.rows() - 1 {
        // Context length 0: one clean call (the reference's `{clean: 1}` is unaffected, §11).
        run.step(&mut x, 0, m.row(r), m.row(r + 1), 0, ctx.view())?;
    }
    run.smooth(&mut x, 0, 0);
    Ok(x)
}

/// §5.7 (turn-taking) and §5.8 (sync): two copies of the whole sequence exchanging tokens, with
/// the official offset (relative to sc, applied relative to s0). `context` `[S, Tc, P, D]`.
pub(crate) fn two_worlds(
    run: &mut Run,
    context: ArrayView4<f32>,
    mask: ArrayView3<bool>,
    sync: bool,
) -> Result<Array4<f32>> {
    let (tm, p) = (run.window, run.persons);
    let (tc, s, d) = (run.context_tokens(), run.samples(), context.dim().3);
    let (n_ar, t, tca) = ar_params(&run.cfg, tm, p);
    let ctx_a = pad_mask(mask, t);
    let mut ctx_b = ctx_a.clone();
    let ctx_full = pad_tokens(context, t);
    let mut xa = normals(run, (s, t, p, d))?;
    where_mask(ctx_a.view(), ctx_full.view(), &mut xa);
    let mut xb = normals(run, (s, t, p, d))?;
    where_mask(ctx_a.view(), ctx_full.view(), &mut xb);
    let first = run.matrix(group_size(Task::AgenticTurnTaking, &run.cfg, p), tc, true);
    let later = first.ar_window(run.ar_stride() * p, run.nets.spec.model.max_t as i64 - 1);
    run.start_task((first.rows() - 1) + n_ar * (later.rows() - 1))?;
    let mut windows = vec![(0, tc, &first)];
    windows.extend((1..=n_ar).map(|a| (a * run.ar_stride(), tca, &later)));
    for (ts, tcc, m) in windows {
        let (s0, sc, s1) = (ts * p, (ts + tcc) * p, (ts + tm) * p);
        for r in 0..m.rows() - 1 {
            let (k, kn) = (m.row(r), m.row(r + 1));
            let mut m_new = ctx_a.clone();
            for f in sc..s1 {
                if k[f - s0] == CLEAN {
                    m_new.slice_mut(s![.., f / p, f % p]).fill(true);
                }
            }
            if sync {
                run.step(&mut xa, ts, k, kn, tcc * p, m_new.view())?;
                run.step(&mut xb, ts, k, kn, tcc * p, m_new.view())?;
                for tau in ts..ts + tm {
                    for sample in 0..s {
                        if m_new[[sample, tau, 1]] {
                            let v = xb.slice(s![sample, tau, 1, ..]).to_owned();
                            xa.slice_mut(s![sample, tau, 1, ..]).assign(&v);
                        }
                        if m_new[[sample, tau, 0]] {
                            let v = xa.slice(s![sample, tau, 0, ..]).to_owned();
                            xb.slice_mut(s![sample, tau, 0, ..]).assign(&v);
                        }
                    }
                }
                let mut scratch = xb.clone();
                run.step(&mut scratch, ts, k, kn, tcc * p, ctx_b.view())?; // the discarded third call
                continue;
            }
            run.step(&mut xa, ts, k, kn, tcc * p, m_new.view())?;
            let ptr = (0..s1 - sc)
                .filter(|&i| {
                    m_new
                        .slice(s![.., (sc + i) / p, (sc + i) % p])
                        .iter()
                        .any(|&v| v)
                })
                .max()
                .unwrap_or(0);
            let (mut kb, mut knb) = (k.to_vec(), kn.to_vec());
            let flat = |f: usize| (f / p, f % p);
            if ptr > 0 {
                let (tt, pp) = flat(s0 + ptr);
                let v = xa.slice(s![.., tt, pp, ..]).to_owned();
                xb.slice_mut(s![.., tt, pp, ..]).assign(&v);
                kb[ptr] = CLEAN;
                knb[ptr] = CLEAN;
            }
            run.step(&mut xb, ts, &kb, &knb, tcc * p, ctx_b.view())?;
            run.grow(&mut ctx_b, ts, tcc, k);
            let (tt, pp) = flat(s0 + ptr + 1);
            let v = xb.slice(s![.., tt, pp, ..]).to_owned();
            xa.slice_mut(s![.., tt, pp, ..]).assign(&v);
        }
    }
    Ok(xa)
}

/// §5.10: partner prediction over the ground truth, then joint generation of `joint_frames`
/// from each sample's last Tc tokens. Each phase has its own progress counter (§11).
pub(crate) fn pp2joint(
    run: &mut Run,
    gt: ArrayView4<f32>,
    joint_frames: usize,
) -> Result<Array4<f32>> {
    let tc = run.context_tokens();
    let pp = partner_prediction(run, gt)?;
    let saved = run.cfg.seq_len;
    run.cfg.seq_len = joint_frames;
    let cfg_task = run.cfg.task;
    let n = pp.dim().1;
    let tail = pp.slice(s![.., n - tc.., .., ..]).to_owned();
    let mask = Array3::from_elem((tail.dim().0, tc, tail.dim().2), true);
    let joint_out = joint(run, tail.view(), mask.view());
    run.cfg.seq_len = saved;
    run.cfg.task = cfg_task;
    let joint_out = joint_out?;
    Ok(ndarray::concatenate(
        Axis(1),
        &[pp.slice(s![.., ..n - tc, .., ..]), joint_out.view()],
    )
    .expect("same samples, people and width"))
}
