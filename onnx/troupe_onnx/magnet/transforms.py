"""Rigid transforms as MAGNet stores them (`docs/spec/magnet.md` §0, §5.0, §7.2), in numpy
float32: "9-D" = [6-D rotation (the first two columns of R), tx, ty, tz]; "7-D" = wxyz_xyz;
`compose(a, b)` applies b first. Mirrored by `src/magnet/transforms.rs`, its rotations by
`src/motion/rotation.rs`.
"""

from __future__ import annotations

import numpy as np

NORM_EPS = np.float32(1e-12)  # F.normalize's floor on a column's length


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.sqrt((v * v).sum(-1, keepdims=True))
    return v / np.maximum(n, NORM_EPS)


def rotation_from_6d(d6: np.ndarray) -> np.ndarray:
    """[..., 6] -> [..., 3, 3] by Gram-Schmidt on the two columns (SO3.from_6d)."""
    d6 = d6.astype(np.float32)
    a1, a2 = d6[..., 0:3], d6[..., 3:6]
    b1 = _normalize(a1)
    b2 = _normalize(a2 - (b1 * a2).sum(-1, keepdims=True) * b1)
    b3 = np.cross(b1, b2)
    return np.stack([b1, b2, b3], axis=-1).astype(np.float32)  # columns


def rotation_to_6d(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] -> [R00, R10, R20, R01, R11, R21]."""
    return np.concatenate([r[..., :, 0], r[..., :, 1]], axis=-1).astype(np.float32)


def from_9d(t9: np.ndarray) -> np.ndarray:
    """[..., 9] -> [..., 4, 4] homogeneous matrices."""
    out = np.zeros(t9.shape[:-1] + (4, 4), np.float32)
    out[..., :3, :3] = rotation_from_6d(t9[..., :6])
    out[..., :3, 3] = t9[..., 6:9]
    out[..., 3, 3] = 1.0
    return out


def to_9d(m: np.ndarray) -> np.ndarray:
    return np.concatenate([rotation_to_6d(m[..., :3, :3]), m[..., :3, 3]], axis=-1).astype(np.float32)


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a o b (b first) of [..., 4, 4] matrices."""
    return np.matmul(a, b).astype(np.float32)


def inverse(m: np.ndarray) -> np.ndarray:
    out = np.zeros_like(m)
    rt = np.swapaxes(m[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, m[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out.astype(np.float32)


def identity_9d(shape: tuple = ()) -> np.ndarray:
    out = np.zeros(shape + (9,), np.float32)
    out[..., 0] = 1.0
    out[..., 4] = 1.0
    return out


def quaternion_from_rotation(r: np.ndarray) -> np.ndarray:
    """[..., 3, 3] -> wxyz by Mike Day's four-case formula (the branch on the largest of the
    trace and the diagonal), sign as it falls."""
    r = r.astype(np.float32)
    m00, m11, m22 = r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]
    m01, m02, m10, m12, m20, m21 = r[..., 0, 1], r[..., 0, 2], r[..., 1, 0], r[..., 1, 2], r[..., 2, 0], r[..., 2, 1]
    one = np.float32(1.0)
    cases = [
        (one + m00 - m11 - m22, lambda t: (m21 - m12, t, m10 + m01, m02 + m20)),
        (one - m00 + m11 - m22, lambda t: (m02 - m20, m10 + m01, t, m21 + m12)),
        (one - m00 - m11 + m22, lambda t: (m10 - m01, m02 + m20, m21 + m12, t)),
        (one + m00 + m11 + m22, lambda t: (t, m21 - m12, m02 - m20, m10 - m01)),
    ]
    # Day: z-branch if m22 < 0 and m00 > m11 -> x, else y; else m00 < -m11 -> z, else w.
    use_x = (m22 < 0) & (m00 > m11)
    use_y = (m22 < 0) & ~(m00 > m11)
    use_z = (m22 >= 0) & (m00 < -m11)
    out = np.zeros(r.shape[:-2] + (4,), np.float32)
    for (t, parts), sel in zip(cases, [use_x, use_y, use_z, ~(use_x | use_y | use_z)]):
        q = np.stack(parts(t), axis=-1) * (np.float32(0.5) / np.sqrt(np.maximum(t, np.float32(1e-30))))[..., None]
        out = np.where(sel[..., None], q, out)
    return out.astype(np.float32)


def to_7d(m: np.ndarray) -> np.ndarray:
    """[..., 4, 4] -> wxyz_xyz."""
    return np.concatenate([quaternion_from_rotation(m[..., :3, :3]), m[..., :3, 3]], axis=-1).astype(np.float32)
