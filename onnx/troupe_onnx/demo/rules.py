"""The partner rules that define the demo model's reactor: mirror, follow and keep-away.

Each rule maps the actor's joint positions to a partner's, **causally** (frame t of the partner
depends on actor frames <= t only), so that an online model can learn it and every actor clip
has a ground-truth partner to measure against. All three are built the same way:

1. take the actor's pose `delay` seconds ago and express it in its own heading frame (root over
   the origin, facing +Z, heights unchanged): its *local pose*;
2. optionally mirror that pose left <-> right (x -> -x and the left/right joints swapped, so the
   result is again an anatomically labelled body);
3. place it at a partner root position with a partner heading.

| rule | delay | local pose | placed at | facing |
|---|---|---|---|---|
| mirror | 0.25 s | mirrored | 1.2 m in front of the actor's (delayed) root | the actor (heading + 180°) |
| follow | 0.5 s | as is | 1.5 m behind the actor's (delayed) root, along its smoothed heading | the actor's heading |
| keep-away | 0.25 s | as is | a point kept 2 m from the actor's current root, moving at most 3 m/s | toward the actor, smoothed |

The partner always stands on the floor (y = 0): when the actor stands on something (a box in
the climbing captures), the partner's local pose is lowered by the actor's support height: its
lowest joint's height above a 5 cm allowance, smoothed over 0.05 s. On the floor the support height is 0 and nothing moves.

"mirror" is an exact reflection of the delayed actor through a plane 0.6 m in front of it that
moves with it. "follow" smooths the heading it walks behind (0.5 s time constant) so that the
follower swings round when the actor turns instead of jumping. "keep-away" starts 2 m in front
of the actor and steps away (or back in) radially as the actor's root comes nearer (or goes).

Positions are metres, +Y up, the floor at y = 0; joints in t2m-22 order. Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from troupe_onnx.motion.skeleton import t2m22

RULES = ("mirror", "follow", "keep-away")  # index = the one-hot position in the condition


@dataclass(frozen=True)
class Rule:
    name: str
    delay_s: float
    mirrored: bool
    distance_m: float


PARAMETERS = {
    "mirror": Rule("mirror", 0.25, True, 1.2),
    "follow": Rule("follow", 0.5, False, 1.5),
    "keep-away": Rule("keep-away", 0.25, False, 2.0),
}
FOLLOW_HEADING_TAU_S = 0.5
KEEP_AWAY_MAX_SPEED = 3.0  # m/s
KEEP_AWAY_FACING_TAU_S = 0.25
SUPPORT_ALLOWANCE_M, SUPPORT_TAU_S = 0.05, 0.05


def condition(rule: str) -> np.ndarray:
    """The rule's conditioning vector: one-hot over RULES, float32."""
    out = np.zeros(len(RULES), np.float32)
    out[RULES.index(rule)] = 1.0
    return out


def mirror_permutation() -> np.ndarray:
    """Joint index of each joint's left/right counterpart (itself for the midline)."""
    names = t2m22().names
    swap = {"left_": "right_", "right_": "left_"}
    out = []
    for n in names:
        for a, b in swap.items():
            if n.startswith(a):
                n = b + n[len(a) :]
                break
        out.append(names.index(n))
    return np.array(out)


def heading(positions: np.ndarray) -> np.ndarray:
    """Unit facing direction on the floor [T, 2] (x, z), from hips and shoulders as InterGen."""
    names = t2m22().names
    across = (positions[:, names.index("right_hip")] - positions[:, names.index("left_hip")]) + (
        positions[:, names.index("right_shoulder")] - positions[:, names.index("left_shoulder")]
    )
    forward = np.stack([across[:, 2], -across[:, 0]], axis=-1)  # up x across, on (x, z)
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)


def yaw_matrix(direction: np.ndarray) -> np.ndarray:
    """[T, 3, 3] rotations about +Y taking +Z to the (x, z) unit `direction` [T, 2]."""
    s, c = direction[:, 0], direction[:, 1]
    z, o = np.zeros_like(s), np.ones_like(s)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], axis=-2)


def local_pose(positions: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """Joints relative to the root's floor point, turned so that `facing` becomes +Z."""
    root = positions[:, :1] * np.array([1.0, 0.0, 1.0])
    return np.einsum("tji,tkj->tki", yaw_matrix(facing), positions - root)  # R^T (p - root)


def place(local: np.ndarray, root_xz: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """Inverse of local_pose: the local pose turned to `facing` with its root over `root_xz`."""
    world = np.einsum("tij,tkj->tki", yaw_matrix(facing), local)
    world[..., 0] += root_xz[:, None, 0]
    world[..., 2] += root_xz[:, None, 1]
    return world


def delayed(x: np.ndarray, frames: int) -> np.ndarray:
    """x[t - frames], holding frame 0 for the first frames (causal)."""
    idx = np.maximum(np.arange(len(x)) - frames, 0)
    return x[idx]


def smooth_direction(direction: np.ndarray, tau_s: float, fps: float) -> np.ndarray:
    """Causal exponential smoothing of unit vectors [T, 2], renormalised."""
    alpha = 1.0 - np.exp(-1.0 / (tau_s * fps))
    out = np.empty_like(direction)
    acc = direction[0]
    for t, d in enumerate(direction):
        acc = acc + alpha * (d - acc)
        n = np.linalg.norm(acc)
        if n < 1e-6:  # a half-turn in one step: keep the last direction
            acc = out[t - 1] if t else d
            n = 1.0
        acc = acc / n
        out[t] = acc
    return out


def support_height(positions: np.ndarray, fps: float) -> np.ndarray:
    """[T] how far the actor stands above the floor (0 on the floor), causal."""
    raw = np.maximum(positions[..., 1].min(axis=1) - SUPPORT_ALLOWANCE_M, 0.0)
    alpha = 1.0 - np.exp(-1.0 / (SUPPORT_TAU_S * fps))
    out = np.empty_like(raw)
    acc = raw[0]
    for t, v in enumerate(raw):
        acc += alpha * (v - acc)
        out[t] = acc
    return out


def partner(actor: np.ndarray, rule: str, fps: float = 30.0, delay_s: float | None = None) -> np.ndarray:
    """The partner of `actor` [T, 22, 3] (metres, +Y up) under `rule`, same shape and frame.
    `delay_s` replaces the rule's delay (the evaluation's no-delay baseline uses 0)."""
    p = PARAMETERS[rule]
    actor = np.asarray(actor, dtype=np.float64)
    lag = int(round((p.delay_s if delay_s is None else delay_s) * fps))
    past = delayed(actor, lag)
    facing = heading(past)
    local = local_pose(past, facing)
    local[..., 1] -= support_height(past, fps)[:, None]
    if p.mirrored:
        local = local[:, mirror_permutation()] * np.array([-1.0, 1.0, 1.0])
    root = past[:, 0, [0, 2]]
    if rule == "mirror":
        return place(local, root + p.distance_m * facing, -facing)
    if rule == "follow":
        behind = smooth_direction(facing, FOLLOW_HEADING_TAU_S, fps)
        return place(local, root - p.distance_m * behind, facing)
    # keep-away: a point on a 2 m leash around the actor's current root, speed-limited.
    now = actor[:, 0, [0, 2]]
    step = KEEP_AWAY_MAX_SPEED / fps
    spot = np.empty_like(now)
    spot[0] = now[0] + p.distance_m * heading(actor[:1])[0]
    for t in range(1, len(now)):
        away = spot[t - 1] - now[t]
        norm = np.linalg.norm(away)
        target = now[t] + p.distance_m * (away / norm if norm > 1e-6 else heading(actor[t : t + 1])[0])
        move = target - spot[t - 1]
        dist = np.linalg.norm(move)
        spot[t] = spot[t - 1] + (move if dist <= step else move * (step / dist))
    toward = now - spot
    toward = toward / np.maximum(np.linalg.norm(toward, axis=-1, keepdims=True), 1e-9)
    return place(local, spot, smooth_direction(toward, KEEP_AWAY_FACING_TAU_S, fps))
