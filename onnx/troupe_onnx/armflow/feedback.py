"""The reactor's own placement, fed back into its condition (`condition.feedback`:
`partner_placement`; the demo model's recipe v3).

Some partners stand wherever the whole stream has taken them, not where the actor's last second
says (the demo's keep-away partner, on its leash). A model that must read that place out of its
own latent history reads it poorly and wanders; a model with feedback is told it. The condition
the conditioning graph reads before token j is the caller's condition followed by

    [valid, dx, dz, fx, fz]

where the reactor stood at the last frame of token j - 1 (frame `j * frames_per_token - 1`),
relative to the actor at that frame, on the floor (+Y up): `valid` is 1 once the reactor has a
frame (token 0's feedback is all zeros), (dx, dz) the reactor's root less the actor's in metres,
(fx, fz) the reactor's unit facing (hips and shoulders, as the demo rules' `heading`). The
reactor's frame is the one the VAE decoder produced for token j - 1 (before any clean-up), the
actor's the caller's input frame; both are interhuman262 feature rows, whose first 66 columns
are the t2m22 joint positions. Only differences and directions are read, so where the stream or
the networks' frame sits on the floor (placement, recentring) does not change the vector.

The AdaLN modulation of the context encoder is therefore recomputed for every token. The runtime
mirrors this in `src/armflow/session/feedback.rs`.
"""

from __future__ import annotations

import torch

KIND = "partner_placement"  # the manifest's `condition.feedback.kind`
DIMS = 5  # floats fed back after the caller's condition
POSITIONS = slice(0, 66)  # interhuman262 columns of the t2m22 joint positions [22, 3]
# t2m22's hips and shoulders (the family reads no skeleton module; a test checks the indices).
_L_HIP, _R_HIP, _L_SHOULDER, _R_SHOULDER = 1, 2, 16, 17


def of(partner: torch.Tensor, actor: torch.Tensor) -> torch.Tensor:
    """Feedback [..., 5] of partner and actor joint positions [..., 22, 3] (metres, +Y up)."""
    across = (partner[..., _R_HIP, :] - partner[..., _L_HIP, :]) + (partner[..., _R_SHOULDER, :] - partner[..., _L_SHOULDER, :])
    facing = torch.stack([across[..., 2], -across[..., 0]], dim=-1)
    facing = facing / facing.norm(dim=-1, keepdim=True).clamp_min(1e-9)
    offset = partner[..., 0, [0, 2]] - actor[..., 0, [0, 2]]
    return torch.cat([torch.ones_like(offset[..., :1]), offset, facing], dim=-1)


def of_features(partner: torch.Tensor, actor: torch.Tensor) -> torch.Tensor:
    """Feedback [..., 5] of partner and actor interhuman262 feature rows [..., >= 66], computed
    in float64 as the runtime does (then rounded to float32)."""
    joints = lambda row: row[..., POSITIONS].to(torch.float64).reshape(*row.shape[:-1], 22, 3)  # noqa: E731
    return of(joints(partner), joints(actor)).to(torch.float32)


def token_conditions(condition: torch.Tensor, partner_frames: torch.Tensor, actor_frames: torch.Tensor,
                     frames_per_token: int) -> torch.Tensor:
    """Conditions [B, N, R + 5] of N tokens in one pass (training): the caller's condition
    [B, R] (the demo: the rule's one-hot), and for token k >= 1 the feedback at the last frame of
    token k - 1 (partner and actor joint positions [B, >= N * fpt, 22, 3]); token 0 has none."""
    b, r = condition.shape
    n = partner_frames.shape[1] // frames_per_token
    last = torch.arange(1, n) * frames_per_token - 1
    fed = of(partner_frames[:, last], actor_frames[:, last])
    fed = torch.cat([torch.zeros(b, 1, DIMS, dtype=fed.dtype), fed], dim=1)
    return torch.cat([condition[:, None].expand(b, n, r), fed], dim=-1)
