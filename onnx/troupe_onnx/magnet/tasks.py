"""MAGNet's sampling entry points (`docs/spec/magnet.md` §5) over motion tokens, operation for
operation, with the official index conventions (the turn-taking offset included, §11 A3).

Every task takes tokens `[T, P, D]` of one clip (the encoder's output, §5.0 step 3; the same
for every sample) and returns `[S, T_out, P, D]`. The network is a callable `denoise(x, k)`
with x `[S, Tm, P, D]` and k `[Tm, P]` levels; draws come from a `draws` object (`draws.py`).
This is the reference the Rust runtime (`src/magnet/tasks.rs`) is tested against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from troupe_onnx.magnet.guidance import Guidance, GuidanceConfig, check_mode
from troupe_onnx.magnet.matrices import ar_matrix, level_matrix, window_levels
from troupe_onnx.magnet.layout import FRAMES_PER_TOKEN, TOKEN_TRANSFORMS, TRANSFORM
from troupe_onnx.magnet.schedule import CLEAN, Schedule, ddim_step
from troupe_onnx.magnet.transforms import compose, from_9d, inverse, rotation_from_6d, rotation_to_6d, to_9d

TASKS = (
    "joint", "partner_prediction", "motion_control_live", "partner_inpainting", "inbetweening",
    "agentic_turn_taking", "agentic_sync", "pp2joint",
)
ROOT_MODES = ("temporal", "temporal_partner")


@dataclass(frozen=True)
class Sampling:
    """One sampling configuration (§5.12): the YAML's numbers, in frames where the YAML is."""

    task: str = "joint"
    steps: int = 50  # N, DDIM steps
    eta: float = 0.0
    schedule: str = "causal_uncertainty"
    subseq_len: int = 16  # `sampling_subseq_len`
    ar_seq_stride: int = 16  # frames
    offset_proportion: float = 0.0
    seq_len: int = 200  # `sampling_seq_len`, frames
    context_len: int = 32  # `context_seq_len`, frames
    samples: int = 10  # S
    root_mode: str = "temporal_partner"
    temporal_smoothing: float | None = 0.3  # lambda, None = off
    smoothing_start: int = 0  # `temporal_smoothing_start_step`
    update_history_transforms: bool = True
    keyframes: tuple = ()  # in-betweening key frames (frames)
    guidance: GuidanceConfig = field(default_factory=GuidanceConfig)
    seed: int = 1111

    @property
    def context_tokens(self) -> int:
        return self.context_len // FRAMES_PER_TOKEN

    @property
    def ar_stride(self) -> int:
        return self.ar_seq_stride // FRAMES_PER_TOKEN

    def to_json(self) -> dict:
        out = {k: v for k, v in self.__dict__.items() if k != "guidance"}
        return out | {"keyframes": list(self.keyframes), "guidance": self.guidance.to_json()}


@dataclass(frozen=True)
class TransformStats:
    """Normalisation of the 9-D transforms inside tokens (§1.3): tm1_t and self->partner."""

    tm1_t_mean: np.ndarray
    tm1_t_std: np.ndarray
    partner_mean: np.ndarray
    partner_std: np.ndarray


class Run:
    """The state one sampler call works on: the token buffer, its context mask and the
    machinery every step shares (§5.0, "Common pieces")."""

    def __init__(self, sampling: Sampling, sched: Schedule, denoise, draws, stats: TransformStats,
                 window: int, persons: int, latent: int, betas: np.ndarray, decoder_grad=None):
        self.cfg, self.sched, self.draws, self.stats = sampling, sched, draws, stats
        self.tm, self.p, self.latent = window, persons, latent
        self.betas = np.broadcast_to(betas.astype(np.float32), (sampling.samples, persons, betas.shape[-1]))
        self.denoise, self.decoder_grad = denoise, decoder_grad
        self.guidance = None
        for mode, _ in sampling.guidance.scales:
            check_mode(mode, persons)

    def start(self, total: int) -> None:
        """A fresh guidance wrapper for a sampler of `total` iterations (its progress counter)."""
        self.guidance = Guidance(self.cfg.guidance, self.sched, self.denoise, self.draws, total,
                                 self.decoder_grad, self.latent)

    def matrix(self, group: int, context_tokens: int, do_prune: bool = True) -> np.ndarray:
        c = self.cfg
        return level_matrix(c.schedule, c.steps, self.tm, self.p, group, context_tokens, c.offset_proportion, do_prune)

    def step(self, x: np.ndarray, ts: int, k_row, k_next_row, ctx_len: int, protect: np.ndarray) -> np.ndarray:
        """One network call + DDIM on window(ts), written back where `protect` [S, T, P] is false.
        Returns the DDIM result for the window (before the write-back)."""
        win = x[:, ts : ts + self.tm]
        k, kn = window_levels(k_row, self.p), window_levels(k_next_row, self.p)
        x0 = self.guidance.x0(win, k, ctx_len, self.betas)
        z = self.draws.normal(win.shape)
        new = ddim_step(self.sched, win, x0, k, kn, self.cfg.eta, z)
        x[:, ts : ts + self.tm] = np.where(protect[:, ts : ts + self.tm, :, None], win, new)
        return new

    def grow(self, ctx: np.ndarray, ts: int, tcc: int, k_row) -> None:
        """Context-mask growth (§5.0): window tokens from tcc on that are clean now become context."""
        k = window_levels(k_row, self.p)
        for tau in range(tcc, self.tm):
            ctx[:, ts + tau] |= (k[tau] == CLEAN)[None]

    def smooth(self, x: np.ndarray, ts: int, chunk: int) -> None:
        lam = self.cfg.temporal_smoothing
        if lam is None or chunk < self.cfg.smoothing_start or self.tm < 3:
            return
        win = x[:, ts : ts + self.tm]
        old = win.copy()
        lam = np.float32(lam)
        win[:, 1:-1] = old[:, 1:-1] - lam * (old[:, 1:-1] - np.float32(0.5) * (old[:, :-2] + old[:, 2:]))

    def postprocess(self, x: np.ndarray, ts: int, cl: int, mode: str) -> None:
        """§5.0 transform post-processing of window(ts): y = 0 and re-orthonormalised transforms;
        in `temporal` mode the partner relations rebuilt from chained frame-0 transitions."""
        if not self.cfg.update_history_transforms:
            return
        p, lat, st = self.p, self.latent, self.stats
        win = x[:, ts : ts + self.tm]
        s, t = win.shape[:2]
        tm1 = win[..., lat : lat + TOKEN_TRANSFORMS].reshape(s, t, p, FRAMES_PER_TOKEN, TRANSFORM)
        tm1 = tm1 * st.tm1_t_std + st.tm1_t_mean
        partner = win[..., lat + TOKEN_TRANSFORMS :].reshape(s, t, p, p - 1, FRAMES_PER_TOKEN, TRANSFORM)
        partner = partner * st.partner_std + st.partner_mean

        def clean(v):
            v = v.copy()
            v[..., 7] = 0.0
            v[..., :6] = rotation_to_6d(rotation_from_6d(v[..., :6]))
            return v

        tm1, partner = clean(tm1).astype(np.float32), clean(partner).astype(np.float32)
        if p > 1 and mode == "temporal":
            eye = np.broadcast_to(np.eye(4, dtype=np.float32), (s, 4, 4))
            anchor = (cl - 1) % t  # Python's index: cl = 0 reads the window's last token (§11 A4)
            worlds = [eye] + [from_9d(partner[:, anchor, 0, j - 1, 0]) for j in range(1, p)]
            for u in range(t - cl):
                if u > 0:
                    worlds = [compose(worlds[q], from_9d(tm1[:, cl + u, q, 0])) for q in range(p)]
                for i in range(p):
                    for j in range(p):
                        if j != i:
                            slot = j if j < i else j - 1
                            partner[:, cl + u, i, slot, 0] = to_9d(compose(inverse(worlds[i]), worlds[j]))
        win[..., lat : lat + TOKEN_TRANSFORMS] = ((tm1 - st.tm1_t_mean) / st.tm1_t_std).reshape(s, t, p, -1)
        if p > 1:
            win[..., lat + TOKEN_TRANSFORMS :] = ((partner - st.partner_mean) / st.partner_std).reshape(s, t, p, -1)


# --------------------------------------------------------------------------------------------
# Window parameters (§5.1)
# --------------------------------------------------------------------------------------------


def ar_params(cfg: Sampling, window: int, persons: int) -> tuple[int, int, int]:
    """(n_ar, total tokens T, Tca) of the AR samplers."""
    stride = cfg.ar_stride
    if stride < 1:
        raise ValueError(f"ar_seq_stride {cfg.ar_seq_stride} frames: at least {FRAMES_PER_TOKEN}")
    need = max(cfg.seq_len // FRAMES_PER_TOKEN, window)
    n_ar = math.ceil((need - window) / stride)
    return n_ar, n_ar * stride + window, window - stride * persons


def rolling_params(t_gt: int, window: int, context: int) -> tuple[int, int, int]:
    """(stride, n_chunks, total tokens T) of the rolling samplers."""
    stride = window - context
    n_chunks = 1 if t_gt <= window else max(1, math.ceil((t_gt - window) / stride) + 1)
    total = (n_chunks - 1) * stride + window if n_chunks > 1 else max(t_gt, window)
    return stride, n_chunks, total


def group_size(task: str, cfg: Sampling, persons: int) -> int:
    """g of §4.4, in flat tokens."""
    if task in ("partner_prediction", "motion_control_live", "partner_inpainting", "inbetweening"):
        return persons
    if task in ("agentic_turn_taking", "agentic_sync"):
        return cfg.subseq_len
    return 1 if cfg.schedule == "autoregressive" else cfg.subseq_len * persons


def _batch(a: np.ndarray, s: int, rank: int) -> np.ndarray:
    """One clip's array repeated for S samples, or an array already per sample (rank + 1 axes)."""
    return a.copy() if a.ndim == rank + 1 else np.repeat(a[None], s, axis=0)


def _pad(a: np.ndarray, t: int, axis: int = 0) -> np.ndarray:
    """Zeros (false) after `a` along its time axis, up to t."""
    shape = list(a.shape)
    shape[axis] = t
    out = np.zeros(shape, a.dtype)
    n = min(t, a.shape[axis])
    index = [slice(None)] * a.ndim
    index[axis] = slice(0, n)
    out[tuple(index)] = a[tuple(index)]
    return out


# --------------------------------------------------------------------------------------------
# Tasks
# --------------------------------------------------------------------------------------------


def joint(run: Run, context: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """§5.2: every person's future from everyone's past. context [Tc, P, D] with mask [Tc, P]
    (false: an absent person), or per sample [S, Tc, P, D] and [S, Tc, P]."""
    cfg, tm, p = run.cfg, run.tm, run.p
    tc = cfg.context_tokens
    n_ar, t, tca = ar_params(cfg, tm, p)
    g = group_size("joint", cfg, p)
    s, d = cfg.samples, context.shape[-1]
    ctx = _pad(_batch(mask.astype(bool), s, 2), t, axis=1)
    x = run.draws.normal((s, t, p, d))
    x = np.where(ctx[..., None], _pad(_batch(context, s, 3), t, axis=1), x).astype(np.float32)
    first = run.matrix(g, tc)
    later = ar_matrix(first, cfg.ar_stride * p)
    run.start((first.shape[0] - 1) + n_ar * (later.shape[0] - 1))
    for r in range(first.shape[0] - 1):
        run.grow(ctx, 0, tc, first[r])
        run.step(x, 0, first[r], first[r + 1], tc * p, ctx)
    run.smooth(x, 0, 0)
    run.postprocess(x, 0, tc, cfg.root_mode)
    ts = 0
    for a in range(1, n_ar + 1):
        ts += cfg.ar_stride
        for r in range(later.shape[0] - 1):
            run.grow(ctx, ts, tca, later[r])
            run.step(x, ts, later[r], later[r + 1], tca * p, ctx)
        run.smooth(x, ts, a)
        run.postprocess(x, ts, tca, cfg.root_mode)
    return x


def partner_prediction(run: Run, gt: np.ndarray) -> np.ndarray:
    """§5.3: person 0's whole motion given (re-noised to each step's level), person 1..P-1
    predicted from their first Tc tokens on. gt [T_gt, P, D]."""
    cfg, tm, p, sched = run.cfg, run.tm, run.p, run.sched
    tc, s, d = cfg.context_tokens, cfg.samples, gt.shape[-1]
    t_gt = gt.shape[0]
    stride, n_chunks, t = rolling_params(t_gt, tm, tc)
    gt_b = _batch(_pad(gt, t), s, 3)
    ctx = np.zeros((s, t, p), bool)
    inject = np.zeros((s, t, p), bool)
    ctx[:, :tc] = True
    inject[:, :tc] = True
    noise_a = run.draws.normal((s, t, 1, d))
    x = run.draws.normal((s, t, p, d))
    x = np.where(inject[..., None], gt_b, x).astype(np.float32)
    m = run.matrix(group_size("partner_prediction", cfg, p), tc)
    run.start(n_chunks * (m.shape[0] - 1))
    for c in range(n_chunks):
        ts = c * stride
        if c > 0:
            ctx[:, ts : ts + tc] = True
            inject[:, ts : ts + tc, 0] = True
        for r in range(m.shape[0] - 1):
            run.grow(ctx, ts, tc, m[r])
            x[:] = np.where(inject[..., None], gt_b, x)
            run.step(x, ts, m[r], m[r + 1], tc * p, ctx)
            k_a = window_levels(m[r + 1], p)[:, 0]  # [Tm]
            ga = gt_b[:, ts : ts + tm, 0]
            idx = np.maximum(k_a, 0)
            renoised = sched.sqrt_abar[idx][None, :, None] * ga + sched.sqrt_one_minus_abar[idx][None, :, None] * noise_a[:, ts : ts + tm, 0]
            a_val = np.where((k_a == CLEAN)[None, :, None], ga, renoised)
            x[:, ts : ts + tm, 0] = np.where(ctx[:, ts : ts + tm, 0, None], ga, a_val)
            x[:] = np.where(inject[..., None], gt_b, x)
    return x[:, :t_gt]


def _live_like(run: Run, gt: np.ndarray, task: str) -> np.ndarray:
    """§5.4 and §5.5: person 0 clean ground truth over the whole window, the others generated in
    rolling chunks."""
    cfg, tm, p = run.cfg, run.tm, run.p
    tc, s = cfg.context_tokens, cfg.samples
    t_gt = gt.shape[0]
    stride, n_chunks, t = rolling_params(t_gt, tm, tc)
    gt_b = _batch(_pad(gt, t), s, 3)
    ctx = np.zeros((s, t, p), bool)
    inject = np.zeros((s, t, p), bool)
    ctx[:, :, 0] = True
    ctx[:, :tc, 1:] = True
    inject[:, :, 0] = True
    inject[:, :tc, 1:] = True
    x = run.draws.normal((s, t, p, gt.shape[-1]))
    x = np.where(inject[..., None], gt_b, x).astype(np.float32)
    m = live_matrix(run, task)
    run.start(n_chunks * (m.shape[0] - 1))
    for c in range(n_chunks):
        ts = c * stride
        if c > 0:
            ctx[:, ts : ts + tc, 1:] = True
        rolling_chunk(run, x, ts, m, gt_b, inject, ctx, c)
    return x[:, :t_gt]


def live_matrix(run: Run, task: str) -> np.ndarray:
    """The rolling tasks' level matrix: g = P (or the configured schedule), person 0 clean."""
    m = run.matrix(group_size(task, run.cfg, run.p), run.cfg.context_tokens)
    m[:, 0 :: run.p] = CLEAN  # person 0 is given
    return m


def rolling_chunk(run: Run, x: np.ndarray, ts: int, m: np.ndarray, gt: np.ndarray, inject: np.ndarray,
                  ctx: np.ndarray, chunk: int) -> None:
    """One chunk of window(ts) (§5.4): the calls of `m` with the context mask growing and the
    given tokens re-injected around each call, then smoothing and transform post-processing."""
    tc = run.cfg.context_tokens
    for r in range(m.shape[0] - 1):
        run.grow(ctx, ts, tc, m[r])
        x[:] = np.where(inject[..., None], gt, x)
        run.step(x, ts, m[r], m[r + 1], tc * run.p, ctx)
        x[:] = np.where(inject[..., None], gt, x)
    run.smooth(x, ts, chunk)
    run.postprocess(x, ts, tc, run.cfg.root_mode)


def motion_control_live(run: Run, gt: np.ndarray) -> np.ndarray:
    """§5.4: person 0 (the user) given, clean, over each whole window (up to Tm - Tc tokens ahead)."""
    return _live_like(run, gt, "motion_control_live")


def partner_inpainting(run: Run, gt: np.ndarray) -> np.ndarray:
    """§5.5: as motion_control_live, with the configured schedule."""
    return _live_like(run, gt, "partner_inpainting")


def inbetweening(run: Run, keys: np.ndarray, key_mask: np.ndarray) -> np.ndarray:
    """§5.6: one window of Tm tokens; key tokens (key_mask [Tm] true) clean, the rest generated.
    keys [Tm, P, D] holds the key tokens (other rows unused)."""
    cfg, tm, p = run.cfg, run.tm, run.p
    if cfg.seq_len // FRAMES_PER_TOKEN != tm:
        raise ValueError(f"in-betweening covers one window of {tm * FRAMES_PER_TOKEN} frames, not {cfg.seq_len}")
    s = cfg.samples
    ctx = np.broadcast_to(key_mask[None, :, None], (s, tm, p)).copy()
    x = run.draws.normal((s, tm, p, keys.shape[-1]))
    x = np.where(ctx[..., None], _batch(keys, s, 3), x).astype(np.float32)
    m = run.matrix(group_size("inbetweening", cfg, p), 0)
    for tau in np.flatnonzero(key_mask):
        m[:, tau * p : (tau + 1) * p] = CLEAN
    run.start(m.shape[0] - 1)
    for r in range(m.shape[0] - 1):
        run.step(x, 0, m[r], m[r + 1], 0, ctx)  # ctx_len 0: one clean call (§11)
    run.smooth(x, 0, 0)
    return x


def _two_worlds(run: Run, context: np.ndarray, mask: np.ndarray, sync: bool) -> np.ndarray:
    """§5.7 (turn-taking) and §5.8 (sync): two copies of the whole sequence exchanging tokens,
    with the official offset (relative to sc, applied relative to s0)."""
    cfg, tm, p = run.cfg, run.tm, run.p
    tc, s, d = cfg.context_tokens, cfg.samples, context.shape[-1]
    n_ar, t, tca = ar_params(cfg, tm, p)
    ctx_a = _batch(_pad(mask.astype(bool), t), s, 2)
    ctx_b = ctx_a.copy()
    ctx_full = _batch(_pad(context, t), s, 3)
    xa = np.where(ctx_a[..., None], ctx_full, run.draws.normal((s, t, p, d))).astype(np.float32)
    xb = np.where(ctx_a[..., None], ctx_full, run.draws.normal((s, t, p, d))).astype(np.float32)
    first = run.matrix(group_size("agentic_turn_taking", cfg, p), tc)
    later = ar_matrix(first, cfg.ar_stride * p)
    run.start((first.shape[0] - 1) + n_ar * (later.shape[0] - 1))
    windows = [(0, tc, first)] + [(a * cfg.ar_stride, tca, later) for a in range(1, n_ar + 1)]
    for ts, tcc, m in windows:
        s0, sc, s1 = ts * p, (ts + tcc) * p, (ts + tm) * p
        for r in range(m.shape[0] - 1):
            k, kn = m[r], m[r + 1]
            m_new = ctx_a.reshape(s, -1).copy()
            for f in range(sc, s1):
                if k[f - s0] == CLEAN:
                    m_new[:, f] = True
            protect_new = m_new.reshape(s, t, p)
            if sync:
                run.step(xa, ts, k, kn, tcc * p, protect_new)
                run.step(xb, ts, k, kn, tcc * p, protect_new)
                win = slice(ts, ts + tm)
                xa[:, win, 1] = np.where(protect_new[:, win, 1, None], xb[:, win, 1], xa[:, win, 1])
                xb[:, win, 0] = np.where(protect_new[:, win, 0, None], xa[:, win, 0], xb[:, win, 0])
                scratch = xb.copy()
                run.step(scratch, ts, k, kn, tcc * p, ctx_b)  # the discarded third call
                continue
            run.step(xa, ts, k, kn, tcc * p, protect_new)
            hits = [i for i in range(s1 - sc) if m_new[:, sc + i].any()]
            ptr = max(hits) if hits else 0
            fa, fb = xa.reshape(s, t * p, d), xb.reshape(s, t * p, d)
            kb, knb = k.copy(), kn.copy()
            if ptr > 0:
                fb[:, s0 + ptr] = fa[:, s0 + ptr]
                kb[ptr] = CLEAN
                knb[ptr] = CLEAN
            run.step(xb, ts, kb, knb, tcc * p, ctx_b)
            run.grow(ctx_b, ts, tcc, k)
            fa[:, s0 + ptr + 1] = fb[:, s0 + ptr + 1]
    return xa


def agentic_turn_taking(run: Run, context: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """§5.7: leader/follower, two calls per step, reproduced with the official offset (§11 A3)."""
    return _two_worlds(run, context, mask, sync=False)


def agentic_sync(run: Run, context: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """§5.8: synchronous agents, three calls per step (the third discarded, as the reference)."""
    return _two_worlds(run, context, mask, sync=True)


def pp2joint(run: Run, gt: np.ndarray, joint_frames: int) -> np.ndarray:
    """§5.10: partner prediction over the ground-truth span, then joint generation of
    `joint_frames` frames from each sample's last Tc tokens. Each phase has its own guidance
    progress counter (§11)."""
    tc, cfg = run.cfg.context_tokens, run.cfg
    pp = partner_prediction(run, gt)
    run.cfg = replace(cfg, seq_len=joint_frames)
    try:
        tail = pp[:, -tc:]
        j = joint(run, tail, np.ones(tail.shape[:3], bool))
    finally:
        run.cfg = cfg
    return np.concatenate([pp[:, :-tc], j], axis=1)
