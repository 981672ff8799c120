"""Training pairs (actor, rule partner) as interhuman262 features, and the windows drawn from them.

Augmentation, all applied to the actor *before* the rule (so the partner is always the rule's
answer to what the model sees): left/right mirroring (InterGen's `swap_left_right` on joints),
speed x0.9 / x1.0 / x1.1 (the v2 recipe: x0.8 to x1.25; linear resampling in time; the rule's
delays stay in seconds), actors that stop and stand (`with_pauses`) and long takes chained from
several clips (`chained`), and, per window, a heading rotation and floor translation of the pair. Features are computed once
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


def build_pairs(clips: list[Clip], speeds=SPEEDS, mirror=(False, True), pauses: int = 0, chains: int = 0,
                seed: int = 0) -> list[Pair]:
    """Every (clip, mirror, speed, rule). `pauses` more actors per clip that stop and stand for
    a while (`with_pauses`), and `chains` actors made of several clips walked one after another
    (`chained`), each under every rule, drawn with `seed`."""
    rng = np.random.default_rng(seed)
    actors = []
    for clip in clips:
        for m in mirror:
            base = mirrored(clip.positions) if m else clip.positions
            for s in speeds:
                actors.append((f"{clip.source}/{clip.name}", resampled(base, s) if s != 1.0 else base))
        for i in range(pauses):
            actors.append((f"{clip.source}/{clip.name}+pauses{i}", with_pauses(clip.positions, rng)))
    for i in range(chains):
        picked = rng.choice(len(clips), size=min(len(clips), 4), replace=False)
        actors.append((f"chain{i}", chained([clips[j].positions for j in picked], rng)))
    out = []
    for name, actor in actors:
        fa = features(actor)
        for k, rule in enumerate(rules.RULES):
            out.append(Pair(name, k, fa, features(rules.partner(actor, rule, FPS))))
    return out


def with_pauses(positions: np.ndarray, rng: np.random.Generator, every_s=(2.0, 5.0), hold_s=(0.5, 2.5)) -> np.ndarray:
    """The clip with the actor stopping now and then: every 2-5 s the pose is held for 0.5-2.5 s
    (an actor who wanders and stops; the partner must stop too)."""
    out, t = [], 0
    while t < len(positions):
        run = int(rng.uniform(*every_s) * FPS)
        out.append(positions[t : t + run])
        t += run
        if t < len(positions):
            out.append(np.repeat(positions[t - 1 : t], int(rng.uniform(*hold_s) * FPS), axis=0))
    return np.concatenate(out)


def chained(clips: list[np.ndarray], rng: np.random.Generator, blend: int = 8) -> np.ndarray:
    """Clips one after another as one long take: each next clip turned and moved so that it
    starts where and facing how the last ended, on the floor, with `blend` frames of cross-fade
    from the last pose (a minute of wandering across a wide floor, longer than any one clip)."""
    out = np.asarray(clips[0], np.float64)
    for nxt in clips[1:]:
        nxt = np.asarray(nxt, np.float64)
        f_end, f_start = rules.heading(out[-1:])[0], rules.heading(nxt[:1])[0]
        yaw = np.arctan2(f_end[0], f_end[1]) - np.arctan2(f_start[0], f_start[1]) + rng.normal(0.0, 0.3)
        c, s = np.cos(yaw), np.sin(yaw)
        rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        moved = (nxt - nxt[:1, :1] * np.array([1.0, 0.0, 1.0])) @ rot.T
        moved += out[-1:, :1] * np.array([1.0, 0.0, 1.0])
        w = np.linspace(0.0, 1.0, blend + 2)[1:-1, None, None]
        bridge = (1 - w) * out[-1:] + w * moved[:1]
        out = np.concatenate([out, bridge, moved])
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


def positions_of(rows: np.ndarray) -> np.ndarray:
    """The joint positions [T + 1, 22, 3] that feature rows [T, 262] were computed from (the
    last frame from the last row's velocity)."""
    p = rows[:, :66].reshape(-1, 22, 3).astype(np.float64)
    last = p[-1] + rows[-1, 66:132].reshape(22, 3)
    return np.concatenate([p, last[None]])


def restarted_partner(actor_rows: np.ndarray, rule: int) -> np.ndarray:
    """The partner features of a stream that starts at `actor_rows`' first frame: the rule run
    afresh there (keep-away's leash in front of the actor, follow's heading the actor's)."""
    return features(rules.partner(positions_of(actor_rows), rules.RULES[rule], FPS))


def draw_window(pair: Pair, frames: int, rng: np.random.Generator, stream_start: bool | None = None,
                prefix: int | None = None):
    """(actor [prefix + frames, 262], partner [...], prefix, first position) of one window.
    `prefix` overrides the history frames of a mid-stream window (the VAE needs none). A stream
    start's partner is the rule started afresh at the window (as a stream starts it); a
    mid-stream window's continues the one that began with the clip."""
    if stream_start is None:
        stream_start = rng.random() < P_STREAM_START
    if prefix is None:
        prefix = 0 if stream_start else PREFIX_FRAMES
    hi = len(pair.actor) - frames - prefix
    if hi < 0:
        return None
    s = int(rng.integers(0, hi + 1))
    a = pair.actor[s : s + prefix + frames]
    b = restarted_partner(a, pair.rule) if stream_start else pair.partner[s : s + prefix + frames]
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
