"""Bodies passing through each other, on joints: the capsule body of the t2m-22 skeleton, the
signed distance to it, ARFlow's penetration loss (`docs/spec/arflow.md` §3) and the metrics,
in torch so that autograd gives the reference gradient. Mirrored by `src/motion/body.rs` and
`src/motion/penetration.rs` (analytic gradients there), which are tested against this.
"""

from __future__ import annotations

import numpy as np

# t2m-22 joints (SMPL order) and parents.
T2M22_PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19]
# Each bone's capsule radius (metres) by its child joint (src/motion/body.rs, T2M22_RADII).
T2M22_RADII = {
    1: 0.10, 2: 0.10, 3: 0.11, 4: 0.075, 5: 0.075, 6: 0.11, 7: 0.05, 8: 0.05, 9: 0.12, 10: 0.04,
    11: 0.04, 12: 0.06, 13: 0.07, 14: 0.07, 15: 0.09, 16: 0.055, 17: 0.055, 18: 0.045, 19: 0.045,
    20: 0.035, 21: 0.035,
}
D_SAFE = 0.02  # the proposed default margin, metres


def capsules() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(from, to, radius) of the t2m-22 body's capsules, in the Rust table's order."""
    to = np.array(sorted(T2M22_RADII))
    return np.array([T2M22_PARENTS[j] for j in to]), to, np.array([T2M22_RADII[j] for j in to])


def signed_distance(pose, points):
    """Signed distance (torch) from `points` [..., K, 3] to the body posed at `pose` [..., 22, 3]
    (same leading shape): the smallest over the capsules of the distance to the axis less the
    radius."""
    import torch

    src, dst, radius = capsules()
    a, b = pose[..., src, :], pose[..., dst, :]  # [..., C, 3]
    axis = b - a
    p = points[..., :, None, :]  # [..., K, 1, 3]
    length2 = (axis * axis).sum(-1)[..., None, :]  # [..., 1, C]
    t = (((p - a[..., None, :, :]) * axis[..., None, :, :]).sum(-1) / length2).clamp(0.0, 1.0)
    nearest = a[..., None, :, :] + t[..., None] * axis[..., None, :, :]
    d = torch.linalg.norm(p - nearest, dim=-1) - torch.as_tensor(radius, dtype=pose.dtype)
    return d.min(dim=-1).values  # [..., K]


def penetration_loss(actor, reactor, d_safe: float = D_SAFE, squared: bool = False):
    """Σ_n Σ_j h(d_safe − φ_n(reactor[n, j])) for joints [F, 22, 3] (torch)."""
    import torch

    x = torch.relu(d_safe - signed_distance(actor, reactor))
    return (x * x if squared else x).sum()


def penetration_metrics(first: np.ndarray, second: np.ndarray) -> dict:
    """Intersection frequency and depth of two people's joints [F, 22, 3] (numpy in, floats out)."""
    import torch

    a, b = torch.as_tensor(first, dtype=torch.float64), torch.as_tensor(second, dtype=torch.float64)
    depth = torch.cat([torch.relu(-signed_distance(a, b)), torch.relu(-signed_distance(b, a))], dim=-1)
    inside = (depth > 0).any(-1)
    frames = depth.shape[0]
    return {
        "frames": frames,
        "frames_intersecting": int(inside.sum()),
        "frequency": float(inside.sum()) / frames if frames else 0.0,
        "depth_sum": float(depth.sum()),
        "max_depth": float(depth.max()) if frames else 0.0,
    }
