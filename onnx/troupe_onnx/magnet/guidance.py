"""MAGNet's guidance (`docs/spec/magnet.md` §6): the mask modes and their weighted sum of x0
predictions, and the x0-space smoothing and foot-skating corrections through the VQ decoder.

The decoder gradients are callables (`decoder_gradients.py`: autograd, the ground truth, and the
hand-written VJP the bundle ships as graphs, §6.5 option (a)); the analytic transform term is
added here, as the Rust runtime (`src/magnet/guidance.rs`) adds it. numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from troupe_onnx.magnet.schedule import Schedule
MODES = ("clean", "full", "subset", "partial")  # plus person{i} and ~person{i}


@dataclass(frozen=True)
class X0Guidance:
    """One x0-space correction: its weight and the share of the run it is active in."""

    weight: float = 2.0
    start: float = 0.0
    end: float = 1.0

    def active(self, counter: int, total: int) -> bool:
        return total > 0 and self.start <= counter / total <= self.end

    def to_json(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True)
class GuidanceConfig:
    """`cfg_scale_dict` (mode -> weight, in order) and the two x0 corrections (None = off)."""

    scales: tuple = (("clean", 1.0),)
    subset_ratio: float = 0.5  # `subset_mask_ratio`: not a config field, the code's default
    partial_level: float = 0.5  # `partial_mask_noise_level`
    smoothing: X0Guidance | None = field(default_factory=X0Guidance)
    foot_skating: X0Guidance | None = field(default_factory=X0Guidance)

    def to_json(self) -> dict:
        return {
            "scales": [[m, w] for m, w in self.scales],
            "subset_ratio": self.subset_ratio,
            "partial_level": self.partial_level,
            "smoothing": self.smoothing.to_json() if self.smoothing else None,
            "foot_skating": self.foot_skating.to_json() if self.foot_skating else None,
        }


def check_mode(mode: str, persons: int) -> None:
    if mode in MODES:
        return
    base = mode[1:] if mode.startswith("~") else mode
    if base.startswith("person") and base[6:].isdigit() and int(base[6:]) < persons:
        return
    raise ValueError(f"guidance mode {mode!r}: one of {', '.join(MODES)}, person<i> or ~person<i> with i < {persons}")


def mode_input(mode: str, x: np.ndarray, k: np.ndarray, ctx_len: int, draws, sched: Schedule, cfg: GuidanceConfig):
    """What the network sees in `mode` (§6.2). x [S, T, P, D], k [T, P]; ctx_len in flat tokens."""
    if mode == "clean":
        return x
    s, t, p, d = x.shape
    n = draws.normal((s, t * p, d))
    flat_k = k.reshape(-1)
    idx = np.where(flat_k < 0, flat_k + sched.abar.shape[0], flat_k)  # -1 reads row 999: pure n
    q = (sched.sqrt_one_minus_abar[idx][None, :, None] * n).astype(np.float32)
    flat = x.reshape(s, t * p, d).copy()
    if mode == "full":
        flat[:, :ctx_len] = q[:, :ctx_len]
    elif mode == "subset":
        cut = int(ctx_len * cfg.subset_ratio)
        flat[:, :cut] = q[:, :cut]
    elif mode == "partial":
        rho = np.float32(cfg.partial_level)
        flat[:, :ctx_len] = rho * q[:, :ctx_len] + (np.float32(1) - rho) * flat[:, :ctx_len]
    else:
        n2 = draws.normal((s, t * p, d)).reshape(s, t, p, d)
        negate = mode.startswith("~")
        person = int(mode.lstrip("~")[6:])
        out = x.copy()
        chosen = np.arange(p) != person if negate else np.arange(p) == person
        out[:, :, chosen] = n2[:, :, chosen]
        return out
    return flat.reshape(s, t, p, d)


def transform_smoothing_gradient(x0: np.ndarray, latent: int) -> np.ndarray:
    """d mean(Lap^2)/dY of the transform dims Y = x0[..., latent:] along the window's token
    axis (§6.4, smoothing, part 2); zero on the latent dims."""
    y = x0[..., latent:].astype(np.float32)
    s, t, p, dy = y.shape
    grad = np.zeros_like(x0, dtype=np.float32)
    if t < 3:
        return grad
    lap = y[:, :-2] - 2 * y[:, 1:-1] + y[:, 2:]  # tau = 1..t-2
    c = np.float32(2.0 / (s * (t - 2) * p * dy))
    g = np.zeros_like(y)
    g[:, :-2] += c * lap
    g[:, 1:-1] += -2 * c * lap
    g[:, 2:] += c * lap
    grad[..., latent:] = g
    return grad


class Guidance:
    """The guidance wrapper of one sampler run (§6.1): combines the modes' x0 predictions,
    applies the x0 corrections while `counter / total` is in their range, counts calls."""

    def __init__(self, cfg: GuidanceConfig, sched: Schedule, denoise, draws, total: int,
                 decoder_grad=None, latent: int = 512):
        self.cfg, self.sched, self.denoise, self.draws = cfg, sched, denoise, draws
        self.total, self.counter = total, 0
        # decoder_grad(x0, betas, w_smooth, w_foot): the latent gradient of the weighted losses
        self.decoder_grad, self.latent = decoder_grad, latent

    def x0(self, x: np.ndarray, k: np.ndarray, ctx_len: int, betas: np.ndarray) -> np.ndarray:
        if ctx_len == 0:
            out = self.denoise(x, k)
        else:
            out = np.zeros_like(x, dtype=np.float32)
            for mode, w in self.cfg.scales:
                out = (out + np.float32(w) * self.denoise(mode_input(mode, x, k, ctx_len, self.draws, self.sched, self.cfg), k)).astype(np.float32)
        smooth, foot = self.cfg.smoothing, self.cfg.foot_skating
        use_smooth = smooth is not None and smooth.active(self.counter, self.total)
        use_foot = foot is not None and foot.active(self.counter, self.total)
        if use_smooth or use_foot:
            # Both corrections at the same x0, subtracted together: w_s grad L_s + w_f grad L_f
            # through the decoder (on the latents), then the smoothing's transform term.
            ws = np.float32(smooth.weight if use_smooth else 0.0)
            wf = np.float32(foot.weight if use_foot else 0.0)
            base = out
            out = (out - self.decoder_grad(base, betas, ws, wf)).astype(np.float32)
            if use_smooth:
                out = (out - ws * transform_smoothing_gradient(base, self.latent)).astype(np.float32)
        self.counter += 1
        return out
