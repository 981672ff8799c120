"""The post-norm transformer layers of torch's nn.TransformerEncoder, written out for ONNX.

Both official codebases use torch's built-in layers in places: UMF's denoisers, experts and
context adapter, ARMFlow's text branch. These modules carry torch's parameter names, so the
official state dicts load into them as they are, and they export to plain ONNX ops.
"""

from __future__ import annotations

import torch
import torch.nn as nn
import torch.nn.functional as F


class Attention(nn.Module):
    """nn.MultiheadAttention (batch first, no dropout) with its parameter names: the packed
    q/k/v projection `in_proj_weight`/`in_proj_bias` and `out_proj`. Written out because the
    built-in module's ONNX trace bakes the batch and sequence sizes into its reshapes."""

    def __init__(self, width: int, heads: int):
        super().__init__()
        self.heads, self.scale = heads, (width // heads) ** -0.5
        self.in_proj_weight = nn.Parameter(nn.init.xavier_uniform_(torch.empty(3 * width, width)))
        self.in_proj_bias = nn.Parameter(torch.zeros(3 * width))
        self.out_proj = nn.Linear(width, width)

    def forward(self, x, memory=None, mask=None):
        """Self-attention over x [B, S, C], or x attending to memory [B, M, C]; `mask` [S, M]
        is added to the attention logits (CLIP's causal mask)."""
        w, b, c = self.in_proj_weight, self.in_proj_bias, x.shape[-1]
        if memory is None:
            q, k, v = F.linear(x, w, b).chunk(3, dim=-1)
        else:
            q = F.linear(x, w[:c], b[:c])
            k, v = F.linear(memory, w[c:], b[c:]).chunk(2, dim=-1)
        q, k, v = (t.unflatten(-1, (self.heads, -1)).transpose(1, 2) for t in (q, k, v))  # [B, H, S, Dh]
        logits = (q * self.scale) @ k.transpose(-2, -1)
        att = torch.softmax(logits if mask is None else logits + mask, dim=-1)
        return self.out_proj((att @ v).transpose(1, 2).flatten(2))


class EncoderLayer(nn.Module):
    """Post-norm transformer layer, exact GELU (the official TransformerEncoderLayer, eval):
    x = norm1(x + attn(x)); x = norm2(x + linear2(gelu(linear1(x))))."""

    def __init__(self, width: int, heads: int, ffn: int):
        super().__init__()
        self.self_attn = Attention(width, heads)
        self.linear1 = nn.Linear(width, ffn)
        self.linear2 = nn.Linear(ffn, width)
        self.norm1 = nn.LayerNorm(width)
        self.norm2 = nn.LayerNorm(width)

    def feed_forward(self, x):
        return self.linear2(F.gelu(self.linear1(x)))

    def forward(self, x):
        x = self.norm1(x + self.self_attn(x))
        return self.norm2(x + self.feed_forward(x))


def pick_token(x: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """x[b, index[b]] for x [B, T, C] and index [B] (int64), as an exact one-hot sum: advanced
    indexing exports to a Flatten that tract cannot shape with a symbolic batch."""
    one_hot = (torch.arange(x.shape[1])[None, :] == index[:, None]).to(x.dtype)
    return (x * one_hot[:, :, None]).sum(dim=1)


class EncoderStack(nn.Module):
    """nn.TransformerEncoder of post-norm layers: no positions, no final norm (keys
    `layers.i.*` as torch's module)."""

    def __init__(self, width: int, heads: int, ffn: int, layers: int):
        super().__init__()
        self.layers = nn.ModuleList(EncoderLayer(width, heads, ffn) for _ in range(layers))

    def forward(self, x):
        for layer in self.layers:
            x = layer(x)
        return x
