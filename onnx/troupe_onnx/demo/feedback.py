"""The partner's own placement, fed back into the condition (recipe v3).

Keep-away's partner stands wherever its leash has taken it: a place that depends on the whole
stream, not on the last second of the actor. Recipe v2's model had to read that place out of its
own latent history, which encodes it poorly (given the true history, its next keep-away token is
30-60 cm off at the root, mirror's 7-15 cm), so its partner wandered round the actor. v3 makes the
state visible: the condition of token k is the rule's one-hot followed by where the partner stood
at the last frame of token k - 1, relative to the actor at that frame, in the networks' frame:

    [valid, dx, dz, fx, fz]

`valid` is 1 once the partner has a frame (0 for the first token, whose feedback is all zeros),
(dx, dz) the partner's root less the actor's on the floor in metres, and (fx, fz) the partner's
unit facing on the floor (hips and shoulders, as `rules.heading`). Relative positions do not
change when the networks' frame is moved (recentring), so the runtime reads them from the frames
it decodes without undoing any shift.
"""

from __future__ import annotations

import torch

from troupe_onnx.motion.skeleton import t2m22

DIMS = 5
_NAMES = t2m22().names
_L_HIP, _R_HIP = _NAMES.index("left_hip"), _NAMES.index("right_hip")
_L_SHOULDER, _R_SHOULDER = _NAMES.index("left_shoulder"), _NAMES.index("right_shoulder")


def of(partner: torch.Tensor, actor: torch.Tensor) -> torch.Tensor:
    """Feedback [..., 5] of partner and actor joint positions [..., 22, 3] (metres, +Y up)."""
    across = (partner[..., _R_HIP, :] - partner[..., _L_HIP, :]) + (partner[..., _R_SHOULDER, :] - partner[..., _L_SHOULDER, :])
    facing = torch.stack([across[..., 2], -across[..., 0]], dim=-1)
    facing = facing / facing.norm(dim=-1, keepdim=True).clamp_min(1e-9)
    offset = partner[..., 0, [0, 2]] - actor[..., 0, [0, 2]]
    return torch.cat([torch.ones_like(offset[..., :1]), offset, facing], dim=-1)


def token_conditions(rule_onehot: torch.Tensor, partner_frames: torch.Tensor, actor_frames: torch.Tensor,
                     frames_per_token: int) -> torch.Tensor:
    """Conditions [B, N, R + 5] of N tokens: the one-hot [B, R], and for token k >= 1 the
    feedback at the last frame of token k - 1 (partner and actor frames [B, >= N * fpt, 22, 3]);
    token 0 has none."""
    b, r = rule_onehot.shape
    n = partner_frames.shape[1] // frames_per_token
    last = torch.arange(1, n) * frames_per_token - 1
    fed = of(partner_frames[:, last], actor_frames[:, last])
    fed = torch.cat([torch.zeros(b, 1, DIMS, dtype=fed.dtype), fed], dim=1)
    return torch.cat([rule_onehot[:, None].expand(b, n, r), fed], dim=-1)
