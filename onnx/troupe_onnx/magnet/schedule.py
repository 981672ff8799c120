"""MAGNet's noise schedule, step-index -> level table, q_sample and DDIM step
(`docs/spec/magnet.md` §3), in numpy float32 exactly as the reference computes them; the Rust
runtime (`src/magnet/schedule.rs`, `src/magnet/ddim.rs`) is tested against these numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MAX_T = 1000
COSINE_S = 0.008
CLEAN = -1  # the level of a clean token
PURE_NOISE = MAX_T - 1  # 999


@dataclass(frozen=True)
class Schedule:
    """The tables of §3.1, float32. `abar` is the float32 cast of the float64 cumulative product;
    `sqrt_abar` and `sqrt_one_minus_abar` are float32 casts of square roots taken in float64.
    DDIM's coefficients use `abar`; q_sample and epsilon use the two square-root tables (§3.4)."""

    abar: np.ndarray
    sqrt_abar: np.ndarray
    sqrt_one_minus_abar: np.ndarray

    @staticmethod
    def cosine(max_t: int = MAX_T, s: float = COSINE_S) -> "Schedule":
        u = np.arange(max_t + 1, dtype=np.float64)
        g = np.cos(((u / max_t) + s) / (1 + s) * math.pi / 2) ** 2
        abar_raw = g / g[0]
        alphas = abar_raw[1:] / abar_raw[:-1]
        betas = np.clip(1 - alphas, 1e-9, 1.0)
        abar = np.cumprod(1 - betas)
        return Schedule(
            abar=abar.astype(np.float32),
            sqrt_abar=np.sqrt(abar).astype(np.float32),
            sqrt_one_minus_abar=np.sqrt(1 - abar).astype(np.float32),
        )

    def to_json(self) -> dict:
        return {k: [float(x) for x in getattr(self, k)] for k in ("abar", "sqrt_abar", "sqrt_one_minus_abar")}


def torch_linspace_f32(start: float, end: float, steps: int) -> np.ndarray:
    """`torch.linspace(start, end, steps)` in float32 as ATen computes it: the first half from
    `start + step * k`, the second from `end - step * (steps - 1 - k)`."""
    f = np.float32
    step = f(f(end) - f(start)) / f(steps - 1)
    k = np.arange(steps)
    lo = f(start) + step * k.astype(np.float32)
    hi = f(end) - step * (steps - 1 - k).astype(np.float32)
    return np.where(k < steps // 2, lo, hi).astype(np.float32)


def level_table(steps: int, max_t: int = MAX_T) -> np.ndarray:
    """level(m) = trunc(linspace(-1, max_t - 1, steps + 1)[m]), m = 0..steps (§3.2)."""
    return np.trunc(torch_linspace_f32(-1.0, max_t - 1.0, steps + 1)).astype(np.int64)


def q_sample(sched: Schedule, x0: np.ndarray, levels: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """sqrt(abar_k) x0 + sqrt(1 - abar_k) n, levels broadcast against x0's leading axes; level -1
    reads row 999 (Python's negative index), as the reference does (§3.3)."""
    idx = np.where(levels < 0, levels + sched.abar.shape[0], levels)
    a = sched.sqrt_abar[idx][..., None]
    b = sched.sqrt_one_minus_abar[idx][..., None]
    return (a * x0 + b * noise).astype(np.float32)


def ddim_step(
    sched: Schedule, x: np.ndarray, x0: np.ndarray, k: np.ndarray, k_next: np.ndarray, eta: float, z: np.ndarray
) -> np.ndarray:
    """One DDIM step per token (§3.4). x, x0, z: [S, T, P, D]; k, k_next: [T, P] levels (shared by
    the batch) or [S, T, P]. Tokens with k == k_next keep x."""
    f = np.float32
    k = np.broadcast_to(k, x.shape[:-1])
    k_next = np.broadcast_to(k_next, x.shape[:-1])
    kc = np.maximum(k, 0)
    a = sched.abar[kc]
    clean_next = k_next < 0
    a_next = np.where(clean_next, f(1.0), sched.abar[np.maximum(k_next, 0)])
    keep = k == k_next
    with np.errstate(divide="ignore", invalid="ignore"):
        # Kept tokens may divide 0 by 0 (999 -> 999); their result is discarded below.
        sigma = np.where(
            clean_next, f(0.0), f(eta) * np.sqrt((f(1) - a / a_next) * (f(1) - a_next) / (f(1) - a))
        ).astype(np.float32)
        c = np.sqrt(np.maximum(f(1) - a_next - sigma * sigma, f(0))).astype(np.float32)
        eps = (x - sched.sqrt_abar[kc][..., None] * x0) / sched.sqrt_one_minus_abar[kc][..., None]
        out = np.sqrt(a_next)[..., None] * x0 + c[..., None] * eps + sigma[..., None] * z
    return np.where(keep[..., None], x, out).astype(np.float32)
