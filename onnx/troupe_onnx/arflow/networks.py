"""ARFlow's network (`docs/spec/arflow.md` §5): x̂_1 = G(x_t, t, c), a transformer decoder over
frames whose memory is one token, the embedding of the time (and of the condition when there is
one), as ReGenNet's `cmdm` (`arch == 'online'`) has it. No official code exists: the layer shapes
follow MDM's, the usual base of both.

- `x_t` [B, T, D] -> Linear -> + sinusoidal position encoding -> `layers` post-norm decoder layers
  (self-attention, cross-attention to the memory token, GELU feed-forward) -> Linear -> x̂_1.
- memory = MLP(sinusoid(1000 t)) [+ Linear(c)]: one token.
- `causal` (the online variant): the self-attention sees only earlier frames, so frame n of x̂_1
  depends only on frames <= n of x_t. The offline variant has no mask.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

NEG = -1e9  # masked attention logits (finite, so a fully masked row cannot give NaN)


@dataclass(frozen=True)
class ArflowConfig:
    dim: int = 262  # features per frame (interhuman262)
    width: int = 512
    layers: int = 8
    heads: int = 4
    feedforward: int = 1024
    condition_dim: int = 0  # 0: unconditioned (c = ∅)
    causal: bool = False  # the online variant
    max_frames: int = 1024  # the position encoding's table

    def to_json(self) -> dict:
        return dict(self.__dict__)


def sinusoid(x: torch.Tensor, width: int) -> torch.Tensor:
    """[..., ] -> [..., width]: sin of the first half, cos of the second, MDM's frequencies."""
    half = width // 2
    freq = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=torch.float32) / half)
    angle = x[..., None].float() * freq
    return torch.cat([torch.sin(angle), torch.cos(angle)], dim=-1)


class Attention(nn.Module):
    def __init__(self, width: int, heads: int):
        super().__init__()
        self.heads = heads
        self.q, self.k, self.v, self.out = (nn.Linear(width, width) for _ in range(4))

    def forward(self, x, memory, bias=None):
        b, t, w = x.shape
        h = self.heads
        split = lambda y: y.reshape(b, -1, h, w // h).transpose(1, 2)  # noqa: E731
        q, k, v = split(self.q(x)), split(self.k(memory)), split(self.v(memory))
        logits = q @ k.transpose(-1, -2) / math.sqrt(w // h)
        if bias is not None:
            logits = logits + bias
        y = torch.softmax(logits, dim=-1) @ v
        return self.out(y.transpose(1, 2).reshape(b, t, w))


class DecoderLayer(nn.Module):
    """Post-norm, as `nn.TransformerDecoderLayer(norm_first=False)`."""

    def __init__(self, cfg: ArflowConfig):
        super().__init__()
        self.self_attn = Attention(cfg.width, cfg.heads)
        self.cross_attn = Attention(cfg.width, cfg.heads)
        self.ff = nn.Sequential(nn.Linear(cfg.width, cfg.feedforward), nn.GELU(), nn.Linear(cfg.feedforward, cfg.width))
        self.norm1, self.norm2, self.norm3 = (nn.LayerNorm(cfg.width) for _ in range(3))

    def forward(self, x, memory, bias=None):
        x = self.norm1(x + self.self_attn(x, x, bias))
        x = self.norm2(x + self.cross_attn(x, memory))
        return self.norm3(x + self.ff(x))


class Arflow(nn.Module):
    def __init__(self, cfg: ArflowConfig):
        super().__init__()
        self.cfg = cfg
        self.input_process = nn.Linear(cfg.dim, cfg.width)
        self.register_buffer("position", sinusoid(torch.arange(cfg.max_frames), cfg.width), persistent=False)
        self.time_embed = nn.Sequential(nn.Linear(cfg.width, cfg.width), nn.SiLU(), nn.Linear(cfg.width, cfg.width))
        self.condition_embed = nn.Linear(cfg.condition_dim, cfg.width) if cfg.condition_dim else None
        self.layers = nn.ModuleList(DecoderLayer(cfg) for _ in range(cfg.layers))
        self.output_process = nn.Linear(cfg.width, cfg.dim)

    def memory(self, t, condition=None):
        m = self.time_embed(sinusoid(t * 1000.0, self.cfg.width))
        if self.condition_embed is not None:
            m = m + self.condition_embed(condition)
        return m[:, None]  # [B, 1, W]

    def forward(self, x, t, condition=None):
        """x [B, T, D], t [B] -> x̂_1 [B, T, D]."""
        frames = x.shape[1]
        h = self.input_process(x) + self.position[:frames]
        bias = None
        if self.cfg.causal:
            index = torch.arange(frames)
            bias = torch.where(index[None, :] > index[:, None], NEG, 0.0)
        memory = self.memory(t, condition)
        for layer in self.layers:
            h = layer(h, memory, bias)
        return self.output_process(h)


class FrameStep(nn.Module):
    """The causal network one frame at a time (the online variant's stream): the new frame's
    x_t [B, 1, D] at time t [B] and position [B], with the keys and values every layer's
    self-attention computed for the earlier frames at the same t, `cache_k`/`cache_v`
    [B, L, H, C, W/H] (rows of fewer frames padded, `cache_mask` [B, C] 1 where a frame is real)
    -> x̂_1 of the new frame [B, 1, D] and its keys and values [B, L, H, 1, W/H]. Equals frame n
    of `Arflow.forward` over frames 0..n (the mask makes later frames invisible there)."""

    def __init__(self, model: Arflow):
        super().__init__()
        self.model = model

    def forward(self, x, t, position, cache_k, cache_v, cache_mask):
        m = self.model
        b, _, _ = x.shape
        h = m.input_process(x) + m.position[position][:, None]
        memory = m.memory(t)
        bias = torch.cat([(1.0 - cache_mask) * NEG, torch.zeros(b, 1)], dim=1)[:, None, None, :]
        keys, values = [], []
        for index, layer in enumerate(m.layers):
            sa = layer.self_attn
            heads, w = sa.heads, h.shape[-1]
            split = lambda y: y.reshape(b, 1, heads, w // heads).transpose(1, 2)  # noqa: E731
            q, k_new, v_new = split(sa.q(h)), split(sa.k(h)), split(sa.v(h))
            k = torch.cat([cache_k[:, index], k_new], dim=2)
            v = torch.cat([cache_v[:, index], v_new], dim=2)
            logits = q @ k.transpose(-1, -2) / math.sqrt(w // heads) + bias
            y = (torch.softmax(logits, dim=-1) @ v).transpose(1, 2).reshape(b, 1, w)
            h = layer.norm1(h + sa.out(y))
            h = layer.norm2(h + layer.cross_attn(h, memory))
            h = layer.norm3(h + layer.ff(h))
            keys.append(k_new)
            values.append(v_new)
        return m.output_process(h), torch.stack(keys, dim=1), torch.stack(values, dim=1)


def init_random(model: Arflow, seed: int) -> None:
    """Seeded weights at a scale where the output depends on every input."""
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for name, p in sorted(model.named_parameters()):
            if name.endswith("bias"):
                p.copy_(torch.randn(p.shape, generator=gen) * 0.02)
            elif p.dim() == 1:  # LayerNorm scale
                p.copy_(1.0 + torch.randn(p.shape, generator=gen) * 0.05)
            else:
                p.copy_(torch.randn(p.shape, generator=gen) / math.sqrt(p.shape[1]))
