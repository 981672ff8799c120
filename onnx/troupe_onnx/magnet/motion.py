"""Frames <-> MAGNet's motion tokens (`shared/spec/magnet.md` §1.3-§1.5, §5.0 step 3, §7): the
normalisation statistics, the token layout, encoding a clip, decoding tokens and rebuilding each
person's root in one world frame. Mirrored by `src/magnet/decoding.rs`.

Per-frame, per-person features (the packed layout of §1.1 without hands and contacts):
body_joint_rotations [21, 6], T_canonical_root [9], T_canonical_tm1_canonical_t [9],
T_self_canonical_partner_canonical [P-1, 9], betas [10], and T_world_canonical [9] /
T_world_root [9] where the root is anchored.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from troupe_onnx.magnet.layout import BETAS, BODY_JOINTS, FRAMES_PER_TOKEN, TOKEN_TRANSFORMS, TRANSFORM
from troupe_onnx.magnet.networks import PoseVQVAE
from troupe_onnx.magnet.tasks import TransformStats
from troupe_onnx.magnet.transforms import compose, from_9d, quaternion_from_rotation, rotation_from_6d, to_7d, to_9d

STATS_DIM = 361  # §1.3: the statistics' length (hands included, one partner block)
STATS = {  # field -> [start, end) in the statistics (dataset_config.py:StdMeanIdx)
    "betas": (0, 10),
    "body_joint_rotations": (10, 136),
    "hand_joint_rotations": (136, 316),
    "T_canonical_tm1_canonical_t": (316, 325),
    "T_canonical_root": (325, 334),
    "T_world_root": (334, 343),
    "T_world_canonical": (343, 352),
    "T_self_canonical_partner_canonical": (352, 361),
}
STD_FLOOR = 1e-2  # computed stds below this were raised to it


@dataclass(frozen=True)
class Stats:
    mean: np.ndarray  # [361]
    std: np.ndarray

    def field(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        a, b = STATS[name]
        return self.mean[a:b].astype(np.float32), self.std[a:b].astype(np.float32)

    def normalize(self, name: str, x: np.ndarray) -> np.ndarray:
        m, s = self.field(name)
        return ((x - m) / s).astype(np.float32)

    def denormalize(self, name: str, x: np.ndarray) -> np.ndarray:
        m, s = self.field(name)
        return (x * s + m).astype(np.float32)

    def transform_stats(self) -> TransformStats:
        tm, ts = self.field("T_canonical_tm1_canonical_t")
        pm, ps = self.field("T_self_canonical_partner_canonical")
        return TransformStats(tm, ts, pm, ps)

    @staticmethod
    def random(seed: int) -> "Stats":
        """Plausible random statistics (std >= the floor), for random bundles."""
        rng = np.random.default_rng(seed)
        mean = (rng.standard_normal(STATS_DIM) * 0.1).astype(np.float32)
        std = (np.abs(rng.standard_normal(STATS_DIM)) * 0.5 + 0.5).astype(np.float32)
        return Stats(mean, np.maximum(std, STD_FLOOR).astype(np.float32))


@dataclass
class Clip:
    """One clip's per-frame features, every array [F, P, ...], float32 and not normalised."""

    body: np.ndarray  # [F, P, 21, 6]
    canonical_root: np.ndarray  # [F, P, 9]
    tm1_t: np.ndarray  # [F, P, 9]
    partner: np.ndarray  # [F, P, P-1, 9]
    betas: np.ndarray  # [P, 10]
    mask: np.ndarray  # [F, P] bool, tpose_mask
    world_canonical: np.ndarray  # [F, P, 9]
    world_root: np.ndarray  # [F, P, 9]

    @property
    def frames(self) -> int:
        return self.body.shape[0]

    @property
    def persons(self) -> int:
        return self.body.shape[1]

    def slice(self, a: int, b: int) -> "Clip":
        cut = lambda v: v[a:b]  # noqa: E731
        return Clip(cut(self.body), cut(self.canonical_root), cut(self.tm1_t), cut(self.partner), self.betas,
                    cut(self.mask), cut(self.world_canonical), cut(self.world_root))


def encode_clip(vqvae: PoseVQVAE, clip: Clip, stats: Stats) -> tuple[np.ndarray, np.ndarray]:
    """Tokens [F/4, P, D] and their mask [F/4, P] (§5.0 step 3, §1.5): latents are snapped
    codebook rows (zero where the person is absent), transforms normalised."""
    f, p = clip.frames, clip.persons
    if f % FRAMES_PER_TOKEN:
        raise ValueError(f"a clip of {f} frames: encoding needs a multiple of {FRAMES_PER_TOKEN}")
    t = f // FRAMES_PER_TOKEN
    body = stats.normalize("body_joint_rotations", clip.body.reshape(f, p, -1))
    root = stats.normalize("T_canonical_root", clip.canonical_root)
    tm1 = stats.normalize("T_canonical_tm1_canonical_t", clip.tm1_t)
    betas = stats.normalize("betas", clip.betas)
    val = np.concatenate([body, root], axis=-1).transpose(1, 0, 2)  # [P, F, 135]
    cond = np.concatenate([np.broadcast_to(betas[None], (f, p, BETAS)), tm1], axis=-1).transpose(1, 0, 2)
    with torch.no_grad():
        z = vqvae.quantizer.snap(vqvae.encode_continuous(torch.from_numpy(np.ascontiguousarray(val)),
                                                         torch.from_numpy(np.ascontiguousarray(cond)))).numpy()
    z = z.transpose(1, 0, 2)  # [T, P, latent]
    mask = clip.mask[::FRAMES_PER_TOKEN] > 0.5  # nearest-neighbour downsample
    z = np.where(mask[..., None], z, 0.0)
    parts = [z, tm1.reshape(t, FRAMES_PER_TOKEN, p, TRANSFORM).transpose(0, 2, 1, 3).reshape(t, p, -1)]
    if p > 1:
        partner = stats.normalize("T_self_canonical_partner_canonical", clip.partner)  # [F, P, P-1, 9]
        parts.append(partner.reshape(t, FRAMES_PER_TOKEN, p, p - 1, TRANSFORM).transpose(0, 2, 3, 1, 4).reshape(t, p, -1))
    return np.concatenate(parts, axis=-1).astype(np.float32), mask


@dataclass
class Decoded:
    """Decoded tokens, per frame, de-normalised: body [S, F, P, 21, 6], canonical_root and tm1_t
    [S, F, P, 9]."""

    body: np.ndarray
    canonical_root: np.ndarray
    tm1_t: np.ndarray


def decode_tokens(vqvae: PoseVQVAE, x: np.ndarray, betas: np.ndarray, stats: Stats, latent: int) -> Decoded:
    """§7.1: snap the latents, decode each person's whole sequence with [betas, tm1_t] as the
    condition. x [S, T, P, D]; betas [P, 10] normalised."""
    s, t, p, _ = x.shape
    tm1 = x[..., latent : latent + TOKEN_TRANSFORMS]
    cond = np.concatenate([np.broadcast_to(betas[None, None], (s, t, p, BETAS)), tm1], axis=-1)
    fold = lambda a: np.ascontiguousarray(a.transpose(0, 2, 1, 3).reshape(s * p, t, -1))  # noqa: E731
    with torch.no_grad():
        z = vqvae.quantizer.snap(torch.from_numpy(fold(x[..., :latent])))
        pose = vqvae.decode(z, torch.from_numpy(fold(cond))).numpy()  # [S*P, 4T, 135]
    pose = pose.reshape(s, p, FRAMES_PER_TOKEN * t, -1).transpose(0, 2, 1, 3)
    body = stats.denormalize("body_joint_rotations", pose[..., : BODY_JOINTS * 6]).reshape(s, -1, p, BODY_JOINTS, 6)
    root = stats.denormalize("T_canonical_root", pose[..., BODY_JOINTS * 6 :])
    tm1_frames = tm1.reshape(s, t, p, FRAMES_PER_TOKEN, TRANSFORM).transpose(0, 1, 3, 2, 4).reshape(s, -1, p, TRANSFORM)
    return Decoded(body, root, stats.denormalize("T_canonical_tm1_canonical_t", tm1_frames))


def world_roots(decoded: Decoded, context_frames: int, anchor_world_canonical: np.ndarray,
                gt_world_root: np.ndarray | None = None) -> np.ndarray:
    """§7.2 (mode `temporal`): each person's root in the world, 7-D wxyz_xyz [S, F, P, 7].
    The canonical frame at `context_frames` is `anchor_world_canonical` [P, 9] (the reference
    passes the ground truth there, §11 A2); later frames chain the predicted transitions; the
    first `context_frames` frames are `gt_world_root` [>= context_frames, P, 9] when given."""
    s, f, p, _ = decoded.canonical_root.shape
    c = context_frames
    world = np.broadcast_to(from_9d(anchor_world_canonical)[None], (s, p, 4, 4)).copy()
    roots = np.zeros((s, f, p, 4, 4), np.float32)
    if gt_world_root is not None:
        roots[:, :c] = from_9d(gt_world_root[:c])[None]
    else:
        roots[:, :c] = np.eye(4, dtype=np.float32)
    roots[:, c] = compose(world, from_9d(decoded.canonical_root[:, c]))
    for u in range(c + 1, f):
        world = compose(world, from_9d(decoded.tm1_t[:, u]))
        roots[:, u] = compose(world, from_9d(decoded.canonical_root[:, u]))
    return to_7d(roots)


def online_anchor(last_world_canonical: np.ndarray, first_tm1_t: np.ndarray) -> np.ndarray:
    """§11 A2's online default: the canonical frame at the first generated frame from the last
    known one and the predicted transition into it (9-D [P, 9])."""
    return to_9d(compose(from_9d(last_world_canonical), from_9d(first_tm1_t)))


def body_quaternions(body6d: np.ndarray) -> np.ndarray:
    """[..., 21, 6] -> [..., 21, 4] wxyz."""
    return quaternion_from_rotation(rotation_from_6d(body6d))
