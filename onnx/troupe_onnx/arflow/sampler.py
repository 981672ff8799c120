"""ARFlow's sampler (`docs/spec/arflow.md` §2-§4), reconstructed from the paper (no code
exists): x̂_1-prediction Euler from the actor, with physical guidance on x̂_1, back-projection,
reweighting toward the actor and re-interpolation, optionally stochastic. Mirrored by
`src/arflow/sampler.rs`, which is tested against this.

Per step m of M, t_m = m / M, in the bundle's normalised feature space (x_0 = a):

    x̂_1  = G(x_m, t_m)
    x̂_1' = x̂_1 − λ ∇_{x̂_1} L_pen                    (guidance; positions are features 0..66)
    x̂_0  = (x_m − t_m x̂_1') / (1 − t_m)              (`guided_backprojection`; else with x̂_1)
    x̃_0  = w x̂_0 + (1 − w) a
    d     = v, (1 − η) v + η ε  or  √(1 − η²) v + η ε,   v = x̂_1' − x̃_0   (`mixing`)
    x_{m+1} = x̂_1' − (1 − t_{m+1}) d

With λ = 0, w = 1, η = 0 this is Euler (Eq. 9). Draws (troupe's generator, stream
`STREAM_ARFLOW`, token = draw index): the start noise when σ > 0 (x_0 = a + σ ε), then one ε
per step when η > 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from troupe_onnx.shared.noise import philox_normals
from troupe_onnx.shared.penetration import penetration_loss

STREAM_ARFLOW = 9  # troupe's Philox stream for ARFlow's draws
POSITIONS = 66  # interhuman262: the 22 joints' positions come first


@dataclass(frozen=True)
class Sampling:
    steps: int = 5  # M
    guidance: float = 2.0  # λ
    weight: float = 0.7  # w
    eta: float = 0.0  # η
    d_safe: float = 0.02
    squared: bool = False  # the hinge
    guided_backprojection: bool = True
    mixing: str = "linear"  # or "variance_preserving"
    sigma: float = 0.0  # start noise
    seed: int = 0

    def to_json(self) -> dict:
        return dict(self.__dict__)


class Draws:
    def __init__(self, seed: int):
        self.seed, self.count = seed, 0

    def normal(self, n: int) -> np.ndarray:
        out = philox_normals(self.seed, self.count, STREAM_ARFLOW, n)
        self.count += 1
        return out


def guidance_gradient(x1: np.ndarray, actor_raw: np.ndarray, mean: np.ndarray, std: np.ndarray,
                      d_safe: float, squared: bool) -> np.ndarray:
    """∇ of L_pen with respect to the normalised x̂_1 [T, D] (float64; torch autograd): the
    reactor's positions x̂_1[:, :66] · std + mean against the actor's body."""
    import torch

    frames = x1.shape[0]
    x = torch.tensor(x1[:, :POSITIONS], dtype=torch.float64, requires_grad=True)
    reactor = (x * torch.tensor(std[:POSITIONS], dtype=torch.float64)
               + torch.tensor(mean[:POSITIONS], dtype=torch.float64)).reshape(frames, 22, 3)
    actor = torch.tensor(actor_raw[:, :POSITIONS], dtype=torch.float64).reshape(frames, 22, 3)
    penetration_loss(actor, reactor, d_safe, squared).backward()
    grad = np.zeros(x1.shape, np.float64)
    grad[:, :POSITIONS] = x.grad.numpy()
    return grad


def sample(denoise, actor_raw: np.ndarray, mean: np.ndarray, std: np.ndarray, s: Sampling) -> np.ndarray:
    """The reactor's features [T, D] (raw) for the actor's [T, D] (raw). `denoise(x, t)` maps
    normalised x [T, D] at time t to x̂_1."""
    a = ((actor_raw - mean) / std).astype(np.float32)
    draws = Draws(s.seed)
    x = a.copy()
    if s.sigma > 0:
        x = (a + np.float32(s.sigma) * draws.normal(a.size).reshape(a.shape)).astype(np.float32)
    m_steps = s.steps
    for m in range(m_steps):
        t, t_next = np.float32(m / m_steps), np.float32((m + 1) / m_steps)
        x1 = denoise(x, t)
        if s.guidance > 0:
            g = guidance_gradient(x1, actor_raw, mean, std, s.d_safe, s.squared)
            x1g = (x1.astype(np.float64) - s.guidance * g).astype(np.float32)
        else:
            x1g = x1
        back = x1g if s.guided_backprojection else x1
        x0 = ((x - t * back) / (np.float32(1) - t)).astype(np.float32)
        x0w = (np.float32(s.weight) * x0 + np.float32(1 - s.weight) * a).astype(np.float32)
        v = x1g - x0w
        if s.eta > 0:
            eps = draws.normal(a.size).reshape(a.shape)
            eta = np.float32(s.eta)
            keep = np.float32(1 - s.eta) if s.mixing == "linear" else np.float32(np.sqrt(1 - s.eta**2))
            d = keep * v + eta * eps
        else:
            d = v
        x = (x1g - (np.float32(1) - t_next) * d).astype(np.float32)
    return (x * std + mean).astype(np.float32)
