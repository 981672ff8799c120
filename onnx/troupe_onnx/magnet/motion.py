"""Frames <-> MAGNet's motion tokens (`docs/spec/magnet.md` §1.3-§1.5, §5.0 step 3, §7): the
normalisation statistics, the token layout, deriving MAGNet's features from troupe's frames,
encoding a clip, decoding tokens and rebuilding each person's root in one world frame. Mirrored
by `src/magnet/motion.rs`. torch only where the VQ-VAE runs.

Per-frame, per-person features (the packed layout of §1.1 without hands and contacts):
body_joint_rotations [21, 6], T_canonical_root [9], T_canonical_tm1_canonical_t [9],
T_self_canonical_partner_canonical [P-1, 9], betas [10], and T_world_canonical [9] /
T_world_root [9] where the root is anchored.
"""

from __future__ import annotations

from dataclasses import dataclass

from typing import TYPE_CHECKING

import numpy as np

from troupe_onnx.magnet.layout import BETAS, BODY_JOINTS, FRAMES_PER_TOKEN, TOKEN_TRANSFORMS, TRANSFORM
from troupe_onnx.magnet.tasks import TransformStats
from troupe_onnx.magnet.transforms import (
    compose, from_9d, inverse, quaternion_from_rotation, rotation_from_6d, rotation_to_6d, to_9d,
)

if TYPE_CHECKING:
    from troupe_onnx.magnet.networks import PoseVQVAE

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


def encode_clip(vqvae: "PoseVQVAE", clip: Clip, stats: Stats) -> tuple[np.ndarray, np.ndarray]:
    """Tokens [F/4, P, D] and their mask [F/4, P] (§5.0 step 3, §1.5): latents are snapped
    codebook rows (zero where the person is absent), transforms normalised."""
    import torch

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


def decode_tokens(vqvae: "PoseVQVAE", x: np.ndarray, betas: np.ndarray, stats: Stats, latent: int) -> Decoded:
    """§7.1: snap the latents, decode each person's whole sequence with [betas, tm1_t] as the
    condition. x [S, T, P, D]; betas [P, 10] normalised."""
    import torch

    with torch.no_grad():
        z = vqvae.quantizer.snap(torch.from_numpy(np.ascontiguousarray(x[..., :latent]))).numpy()
    return _decode(vqvae, z, x[..., latent : latent + TOKEN_TRANSFORMS], betas, stats)


def _decode(vqvae: "PoseVQVAE", z: np.ndarray, tm1: np.ndarray, betas: np.ndarray, stats: Stats) -> Decoded:
    """Latents z [S, T, P, latent] (decoded as given) and the tokens' transitions tm1
    [S, T, P, 36] (normalised) -> per frame, de-normalised."""
    import torch

    s, t, p, _ = z.shape
    cond = np.concatenate([np.broadcast_to(betas[None, None], (s, t, p, BETAS)), tm1], axis=-1)
    fold = lambda a: np.ascontiguousarray(a.transpose(0, 2, 1, 3).reshape(s * p, t, -1))  # noqa: E731
    with torch.no_grad():
        pose = vqvae.decode(torch.from_numpy(fold(z)), torch.from_numpy(fold(cond))).numpy()  # [S*P, 4T, 135]
    pose = pose.reshape(s, p, FRAMES_PER_TOKEN * t, -1).transpose(0, 2, 1, 3)
    body = stats.denormalize("body_joint_rotations", pose[..., : BODY_JOINTS * 6]).reshape(s, -1, p, BODY_JOINTS, 6)
    root = stats.denormalize("T_canonical_root", pose[..., BODY_JOINTS * 6 :])
    tm1_frames = tm1.reshape(s, t, p, FRAMES_PER_TOKEN, TRANSFORM).transpose(0, 1, 3, 2, 4).reshape(s, -1, p, TRANSFORM)
    return Decoded(body, root, stats.denormalize("T_canonical_tm1_canonical_t", tm1_frames))


def key_tokens(vqvae: "PoseVQVAE", clip: Clip, keyframes, stats: Stats, window: int, latent: int):
    """§5.0 step 2 for in-betweening: the window's key tokens [Tm, P, D] and their mask [Tm].
    Key frame kf sets token kf // 4: its latent from frames kf..kf+3 encoded on their own, its
    transforms from the token's own frames (the official code fills every token's transform
    slices from the ground truth), so a key frame off the token grid (63) takes its latent from
    frames 63-66 and its transforms from 60-63."""
    keys, key_mask = None, np.zeros(window, bool)
    for kf in keyframes:
        tau = kf // FRAMES_PER_TOKEN
        own, _ = encode_clip(vqvae, clip.slice(tau * FRAMES_PER_TOKEN, (tau + 1) * FRAMES_PER_TOKEN), stats)
        at_key, _ = encode_clip(vqvae, clip.slice(kf, kf + FRAMES_PER_TOKEN), stats)
        if keys is None:
            keys = np.zeros((window,) + own.shape[1:], np.float32)
        keys[tau] = own[0]
        keys[tau, :, :latent] = at_key[0, :, :latent]
        key_mask[tau] = True
    return keys, key_mask


def overwrite_key_frames(vqvae: "PoseVQVAE", decoded: Decoded, x: np.ndarray, keys: np.ndarray, keyframes,
                         betas: np.ndarray, stats: Stats, latent: int) -> Decoded:
    """§7.4: after the whole sequence is decoded, each key frame kf whose 4 frames the output
    holds gets frames kf..kf+3 from its original key latent decoded on its own (one token, not
    snapped: `decode_wo_quantize`), with the sampled token kf // 4's transitions as the
    condition; body, canonical root and transitions are replaced. x [S, T, P, D] sampled,
    keys [Tm, P, D] as `key_tokens` made them."""
    s, t, p, _ = x.shape
    body, root, tm1_t = decoded.body.copy(), decoded.canonical_root.copy(), decoded.tm1_t.copy()
    for kf in keyframes:
        if FRAMES_PER_TOKEN * t < kf + FRAMES_PER_TOKEN:
            continue
        tau = kf // FRAMES_PER_TOKEN
        z = np.broadcast_to(keys[None, tau : tau + 1, :, :latent], (s, 1, p, latent))
        one = _decode(vqvae, z, x[:, tau : tau + 1, :, latent : latent + TOKEN_TRANSFORMS], betas, stats)
        frames = slice(kf, kf + FRAMES_PER_TOKEN)
        body[:, frames], root[:, frames], tm1_t[:, frames] = one.body, one.canonical_root, one.tm1_t
    return Decoded(body, root, tm1_t)


def anchor_frame(context_len: int) -> int:
    """§7.2: the frame the reference anchors every task's roots at, `context_seq_len` (4 when
    that is 0); the frames before it are the input's."""
    return context_len or FRAMES_PER_TOKEN


def world_roots(decoded: Decoded, context_frames: int, anchor_world_canonical: np.ndarray,
                gt_world_root: np.ndarray | None = None) -> np.ndarray:
    """§7.2 (mode `temporal`): each person's root in the world, 4x4 [S, F, P, 4, 4].
    The canonical frame at `context_frames` is `anchor_world_canonical` [P, 9] (the reference
    passes the ground truth there, §11 A2); later frames chain the predicted transitions; the
    first `context_frames` frames are `gt_world_root` [>= context_frames, P, 9] when given."""
    s, f, p, _ = decoded.canonical_root.shape
    c = min(context_frames, f - 1)
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
    return roots


def online_anchor(last_world_canonical: np.ndarray, first_tm1_t: np.ndarray) -> np.ndarray:
    """§11 A2's online default: the canonical frame at the first generated frame from the last
    known one and the predicted transition into it (9-D [P, 9])."""
    return to_9d(compose(from_9d(last_world_canonical), from_9d(first_tm1_t)))


def body_quaternions(body6d: np.ndarray) -> np.ndarray:
    """[..., 21, 6] -> [..., 21, 4] wxyz."""
    return quaternion_from_rotation(rotation_from_6d(body6d))


# --------------------------------------------------------------------------------------------
# troupe's frame layout: what a caller gives and gets, per person and frame
# --------------------------------------------------------------------------------------------

FRAME_LAYOUT = "magnet-smplx145"
FRAME = {"betas": (0, 10), "body": (10, 136), "world_root": (136, 145)}
FRAME_DIM = 145  # betas, 21 body joints' 6-D rotations, the root's pose in the world (9-D)


def canonical_frames(world_root: np.ndarray) -> np.ndarray:
    """§1.2 step 4: each frame's canonical frame, [..., 4, 4]: the root's heading about y (the
    yaw of its x axis) at the root's position on the floor (y = 0)."""
    root = from_9d(world_root)
    ex = root[..., :3, 0]
    psi = -np.arctan2(ex[..., 2], ex[..., 0])
    c, s = np.cos(psi).astype(np.float32), np.sin(psi).astype(np.float32)
    out = np.zeros(root.shape, np.float32)
    out[..., 0, 0], out[..., 0, 2], out[..., 1, 1], out[..., 2, 0], out[..., 2, 2] = c, s, 1.0, -s, c
    out[..., 0, 3], out[..., 2, 3], out[..., 3, 3] = root[..., 0, 3], root[..., 2, 3], 1.0
    return out


def clip_from_frames(frames: np.ndarray, mask: np.ndarray | None = None) -> Clip:
    """troupe's frames [F, P, 145] (betas from the first frame) -> every feature MAGNet reads,
    derived as §1.2 step 6 does: transitions between consecutive canonical frames (identity at
    frame 0), each partner's canonical frame in one's own, the root in one's canonical frame."""
    f, p, _ = frames.shape
    a, b = FRAME["world_root"]
    world_root = frames[..., a:b].astype(np.float32)
    canon = canonical_frames(world_root)
    inv = inverse(canon)
    tm1 = np.broadcast_to(np.eye(4, dtype=np.float32), canon.shape).copy()
    tm1[1:] = compose(inv[:-1], canon[1:])
    partner = np.zeros((f, p, max(p - 1, 0), 9), np.float32)
    for i in range(p):
        for j in range(p):
            if j != i:
                partner[:, i, j if j < i else j - 1] = to_9d(compose(inv[:, i], canon[:, j]))
    a0, b0 = FRAME["betas"]
    a1, b1 = FRAME["body"]
    return Clip(
        body=frames[..., a1:b1].reshape(f, p, BODY_JOINTS, 6).astype(np.float32),
        canonical_root=to_9d(compose(inv, from_9d(world_root))),
        tm1_t=to_9d(tm1),
        partner=partner,
        betas=frames[0, :, a0:b0].astype(np.float32),
        mask=np.ones((f, p), bool) if mask is None else mask.astype(bool),
        world_canonical=to_9d(canon),
        world_root=world_root,
    )


def frames_from_decoded(decoded: Decoded, roots: np.ndarray, betas: np.ndarray) -> np.ndarray:
    """Decoded tokens and world roots [S, F, P, 4, 4] -> troupe's frames [S, F, P, 145]; body
    rotations orthonormalised (SO3.from_6d, as the reference saves them), betas as given."""
    s, f, p = roots.shape[:3]
    body = rotation_to_6d(rotation_from_6d(decoded.body)).reshape(s, f, p, -1)
    return np.concatenate([np.broadcast_to(betas[None, None], (s, f, p, BETAS)), body, to_9d(roots)], axis=-1).astype(np.float32)
