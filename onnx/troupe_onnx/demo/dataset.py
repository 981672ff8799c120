"""Training pairs (actor, rule partner) as interhuman262 features, and the windows drawn from them.

Augmentation, all applied to the actor *before* the rule (so the partner is always the rule's
answer to what the model sees): left/right mirroring (InterGen's `swap_left_right` on joints),
speed x0.9 / x1.0 / x1.1 (linear resampling in time; the rule's delays stay in seconds), and,
per window, a heading rotation and floor translation of the pair. Features are computed once
per (clip, mirror, speed, rule) in the clip's world frame; a window only rotates and translates
their position and velocity columns (the rotation columns are local, contacts are invariant).

A window is placed the way troupe's stream places the actor (`src/motion/placement.rs`): at its
first frame the actor's root is over the origin and it faces +Z. With probability
`P_STREAM_START` a window is such a stream start (its tokens at positions 0..L-1); otherwise it
stands for a later part of a long stream: positions start at a random offset, the pair is turned
and moved at random, and the VAE sees `PREFIX_FRAMES` of real history before it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from troupe_onnx.demo import rules
from troupe_onnx.demo.sources import FPS, Clip
from troupe_onnx.motion import intergen

SPEEDS = (0.9, 1.0, 1.1)
P_STREAM_START = 0.3
MAX_POSITION = 1024  # context positions a window may start at (about 2.3 min of stream)
PREFIX_FRAMES = 32  # real history before a mid-stream window, for the causal VAE
MAX_OFFSET_M = 1.5  # random floor translation of a mid-stream window (wider costs VAE precision)


def features(positions: np.ndarray) -> np.ndarray:
    """interhuman262 features of positions [T, 22, 3] (+Y up metres) as they stand: [T-1, 262]."""
    p = np.asarray(positions, dtype=np.float64)
    feet_l, feet_r = intergen.foot_detect(p)
    rot = intergen.rotation_features(p)
    flat = p.reshape(len(p), -1)
    out = np.concatenate([flat[:-1], flat[1:] - flat[:-1], rot[:-1], feet_l, feet_r], axis=-1)
    return out.astype(np.float32)


def mirrored(positions: np.ndarray) -> np.ndarray:
    return positions[:, rules.mirror_permutation()] * np.array([-1.0, 1.0, 1.0])


def resampled(positions: np.ndarray, speed: float) -> np.ndarray:
    """The clip played `speed` times as fast, by linear interpolation between frames."""
    n = int(np.floor((len(positions) - 1) / speed)) + 1
    t = np.arange(n) * speed
    i = np.minimum(t.astype(int), len(positions) - 2)
    w = (t - i)[:, None, None]
    return (1 - w) * positions[i] + w * positions[i + 1]


@dataclass
class Pair:
    """One (clip, mirror, speed, rule): features of both people in the clip's world frame."""

    clip: str
    rule: int
    actor: np.ndarray  # [T-1, 262]
    partner: np.ndarray  # [T-1, 262]


def build_pairs(clips: list[Clip], speeds=SPEEDS, mirror=(False, True)) -> list[Pair]:
    out = []
    for clip in clips:
        for m in mirror:
            base = mirrored(clip.positions) if m else clip.positions
            for s in speeds:
                actor = resampled(base, s) if s != 1.0 else base
                fa = features(actor)
                for k, rule in enumerate(rules.RULES):
                    out.append(Pair(f"{clip.source}/{clip.name}", k, fa, features(rules.partner(actor, rule, FPS))))
    return out


def rigid(x: np.ndarray, yaw: float, shift_xz: np.ndarray) -> np.ndarray:
    """Turn feature rows [..., 262] about +Y by `yaw` and move positions by `shift_xz`; the
    velocity columns turn too; rotations and contacts are left as they are."""
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]], np.float32)
    out = x.copy()
    for cols, move in ((slice(0, 66), True), (slice(66, 132), False)):
        v = x[..., cols].reshape(*x.shape[:-1], 22, 3) @ rot.T
        if move:
            v[..., 0] += shift_xz[0]
            v[..., 2] += shift_xz[1]
        out[..., cols] = v.reshape(*x.shape[:-1], 66)
    return out


def turned_xz(point: np.ndarray, yaw: float) -> np.ndarray:
    """The (x, z) of a point [3] turned about +Y by `yaw`, as `rigid` turns positions."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([c * point[0] + s * point[2], -s * point[0] + c * point[2]])


def placement_at(actor_row: np.ndarray) -> tuple[float, np.ndarray]:
    """(yaw, shift) that put this actor frame's root over the origin facing +Z."""
    p = actor_row[:66].reshape(22, 3).astype(np.float64)
    across = p[2] - p[1]  # right hip - left hip, as the stream's placement
    f = np.array([across[2], -across[0]]) / max(np.hypot(across[2], across[0]), 1e-9)
    yaw = -np.arctan2(f[0], f[1])
    return yaw, -turned_xz(p[0], yaw)


def draw_window(pair: Pair, frames: int, rng: np.random.Generator, stream_start: bool | None = None,
                prefix: int | None = None):
    """(actor [prefix + frames, 262], partner [...], prefix, first position) of one window.
    `prefix` overrides the history frames of a mid-stream window (the VAE needs none)."""
    if stream_start is None:
        stream_start = rng.random() < P_STREAM_START
    if prefix is None:
        prefix = 0 if stream_start else PREFIX_FRAMES
    hi = len(pair.actor) - frames - prefix
    if hi < 0:
        return None
    s = int(rng.integers(0, hi + 1))
    a = pair.actor[s : s + prefix + frames]
    b = pair.partner[s : s + prefix + frames]
    yaw, shift = placement_at(a[prefix])
    if not stream_start:
        yaw += rng.uniform(-np.pi, np.pi)
        shift = rng.uniform(-MAX_OFFSET_M, MAX_OFFSET_M, 2)
        # the random translation replaces the placement's: re-centre the root first
        shift = shift - turned_xz(a[prefix, :3], yaw)
        position = int(rng.integers(1, MAX_POSITION))
    else:
        position = 0
    return rigid(a, yaw, shift), rigid(b, yaw, shift), prefix, position
