"""Joint rotations from joint positions and back, in numpy, vectorised over frames.

Written from the specification in `src/motion/ik.rs` (its module documentation) and the skeleton
document, as the reference the Rust implementation is tested against; it works with rotation
matrices where the Rust works with quaternions.

The rules, as specified:
- rotations are local: joint j's rotation turns the rest offsets of j's children, and its world
  rotation is its parent's world rotation times its local one (the root's local rotation is its
  world rotation);
- a joint with one child gets the shortest-arc rotation taking the child's rest offset onto the
  posed bone, seen from the parent's world frame (no twist about the bone);
- a joint with a branch frame (several children) is oriented by it: posed frame times rest
  frame transposed, the frame having x along (left child - right child) and y toward the up
  child made perpendicular to x;
- a joint without children gets no rotation (its world rotation is its parent's), and so does a
  bone of zero length or a branch frame whose directions are degenerate.

`fit_skeleton` measures a skeleton from a clip as `Skeleton::fitted_to` is specified to:
single-child bones keep their rest direction and take the clip's mean length; children of a
branch joint take their mean position in the branch's frame.
"""

from __future__ import annotations

import numpy as np

from troupe_onnx.motion.skeleton import Skeleton

# Shorter than this, a vector has no direction (the runtime's threshold).
TINY = 1e-9


def normalize(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along the last axis, and where they exist (norm > TINY)."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = (n[..., 0] > TINY) & np.isfinite(n[..., 0])
    return v / np.where(ok[..., None], n, 1.0), ok


def frame_matrix(across: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation whose columns are x = across/|across|, y = up made perpendicular to x, and
    x × y; and where it exists."""
    x, ok_x = normalize(across)
    y, ok_y = normalize(up - x * np.sum(x * up, axis=-1, keepdims=True))
    z = np.cross(x, y)
    return np.stack([x, y, z], axis=-1), ok_x & ok_y


def shortest_arc(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation matrix of the shortest arc taking direction a onto direction b (neither need
    be unit), broadcast over leading axes; and where both have a direction.

    Rodrigues' formula with v = â × b̂, c = â · b̂: R = I + [v]× + [v]×² / (1 + c). Opposite
    directions (1 + c < 1e-12) turn by half a turn about â × e, e = x̂ unless â is within
    ~25° of it, then ŷ (the runtime's choice; a half turn's axis is otherwise arbitrary)."""
    a, ok_a = normalize(a)
    b, ok_b = normalize(b)
    a, b = np.broadcast_arrays(a, b)
    c = np.sum(a * b, axis=-1)
    v = np.cross(a, b)
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2] = -v[..., 2], v[..., 1]
    k[..., 1, 0], k[..., 1, 2] = v[..., 2], -v[..., 0]
    k[..., 2, 0], k[..., 2, 1] = -v[..., 1], v[..., 0]
    opposite = 1.0 + c < 1e-12
    r = np.eye(3) + k + (k @ k) / np.where(opposite, 1.0, 1.0 + c)[..., None, None]
    if np.any(opposite):
        other = np.where((np.abs(a[..., 0]) < 0.9)[..., None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        n, _ = normalize(np.cross(a, other))
        half = 2.0 * n[..., :, None] * n[..., None, :] - np.eye(3)
        r = np.where(opposite[..., None, None], half, r)
    return r, np.broadcast_to(ok_a, c.shape) & np.broadcast_to(ok_b, c.shape)


def rest_frame(skeleton: Skeleton, joint: int) -> np.ndarray:
    """The rest-pose rotation of a branch joint's frame (the identity if degenerate)."""
    f = skeleton.branch_frames[joint]
    o = skeleton.offsets
    r, ok = frame_matrix(o[f.left] - o[f.right], o[f.up])
    return r if ok else np.eye(3)


def _branch_world(skeleton: Skeleton, joint: int, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f = skeleton.branch_frames[joint]
    posed, ok = frame_matrix(positions[:, f.left] - positions[:, f.right], positions[:, f.up] - positions[:, joint])
    return posed @ rest_frame(skeleton, joint).T, ok


def inverse_kinematics(skeleton: Skeleton, positions: np.ndarray) -> np.ndarray:
    """Local rotation matrices `[T, J, 3, 3]` of canonical joint positions `[T, J, 3]`."""
    positions = np.asarray(positions, dtype=np.float64)
    frames, joints = positions.shape[:2]
    assert joints == len(skeleton), f"{joints} joints for a {len(skeleton)}-joint skeleton"
    world = np.zeros((frames, joints, 3, 3))
    local = np.zeros((frames, joints, 3, 3))
    eye = np.broadcast_to(np.eye(3), (frames, 3, 3))
    for j in range(joints):
        p = skeleton.parents[j]
        parent = world[:, p] if p >= 0 else eye
        children = skeleton.children(j)
        if j in skeleton.branch_frames:
            w, ok = _branch_world(skeleton, j, positions)
        elif len(children) == 1:
            c = children[0]
            # The posed bone in the parent's frame, and the turn of the rest offset onto it.
            target = np.einsum("tji,tj->ti", parent, positions[:, c] - positions[:, j])
            turn, ok = shortest_arc(skeleton.offsets[c], target)
            w = parent @ turn
        else:
            w, ok = parent, np.zeros(frames, dtype=bool)
        world[:, j] = np.where(ok[:, None, None], w, parent)
        local[:, j] = np.where(ok[:, None, None], np.swapaxes(parent, -1, -2) @ world[:, j], np.eye(3))
    return local


def forward_kinematics(skeleton: Skeleton, root: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Joint positions `[T, J, 3]` from root positions `[T, 3]` and local rotations `[T, J, 3, 3]`."""
    frames, joints = local.shape[:2]
    world = np.zeros_like(local)
    out = np.zeros((frames, joints, 3))
    for j in range(joints):
        p = skeleton.parents[j]
        if p < 0:
            out[:, j] = root
            world[:, j] = local[:, j]
        else:
            out[:, j] = out[:, p] + world[:, p] @ skeleton.offsets[j]
            world[:, j] = world[:, p] @ local[:, j]
    return out


def fit_skeleton(skeleton: Skeleton, clip: np.ndarray) -> Skeleton:
    """The skeleton with bone lengths and branch shapes measured from canonical positions
    `[T, J, 3]` (see the module documentation). Frames where a branch has no frame are skipped."""
    clip = np.asarray(clip, dtype=np.float64)
    offsets = skeleton.offsets.copy()
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            continue
        if p in skeleton.branch_frames:
            w, ok = _branch_world(skeleton, p, clip)
            if ok.any():
                local = np.einsum("tji,tj->ti", w[ok], clip[ok, j] - clip[ok, p])
                offsets[j] = local.mean(axis=0)
        else:
            direction, ok = normalize(skeleton.offsets[j])
            if ok and len(clip):
                offsets[j] = direction * np.linalg.norm(clip[:, j] - clip[:, p], axis=-1).mean()
    return skeleton.with_offsets(offsets)


def to_6d(r: np.ndarray) -> np.ndarray:
    """InterHuman's 6-D rotation: the first two columns of the matrix, row by row:
    `[m00, m01, m10, m11, m20, m21]`."""
    return r[..., :, :2].reshape(r.shape[:-2] + (6,))
