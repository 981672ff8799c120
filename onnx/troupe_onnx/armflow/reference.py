"""PyTorch reference of ARMFlow's networks and of troupe's streaming sampling loop.

This module is the ground truth the Rust runtime is tested against. The networks follow
`docs/spec/armflow.md` (read from the official code) at any width and depth; the
streaming loop mirrors `src/armflow/session/` operation for operation, so that given the same noise the
two agree to float32 rounding.

Nothing here is copied from the official repository; it is written from the specification.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from troupe_onnx.armflow import feedback
from troupe_onnx.shared.clip import CONTEXT, FULL_MERGES, ClipTransformer, clip_features, empty_prompt, vocab_size
from troupe_onnx.shared.transformer import EncoderStack, pick_token

# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------


@dataclass
class VaeConfig:
    """CNN-VAE hyper-parameters (`docs/spec/armflow.md` §3)."""

    encoder_width: int  # 512 in the paper (`is_double`)
    decoder_width: int  # 256 in the paper
    depth: int  # ResConv1D blocks per Resnet1D; dilations 3**k, applied in reverse order
    kernel: int  # kernel of the dilated convolution (7 in the official code)
    norm_groups: int  # GroupNorm groups (32 in the official code)
    causal: bool  # True: the streaming variant (left padding, per-frame group statistics)


@dataclass
class ArmflowConfig:
    frame_dim: int = 262
    latent_dim: int = 256
    latent_scale: float = 0.1825
    cond_dim: int = 768
    layers: int = 7  # context encoder depth: (layers-1)/2 in, 1 mid, (layers-1)/2 out
    heads: int = 8
    mlp_blocks: int = 5
    frames_per_token: int = 4
    fps: int = 30
    context_capacity: int = 256
    steps: int = 1  # MeanFlow steps per token (the official num_steps)
    cfg_scale: float = 1.0  # guidance at inference (1: none, as the official models run)
    clip_frames: int = 0  # official clip length (300 InterHuman, 150 InterX); 0: streaming only
    text_branch: bool = False  # the official text encoder: CLIP's text tower and the branch after it
    text_heads: int = 8
    text_ffn: int = 2048
    clip_layers: int = 12  # CLIP ViT-L/14@336px's text tower (its width is cond_dim)
    clip_heads: int = 12
    clip_merges: int = FULL_MERGES  # the tokenizer's byte-pair merges
    stream_windows: VaeWindows | None = None  # stream-mode windows of a non-causal VAE
    null_condition: tuple[float, ...] | None = None  # what condition None means (zeros if unset), caller's part
    vae: VaeConfig = field(
        default_factory=lambda: VaeConfig(512, 256, 3, 3, 32, True)
    )
    # What the loop feeds back after the caller's condition before every token (`feedback.py`):
    # "partner_placement" or None. With it, `cond_dim` is the conditioning's whole input (the
    # caller's `caller_cond_dim` floats, then `feedback.DIMS`).
    condition_feedback: str | None = None

    def __post_init__(self):
        if self.condition_feedback not in (None, feedback.KIND):
            raise ValueError(f"condition_feedback {self.condition_feedback!r} is unknown (None or {feedback.KIND!r})")
        if self.condition_feedback is not None:
            if self.text_branch or self.clip_frames:
                raise ValueError("condition feedback is for streams: no text branch, no clip mode")
            if self.frame_dim != 262:
                raise ValueError("condition feedback reads t2m22 joint positions: interhuman262 frames (262)")
            if self.cond_dim <= feedback.DIMS:
                raise ValueError(f"cond_dim {self.cond_dim} leaves no room for the caller's condition")
        if self.null_condition is not None and len(self.null_condition) != self.caller_cond_dim:
            raise ValueError(f"null_condition has {len(self.null_condition)} floats, the caller's condition "
                             f"{self.caller_cond_dim}")

    @property
    def feedback_dim(self) -> int:
        """Floats fed back after the caller's condition (0 without feedback)."""
        return feedback.DIMS if self.condition_feedback else 0

    @property
    def caller_cond_dim(self) -> int:
        """Floats of the condition a caller passes (the manifest's `condition.dim`)."""
        return self.cond_dim - self.feedback_dim

    @property
    def width(self) -> int:
        # The context encoder and MLP run on (actor || reactor) tokens.
        return 2 * self.latent_dim

    @property
    def head_dim(self) -> int:
        return self.width // self.heads


# --------------------------------------------------------------------------------------------
# CNN-VAE (`docs/spec/armflow.md` §3), official (non-causal) and streaming (causal) variants
# --------------------------------------------------------------------------------------------


class FrameGroupNorm(nn.Module):
    """GroupNorm whose statistics are taken per frame (over the channels of a group only).

    The official GroupNorm averages over the whole time axis, which makes every token depend on
    the whole clip. The streaming variant keeps the same parameters but never mixes frames.
    """

    def __init__(self, groups: int, channels: int, eps: float = 1e-6):
        super().__init__()
        self.groups, self.eps = groups, eps
        self.weight = nn.Parameter(torch.ones(channels))
        self.bias = nn.Parameter(torch.zeros(channels))

    def forward(self, x):  # x: [B, C, T]
        b, c, _ = x.shape
        g = x.reshape(b, self.groups, c // self.groups, -1)
        mean = g.mean(dim=2, keepdim=True)
        var = (g - mean).pow(2).mean(dim=2, keepdim=True)
        g = (g - mean) / torch.sqrt(var + self.eps)
        return g.reshape(b, c, -1) * self.weight[None, :, None] + self.bias[None, :, None]


def make_norm(cfg: VaeConfig, channels: int) -> nn.Module:
    if cfg.causal:
        return FrameGroupNorm(cfg.norm_groups, channels)
    return nn.GroupNorm(cfg.norm_groups, channels, eps=1e-6, affine=True)


class TimeConv(nn.Conv1d):
    """Conv1d over time with explicit padding. Non-causal: symmetric, as the official code;
    causal: all of it on the left, so output n never sees input after n (after striding).
    A subclass of nn.Conv1d so that its parameters carry the official names."""

    def __init__(self, c_in, c_out, kernel, stride=1, dilation=1, causal=False, padding=None):
        super().__init__(c_in, c_out, kernel, stride=stride, dilation=dilation)
        total = (kernel - 1) * dilation if padding is None else 2 * padding
        if stride > 1:
            total = kernel - stride  # keeps length T/stride for T divisible by stride
        self.left = total if causal else total // 2
        self.right = 0 if causal else total - total // 2

    def forward(self, x):
        return super().forward(F.pad(x, (self.left, self.right)))

    def reach(self, lo: int, hi: int) -> tuple[int, int]:
        """Input index range (inclusive) that output indices lo..hi read."""
        k, s, d = self.kernel_size[0], self.stride[0], self.dilation[0]
        return s * lo - self.left, s * hi - self.left + (k - 1) * d


class ResConv1DBlock(nn.Module):
    """norm -> ReLU -> dilated conv -> norm -> ReLU -> 1x1 conv, plus the input."""

    def __init__(self, cfg: VaeConfig, width: int, dilation: int):
        super().__init__()
        self.norm1 = make_norm(cfg, width)
        self.conv1 = TimeConv(width, width, cfg.kernel, dilation=dilation, causal=cfg.causal)
        self.norm2 = make_norm(cfg, width)
        self.conv2 = TimeConv(width, width, 1, causal=cfg.causal)

    def forward(self, x):
        h = self.conv1(F.relu(self.norm1(x)))
        return x + self.conv2(F.relu(self.norm2(h)))

    def reach(self, lo, hi):
        lo2, hi2 = self.conv1.reach(*self.conv2.reach(lo, hi))
        return min(lo, lo2), max(hi, hi2)


class Resnet1D(nn.Module):
    def __init__(self, cfg: VaeConfig, width: int):
        super().__init__()
        dilations = [3**k for k in range(cfg.depth)][::-1]  # reverse_dilation: 27, 9, 3, 1
        self.model = nn.Sequential(*[ResConv1DBlock(cfg, width, d) for d in dilations])

    def forward(self, x):
        return self.model(x)


class Upsample2(nn.Module):
    def forward(self, x):
        return F.interpolate(x, scale_factor=2.0, mode="nearest")

    def reach(self, lo, hi):
        return lo // 2, hi // 2


class Relu(nn.Module):
    def forward(self, x):
        return F.relu(x)

    def reach(self, lo, hi):
        return lo, hi


def flat_layers(module: nn.Module) -> list[nn.Module]:
    """The VAE's layers in execution order, nested Sequentials and Resnet1Ds unrolled."""
    if isinstance(module, (nn.Sequential, Resnet1D)):
        seq = module.model if isinstance(module, Resnet1D) else module
        return [x for m in seq for x in flat_layers(m)]
    return [module]


def chain_reach(stack, lo, hi):
    """Walk a VAE stack backwards and return the input range the outputs lo..hi depend on."""
    for layer in reversed(flat_layers(stack.model)):
        lo, hi = layer.reach(lo, hi)
    return lo, hi


class VaeEncoder(nn.Module):
    """frames [B, T, D] -> (mean, logvar) [B, T/4, latent]. Official layout: `model` is
    conv, ReLU, 2 x (stride-2 conv, Resnet1D), conv."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        v, w = cfg.vae, cfg.vae.encoder_width
        layers = [TimeConv(cfg.frame_dim, w, 3, causal=v.causal, padding=1), Relu()]
        for _ in range(2):  # down_t = 2, stride 2 each
            layers.append(nn.Sequential(TimeConv(w, w, 4, stride=2, causal=v.causal, padding=1), Resnet1D(v, w)))
        layers += [TimeConv(w, 2 * cfg.latent_dim, 3, causal=v.causal, padding=1)]
        self.model = nn.Sequential(*layers)
        self.latent_dim = cfg.latent_dim

    def forward(self, motion):
        h = self.model(motion.transpose(1, 2)).transpose(1, 2)
        return h[..., : self.latent_dim], h[..., self.latent_dim :]


class VaeDecoder(nn.Module):
    """latents [B, N, latent] (unscaled) -> frames [B, 4N, D]. Official layout: `model` is
    conv, ReLU, 2 x (Resnet1D, upsample, conv), conv, ReLU, conv."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        v, w = cfg.vae, cfg.vae.decoder_width
        layers = [TimeConv(cfg.latent_dim, w, 3, causal=v.causal, padding=1), Relu()]
        for _ in range(2):
            layers.append(nn.Sequential(Resnet1D(v, w), Upsample2(), TimeConv(w, w, 3, causal=v.causal, padding=1)))
        layers += [
            TimeConv(w, w, 3, causal=v.causal, padding=1),
            Relu(),
            TimeConv(w, cfg.frame_dim, 3, causal=v.causal, padding=1),
        ]
        self.model = nn.Sequential(*layers)

    def forward(self, latents):
        return self.model(latents.transpose(1, 2)).transpose(1, 2)


class KLVae(nn.Module):
    """The VAE's two halves under the official names (`vae.encoder`, `vae.decoder`)."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        self.encoder = VaeEncoder(cfg)
        self.decoder = VaeDecoder(cfg)


class VaeStep(nn.Module):
    """One token of a causal VAE (encoder or decoder) with its convolution state made explicit:
    `(chunk [B, n, C_in], *state) -> (out [B, m, C_out], *next_state)`, one row per stream.

    Every causal TimeConv with left padding `p > 0` keeps the last `p` frames of its input; a
    stream starts from zeros, which is the causal pass's zero padding. Norms are per frame and
    upsampling is per frame, so nothing else carries over between tokens. Stepping token by token
    equals one causal pass over the whole stream, at O(1) cost per token instead of a window.
    """

    def __init__(self, stack: nn.Module):
        super().__init__()
        self.stack = stack
        self.convs = [m for m in stack.modules() if isinstance(m, TimeConv) and m.left > 0]

    def state_shapes(self, batch: int = 1) -> list[tuple[int, int, int]]:
        return [(batch, c.in_channels, c.left) for c in self.convs]

    def forward(self, chunk, *state):
        assert len(state) == len(self.convs)
        states, next_state = iter(state), []

        def conv(c: TimeConv, h):
            if c.left == 0:
                return nn.Conv1d.forward(c, h)
            full = torch.cat([next(states), h], dim=2)
            next_state.append(full[:, :, -c.left :])
            return nn.Conv1d.forward(c, full)

        h = chunk.transpose(1, 2)
        for layer in flat_layers(self.stack.model):
            if isinstance(layer, TimeConv):
                h = conv(layer, h)
            elif isinstance(layer, ResConv1DBlock):
                r = conv(layer.conv1, F.relu(layer.norm1(h)))
                h = h + conv(layer.conv2, F.relu(layer.norm2(r)))
            else:
                h = layer(h)
        return (h.transpose(1, 2), *next_state)


class ChannelsLastVaeStep(VaeStep):
    """`VaeStep` written channels-last, as the bundle's step graphs are: every convolution one matrix product
    over the rows of all streams and output frames (`[B·T_out, k·C_in] @ [k·C_in, C_out]`, the
    taps of every output frame gathered at once), every group norm a layer norm over the channels
    of a group.
    Same function, same weights; the state is channels-last too (`[B, K, C]`: the last `K`
    frames of a convolution's input, oldest first), so a step moves no state between layouts. No
    per-stream convolution and no broadcast over a strided axis, which is what makes the
    channels-first graph slow in tract."""

    def state_shapes(self, batch: int = 1) -> list[tuple[int, int, int]]:
        return [(batch, c.left, c.in_channels) for c in self.convs]

    def forward(self, chunk, *state):
        assert len(state) == len(self.convs)
        states, next_state = iter(state), []

        def conv(c: TimeConv, h):  # h [B, T, C_in] -> [B, T_out, C_out]
            if c.left > 0:
                h = torch.cat([next(states), h], dim=1)
                next_state.append(h[:, -c.left :, :])
            k, s, d = c.kernel_size[0], c.stride[0], c.dilation[0]
            t_out = (h.shape[1] - (k - 1) * d - 1) // s + 1
            if k > 1 or s > 1:
                # Every output frame's taps in one gather, frame-major then tap-major: row
                # t * k + i is input frame t * s + i * d, so the reshape puts output t's taps
                # side by side. One gather, not a slice per tap and a concatenation: tract
                # splits a product whose input is a concatenation into a product per part.
                frames = torch.tensor([t * s + i * d for t in range(t_out) for i in range(k)])
                h = h.index_select(1, frames).reshape(-1, t_out, k * h.shape[2])
            w = c.weight.permute(0, 2, 1).reshape(c.out_channels, -1)  # tap-major, as the gather
            return F.linear(h, w, c.bias)

        def norm(n: FrameGroupNorm, h):  # per frame, over each group's channels
            width = n.weight.shape[0] // n.groups  # static sizes: the export keeps them constant
            g = F.layer_norm(h.unflatten(-1, (n.groups, width)), (width,), eps=n.eps)
            return g.flatten(-2) * n.weight + n.bias

        h = chunk
        for layer in flat_layers(self.stack.model):
            if isinstance(layer, TimeConv):
                h = conv(layer, h)
            elif isinstance(layer, ResConv1DBlock):
                r = conv(layer.conv1, F.relu(norm(layer.norm1, h)))
                h = h + conv(layer.conv2, F.relu(norm(layer.norm2, r)))
            elif isinstance(layer, Upsample2):
                h = h.repeat_interleave(2, dim=1)
            else:
                h = layer(h)
        return (h, *next_state)


def encoder_context_frames(enc: VaeEncoder, fpt: int) -> int:
    """Frames before a token's first frame that its (causal) encoding depends on, rounded up to a
    whole token so that every window starts on the token grid."""
    lo, hi = chain_reach(enc, 1000, 1000)
    assert hi <= 1001 * fpt - 1, "encoder must not look ahead"
    need = 1000 * fpt - lo
    return -(-need // fpt) * fpt


def decoder_context_tokens(dec: VaeDecoder, fpt: int) -> int:
    """Tokens before token j that the frames of token j depend on (causal decoder)."""
    j = 1000
    lo, hi = chain_reach(dec, j * fpt, j * fpt + fpt - 1)
    assert hi <= j, "decoder must not look ahead"
    return j - lo


# --------------------------------------------------------------------------------------------
# Context encoder: SkipAdaLN transformer with <sos> (`docs/spec/armflow.md` §4)
# --------------------------------------------------------------------------------------------


def sinusoid_positions(positions: torch.Tensor, width: int) -> torch.Tensor:
    """pe[p, 2k] = sin(p w_k), pe[p, 2k+1] = cos(p w_k), w_k = exp(-2k ln(10000)/width)."""
    div = torch.exp(torch.arange(0, width, 2, dtype=torch.float32) * (-math.log(10000.0) / width))
    ang = positions.to(torch.float32)[..., None] * div
    return torch.stack([torch.sin(ang), torch.cos(ang)], dim=-1).flatten(-2)


class SelfAttention(nn.Module):
    def __init__(self, width: int, heads: int):
        super().__init__()
        self.heads, self.head_dim = heads, width // heads
        self.scale = 0.25 / math.sqrt(self.head_dim)  # VAR-style, 1/32 at head dim 64
        self.mat_qkv = nn.Linear(width, 3 * width, bias=False)
        self.q_bias = nn.Parameter(torch.zeros(width))
        self.v_bias = nn.Parameter(torch.zeros(width))
        self.register_buffer("zero_k_bias", torch.zeros(width))  # in the official state dict
        self.proj = nn.Linear(width, width)

    def forward(self, x, past_k, past_v, past_mask, new_mask):
        """x [B, S, C]; past_k/past_v [B, H, P, Dh] with past_mask [B, 1, 1, P] (0 keeps an
        entry, -1e30 hides it); new_mask [S, S] over the new tokens. Returns (output, k, v) with
        only the new tokens' keys and values: the caller owns the cache. Attention is split into
        a past and a new part under one softmax, so no step copies the cache."""
        b, s, c = x.shape
        bias = torch.cat((self.q_bias, self.zero_k_bias, self.v_bias))
        qkv = F.linear(x, self.mat_qkv.weight, bias).view(b, s, 3, self.heads, self.head_dim)
        q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # [B, H, S, Dh]
        p = past_k.shape[2]
        # Written with keys as rows (scores [B, H, P+S, S]) so that with one new token every
        # product has the cache's length as its long side: tract then runs its matrix-vector
        # kernels on whole rows instead of padding a single query row to a 32-row tile.
        flip = lambda m: m.transpose(-2, -1) if torch.is_tensor(m) and m.dim() >= 2 else m  # noqa: E731
        on_past = (past_k @ q.transpose(-2, -1)) * self.scale + flip(past_mask)
        on_new = (k @ q.transpose(-2, -1)) * self.scale + flip(new_mask)
        att = torch.cat([on_past, on_new], dim=-2).softmax(dim=-2)  # scores only
        out = past_v.transpose(-2, -1) @ att[..., :p, :] + v.transpose(-2, -1) @ att[..., p:, :]  # [B, H, Dh, S]
        return self.proj(out.permute(0, 3, 1, 2).reshape(b, s, c)), k, v

    def projections(self, x):
        """The runtime's split (`layer_entry`): x [N, C] to the queries, already multiplied by
        the scale, and the keys and values, [N, C] each with the heads side by side."""
        bias = torch.cat((self.q_bias, self.zero_k_bias, self.v_bias))
        q, k, v = F.linear(x, self.mat_qkv.weight, bias).chunk(3, dim=-1)
        return q * self.scale, k, v


class FFN(nn.Module):
    def __init__(self, width: int):
        super().__init__()
        self.fc1 = nn.Linear(width, 4 * width)
        self.fc2 = nn.Linear(4 * width, width)

    def forward(self, x):
        return self.fc2(F.gelu(self.fc1(x), approximate="tanh"))


class AdaLNSelfAttn(nn.Module):
    def __init__(self, width: int, heads: int, cond_dim: int):
        super().__init__()
        self.width = width
        self.attn = SelfAttention(width, heads)
        self.ffn = FFN(width)
        self.ada_lin = nn.Sequential(nn.SiLU(), nn.Linear(cond_dim, 6 * width))

    def modulation(self, cond):  # [B, cond] -> [B, 6, C]; per token: [B, S, cond] -> [B, 6, S, C]
        if cond.dim() == 3:
            return self.ada_lin(cond).view(*cond.shape[:2], 6, self.width).transpose(1, 2)
        return self.ada_lin(cond).view(-1, 6, self.width)

    def forward(self, x, mod, past_k, past_v, past_mask, new_mask):
        per_token = mod if mod.dim() == 4 else mod[:, :, None, :]  # [B, 6, S or 1, C]
        g1, g2, s1, s2, sh1, sh2 = per_token.unbind(1)  # each [B, S or 1, C]
        ln = lambda t: F.layer_norm(t, (self.width,), eps=1e-6)  # noqa: E731
        a, k, v = self.attn(ln(x) * (1 + s1) + sh1, past_k, past_v, past_mask, new_mask)
        x = x + g1 * a
        x = x + g2 * self.ffn(ln(x) * (1 + s2) + sh2)
        return x, k, v

    def start(self, x, mod):
        """The block up to its attention: x [N, C], mod [6, N, C] to (q, k, v) [N, C]. The
        modulation is component-major so that each component is one contiguous [N, C] block."""
        _, _, s1, _, sh1, _ = mod.unbind(0)
        return self.attn.projections(F.layer_norm(x, (self.width,), eps=1e-6) * (1 + s1) + sh1)

    def finish(self, x, attention, mod):
        """The block after its attention: `attention` [N, C] is the softmax-weighted sum of the
        values, heads side by side, before the output projection."""
        g1, g2, _, s2, _, sh2 = mod.unbind(0)
        x = x + g1 * self.attn.proj(attention)
        return x + g2 * self.ffn(F.layer_norm(x, (self.width,), eps=1e-6) * (1 + s2) + sh2)


class SkipAdaLNTransformer(nn.Module):
    """The context encoder (official `armflow.arnet`): in layers, a mid layer and out layers
    that each first fuse the matching in layer's output (LIFO) through a linear layer."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        assert cfg.layers % 2 == 1, "layers = 2 * n_in + 1"
        n, c = cfg.layers // 2, cfg.width
        self.width, self.n_in = c, n
        block = lambda: AdaLNSelfAttn(c, cfg.heads, cfg.cond_dim)  # noqa: E731
        self.in_layers = nn.ModuleList(block() for _ in range(n))
        self.mid_layer = block()
        self.out_layers = nn.ModuleList(block() for _ in range(n))
        self.linear_layers = nn.ModuleList(nn.Linear(2 * c, c) for _ in range(n))

    def blocks(self) -> list[AdaLNSelfAttn]:
        return [*self.in_layers, self.mid_layer, *self.out_layers]

    def modulation(self, cond):  # [B, cond] -> [B, L, 6, C]; per token [B, S, cond] -> [B, L, 6, S, C]
        return torch.stack([blk.modulation(cond) for blk in self.blocks()], dim=1)

    def run(self, x, modulation, past, past_mask, new_mask):
        """x [B, S, C] (positions added), past: L (k, v) pairs -> (output [B, S, C], new), new
        holding the new tokens' (k, v) per layer."""
        skips, present = [], []
        for i, blk in enumerate(self.blocks()):
            if i > self.n_in:  # out layers pop the skips LIFO
                x = self.linear_layers[i - self.n_in - 1](torch.cat([x, skips.pop()], dim=-1))
            x, k, v = blk(x, modulation[:, i], past[i][0], past[i][1], past_mask, new_mask)
            present.append((k, v))
            if i < self.n_in:
                skips.append(x)
        return x, present  # no final norm: the official head_nm is never called

    def step(self, tokens, positions, modulation, past, key_mask=None):
        """tokens [B, S, C], positions int64 [B, S], modulation [B, L, 6, C], past: list of L
        (k, v) pairs [B, H, P, Dh], key_mask [B, P] added to the scores of the past keys (0 to
        keep, -1e30 to skip a free slot or padding; the runtime's cache has both). The new
        tokens see every kept past entry and, causally, each other. Returns (context [B, C] at
        the last position, the new tokens' (k, v) pairs [B, H, S, Dh] per layer)."""
        p, s = past[0][0].shape[2], tokens.shape[1]
        if key_mask is None:
            key_mask = torch.zeros(tokens.shape[0], p)
        # Absolute positions, as before the runtime owned the cache: a mask built from one
        # `arange(S)` compared with itself is mis-shaped by tract 0.23's optimiser.
        key_pos, query_pos = torch.arange(s) + p, torch.arange(p, p + s)
        causal = torch.where(key_pos[None, :] <= query_pos[:, None], 0.0, -1e30)  # [S, S]
        x, new = self.run(
            tokens + sinusoid_positions(positions, self.width), modulation, past, key_mask[:, None, None, :], causal
        )
        return x[:, -1], new

    # The split the runtime runs: the dense parts as `layers + 1` graphs over N token rows of
    # any streams, the attention between them its own (over the cache it owns).

    def layer_entry(self, tokens, positions, modulation):
        """Graph 0: tokens [N, C] at positions [N] (int64) under layer 0's modulation [6, N, C]
        to the residual stream x and block 0's (q, k, v), [N, C] each."""
        x = tokens + sinusoid_positions(positions, self.width)
        return (x, *self.blocks()[0].start(x, modulation))

    def layer_link(self, index, x, attention, finish_modulation, modulation, skip=None):
        """Graph `index` (1 <= index < layers): finishes block index-1 with its attention output,
        fuses the skip an out layer pops (index > n_in), and starts block `index`."""
        blocks = self.blocks()
        x = blocks[index - 1].finish(x, attention, finish_modulation)
        if index > self.n_in:
            x = self.linear_layers[index - self.n_in - 1](torch.cat([x, skip], dim=-1))
        return (x, *blocks[index].start(x, modulation))

    def layer_exit(self, x, attention, finish_modulation):
        """Graph `layers`: finishes the last block; the context of every row."""
        return self.blocks()[-1].finish(x, attention, finish_modulation)

    def layer_skip_source(self, index) -> bool:
        """Whether graph `index`'s x output is a skip an out layer reads later (LIFO)."""
        return 1 <= index <= self.n_in

    def full(self, tokens, modulation):
        """The official inference call: the whole prefix [B, S, C] at positions 0..S-1 with no
        attention mask (earlier tokens also see later ones). Returns the last position [B, C]."""
        b, s, _ = tokens.shape
        h = self.in_layers[0].attn
        empty = torch.zeros(b, h.heads, 0, h.head_dim)
        x = tokens + sinusoid_positions(torch.arange(s), self.width)[None]
        x, _ = self.run(x, modulation, [(empty, empty)] * len(self.blocks()), 0.0, 0.0)
        return x[:, -1]


# --------------------------------------------------------------------------------------------
# Velocity MLP (`docs/spec/armflow.md` §5)
# --------------------------------------------------------------------------------------------


class TimestepEmbedder(nn.Module):
    def __init__(self, width: int, freq_dim: int = 256):
        super().__init__()
        self.freq_dim = freq_dim
        self.mlp = nn.Sequential(nn.Linear(freq_dim, width), nn.SiLU(), nn.Linear(width, width))

    def forward(self, t):  # t [B], raw in [0, 1]
        half = self.freq_dim // 2
        freqs = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=torch.float32) / half)
        args = t[:, None].to(torch.float32) * freqs[None]
        return self.mlp(torch.cat([torch.cos(args), torch.sin(args)], dim=-1))  # cos first


class AdaLnMLPBlock(nn.Module):
    def __init__(self, width: int):
        super().__init__()
        self.width = width
        self.ada_lin = nn.Sequential(nn.SiLU(), nn.Linear(width, 2 * width))
        self.linear1 = nn.Linear(width, 4 * width)
        self.linear2 = nn.Linear(4 * width, width)

    def forward(self, x, cond):
        scale, shift = self.ada_lin(cond).chunk(2, dim=-1)
        h = F.layer_norm(x, (self.width,), eps=1e-5) * (1 + scale) + shift
        return x + self.linear2(F.relu(self.linear1(h)))


class AdaLnMLP(nn.Module):
    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        self.blocks = nn.Sequential(*[AdaLnMLPBlock(cfg.width) for _ in range(cfg.mlp_blocks)])


class ArmflowCore(nn.Module):
    """The autoregressive part under the official names (`armflow.*`): <sos>, the context
    encoder `arnet`, the r/t embedders and the velocity MLP `mlp`."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        self.latent_dim = cfg.latent_dim
        self.start_token = nn.Parameter(torch.randn(1, 1, cfg.width) * 0.5)
        self.arnet = SkipAdaLNTransformer(cfg)
        self.r_embedder = TimestepEmbedder(cfg.width)
        self.t_embedder = TimestepEmbedder(cfg.width)
        self.mlp = AdaLnMLP(cfg)

    def velocity(self, actor, noisy, context, r, t):  # [B, latent], [B, latent], [B, C], [B], [B]
        """u(z, r, t | a, c): average velocity of the reactor half."""
        x = torch.cat([actor, noisy], dim=-1)
        cond = context + self.r_embedder(r) + self.t_embedder(t)
        for blk in self.mlp.blocks:
            x = blk(x, cond)
        return x[:, self.latent_dim :]  # no head: the reactor half of the residual stream


class VelocityGraph(nn.Module):
    def __init__(self, core: ArmflowCore):
        super().__init__()
        self.core = core

    def forward(self, actor, noisy, context, r, t):
        return self.core.velocity(actor, noisy, context, r, t)


class TextBranch(nn.Module):
    """The official text encoder (`models/armflow/textenc.py`, "intergen" style) under its
    names: CLIP's frozen text tower (`clip_token_embedding`, `clip_positional_embedding`,
    `clip_transformer`, `clip_ln_final`) gives token features [B, 77, 768]; the trainable part
    (`clipTrans`: 2 post-norm layers, `clipln`) turns them into the condition [B, 768], read at
    the end-of-text token (the argmax of CLIP's token ids)."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        c = cfg.cond_dim
        self.clip_token_embedding = nn.Embedding(vocab_size(cfg.clip_merges), c)
        self.clip_transformer = ClipTransformer(c, cfg.clip_layers, cfg.clip_heads)
        self.clip_positional_embedding = nn.Parameter(torch.randn(CONTEXT, c) * 0.01)
        self.clip_ln_final = nn.LayerNorm(c)
        self.clipTrans = EncoderStack(c, cfg.text_heads, cfg.text_ffn, 2)
        self.clipln = nn.LayerNorm(c)

    def clip_features(self, ids):  # [B, 77] int64 -> [B, 77, C]
        return clip_features(
            self.clip_token_embedding, self.clip_positional_embedding, self.clip_transformer, self.clip_ln_final, ids
        )

    def forward(self, tokens, eot):  # [B, T, C] float, [B] int64
        return pick_token(self.clipln(self.clipTrans(tokens)), eot)

    @torch.no_grad()
    def empty_prompt(self) -> torch.Tensor:
        """[1, C]: "" through CLIP and the branch, which the official code encodes for "no text"
        (`encode_null_condition`): ids [<|startoftext|>, <|endoftext|>, 0, ...]."""
        ids, eot = empty_prompt(self.clip_token_embedding.num_embeddings)
        return self(self.clip_features(ids), eot)


class Armflow(nn.Module):
    """ARMFlow under the official module and parameter names: `vae.*`, `armflow.*` and, when
    the configuration has a text branch, `text_encoder.clipTrans.*` / `text_encoder.clipln.*`."""

    def __init__(self, cfg: ArmflowConfig):
        super().__init__()
        self.cfg = cfg
        self.vae = KLVae(cfg)
        self.armflow = ArmflowCore(cfg)
        if cfg.text_branch:
            self.text_encoder = TextBranch(cfg)


# --------------------------------------------------------------------------------------------
# Seeded noise: stream ids of the portable generator (troupe_onnx.shared.noise)
# --------------------------------------------------------------------------------------------

STREAM_ACTOR_POSTERIOR = 0
STREAM_REACTOR_NOISE = 1


# --------------------------------------------------------------------------------------------
# The streaming loop troupe runs (mirrors src/armflow/session/)
# --------------------------------------------------------------------------------------------


def meanflow_grid(steps: int) -> list[float]:
    """The official `torch.linspace(1, 0, steps + 1)` in float32 as ATen's CUDA kernel (and the
    CPU kernel's scalar path) computes it: step = -1 / steps, 1 + step * k for the first half
    of the points, 0 - step * (steps - k) for the rest (1 is noise, 0 is data)."""
    f = np.float32
    points, step = steps + 1, f(f(-1) / f(steps))
    return [
        float(f(1) + f(step * f(k)) if k < points // 2 else f(0) - f(step * f(points - k - 1)))
        for k in range(points)
    ]


@dataclass
class StreamOptions:
    steps: int = 1
    cfg_scale: float = 1.0
    condition: np.ndarray | None = None
    capacity: int | None = None  # context tokens kept, <sos> included


@dataclass
class VaeWindows:
    """The stream-mode VAE windows of the manifest's `vae` section."""

    context_frames: int
    lookahead_frames: int
    context_tokens: int
    lookahead_tokens: int

    @staticmethod
    def of(model: Armflow) -> "VaeWindows":
        """The configured windows; for a causal VAE, those that make windowed calls equal one
        pass over the stream."""
        if model.cfg.stream_windows is not None:
            return model.cfg.stream_windows
        fpt = model.cfg.frames_per_token
        return VaeWindows(
            encoder_context_frames(model.vae.encoder, fpt), 0,
            decoder_context_tokens(model.vae.decoder, fpt), 0,
        )


def null_condition(model: Armflow) -> torch.Tensor:
    """[1, caller_cond_dim]: what "no condition" means: the empty prompt through the text
    encoder when the model has one (the official meaning), else the configuration's null
    condition, else zeros. The caller's part only: feedback is the loop's to append."""
    cfg = model.cfg
    if cfg.text_branch:
        return model.text_encoder.empty_prompt()
    if cfg.null_condition is not None:
        return torch.tensor([cfg.null_condition], dtype=torch.float32)
    return torch.zeros(1, cfg.caller_cond_dim)


def condition_or_null(model: Armflow, condition: np.ndarray | None) -> torch.Tensor:
    """[1, caller_cond_dim]: the caller's condition, or the model's null condition."""
    if condition is None:
        return null_condition(model)
    if condition.shape[-1] != model.cfg.caller_cond_dim:
        raise ValueError(f"a condition of {condition.shape[-1]} floats: the model takes {model.cfg.caller_cond_dim}")
    return torch.from_numpy(condition)[None]


@torch.no_grad()
def stream_reference(
    model: Armflow, actor: np.ndarray, xi: np.ndarray, eps: np.ndarray, opt: StreamOptions,
    windows: VaeWindows | None = None,
):
    """Run the streaming ARMFlow loop over a whole actor clip with injected noise.

    With `condition_feedback` the modulation is recomputed before every token j from the
    caller's condition followed by the feedback (`feedback.py`): zeros for token 0, else
    `feedback.of_features` of the reactor's frame j * fpt - 1 as the decoder produced it for
    token j - 1 and the actor's input frame j * fpt - 1 (needs a decoder without lookahead).

    Returns a dict of float32 arrays: actor_latents, reactor_latents, contexts [N, *] and
    frames (reactor frames of every token whose decoder lookahead exists); with feedback also
    feedback [N, 5], what each token's condition was given after the caller's."""
    cfg, core = model.cfg, model.armflow
    fpt = cfg.frames_per_token
    w = windows or VaeWindows.of(model)
    capacity = opt.capacity or cfg.context_capacity
    n_tokens = (actor.shape[0] - w.lookahead_frames) // fpt
    condition = condition_or_null(model, opt.condition)
    fed = cfg.condition_feedback is not None
    if fed and w.lookahead_tokens:
        raise ValueError("condition feedback needs a decoder without lookahead: token j - 1 decoded before token j")
    modulation = None if fed else core.arnet.modulation(condition)
    fed_hist = []
    h, dh = cfg.heads, cfg.head_dim
    past = [(torch.zeros(1, h, 0, dh), torch.zeros(1, h, 0, dh)) for _ in range(cfg.layers)]
    grid = meanflow_grid(opt.steps)
    motion = torch.from_numpy(actor)[None]
    a_hist, b_hist, c_hist, frames = [], [], [], []
    for j in range(n_tokens):
        # 1. actor token from the encoder window around this token's frames
        start = max(0, j * fpt - w.context_frames)
        mean, logvar = model.vae.encoder(motion[:, start : (j + 1) * fpt + w.lookahead_frames])
        row = (j * fpt - start) // fpt
        mean, logvar = mean[0, row], logvar[0, row]
        a = (mean + torch.sqrt(torch.exp(logvar)) * torch.from_numpy(xi[j])) * cfg.latent_scale
        # 2. context: append <sos> (first token) or the previous (actor || reactor) pair
        token = core.start_token if j == 0 else torch.cat([a_hist[-1], b_hist[-1]])[None, None]
        held = past[0][0].shape[2]
        if held + 1 > capacity:  # slide: keep <sos> and the newest capacity - 2 pairs
            drop_to = held - (capacity - 2)
            past = [tuple(torch.cat([x[:, :, :1], x[:, :, drop_to:]], 2) for x in kv) for kv in past]
        if fed:  # the reactor's placement at the last frame of token j - 1, decoded in step 4
            last = j * fpt - 1
            fb = torch.zeros(feedback.DIMS) if j == 0 else feedback.of_features(frames[-1][-1], motion[0, last])
            fed_hist.append(fb)
            modulation = core.arnet.modulation(torch.cat([condition, fb[None]], dim=-1))
        c, new = core.arnet.step(token, torch.tensor([[j]]), modulation, past)
        past = [tuple(torch.cat([old, n], 2) for old, n in zip(kv, new_kv)) for kv, new_kv in zip(past, new)]
        # 3. MeanFlow: z <- z - (tau_k - tau_{k+1}) u(z, r=tau_{k+1}, t=tau_k)
        z = torch.from_numpy(eps[j])[None]
        for k in range(opt.steps):
            t_hi, t_lo = grid[k], grid[k + 1]
            r_t = torch.tensor([t_lo]), torch.tensor([t_hi])
            u = core.velocity(a[None], z, c, *r_t)
            if opt.cfg_scale != 1.0:
                u_null = core.velocity(torch.zeros_like(a[None]), z, torch.zeros_like(c), *r_t)
                u = u_null + opt.cfg_scale * (u - u_null)
            z = z - np.float32(t_hi - t_lo) * u
        a_hist.append(a)
        b_hist.append(z[0])
        c_hist.append(c[0])
        # 4. decode token k = j - lookahead once its lookahead tokens exist
        k = j - w.lookahead_tokens
        if k >= 0:
            first = max(0, k - w.context_tokens)
            window = torch.stack(b_hist[first:])[None] / torch.tensor(cfg.latent_scale, dtype=torch.float32)
            frames.append(model.vae.decoder(window)[0, (k - first) * fpt : (k - first + 1) * fpt])
    as_np = lambda xs: torch.stack(xs).numpy().astype(np.float32)  # noqa: E731
    out = {
        "actor_latents": as_np(a_hist),
        "reactor_latents": as_np(b_hist),
        "contexts": as_np(c_hist),
        "frames": torch.cat(frames).numpy().astype(np.float32),
    }
    if fed:
        out["feedback"] = as_np(fed_hist)
    return out


# --------------------------------------------------------------------------------------------
# The official clip loop (`docs/spec/armflow.md` §7), on the same modules
# --------------------------------------------------------------------------------------------


def clip_tokens(cfg: ArmflowConfig) -> int:
    """Tokens of a padded clip: the two stride-2 convolutions (k4, p1) floor odd lengths, so
    150 frames give 75 then 37 tokens (InterX), 300 give 75 (InterHuman)."""
    n = cfg.clip_frames
    for _ in range(2):
        n = (n + 2 - 4) // 2 + 1
    return n


@torch.no_grad()
def clip_reference(model: Armflow, actor: np.ndarray, xi: np.ndarray, eps: np.ndarray,
                   condition: np.ndarray | None, steps: int = 1, causal_context: bool = False,
                   cfg_scale: float | None = None):
    """The official sampling loop: the actor clip zero-padded to the clip length and encoded
    once with the posterior sample `xi` [N, latent]; for every token the whole prefix
    [sos, (a_j || b_j) for j < i] re-run through the context encoder with no attention mask;
    the same noise token `eps` [latent] (the official E[N-1]) for every token; one decode of
    all reactor tokens, padded to the clip length by repeating the last frame (InterX).

    `causal_context` swaps the unmasked prefix for the causal mask that stream mode's key/value
    cache implies (a measurement aid, not the official loop).

    `cfg_scale` (default: the model's, `mf.cfg_scale` of a checkpoint) other than 1 guides as
    the official sampler does: a null row with the actor token and the context zeroed,
    `u = u_null + cfg_scale * (u_cond - u_null)`.

    Returns actor_latents, reactor_latents, contexts [N, *] and frames [clip_frames, D]."""
    cfg, core = model.cfg, model.armflow
    if cfg.condition_feedback is not None:
        raise ValueError(f"the clip loop does not support condition feedback ({cfg.condition_feedback}): "
                         "a model with it runs the stream loop only")
    frames_in, d = actor.shape
    assert frames_in <= cfg.clip_frames
    padded = np.zeros((cfg.clip_frames, d), np.float32)
    padded[:frames_in] = actor
    mean, logvar = model.vae.encoder(torch.from_numpy(padded)[None])
    a = (mean + logvar.exp().pow(0.5) * torch.from_numpy(xi)[None]) * cfg.latent_scale  # [1, N, lat]
    modulation = core.arnet.modulation(condition_or_null(model, condition))
    grid = meanflow_grid(steps)
    scale = cfg.cfg_scale if cfg_scale is None else cfg_scale
    e = torch.from_numpy(eps)[None]
    b_hist, c_hist = [], []
    for i in range(a.shape[1]):
        seq = core.start_token
        if i > 0:
            pairs = torch.cat([a[:, :i], torch.stack(b_hist)[None]], dim=-1)
            seq = torch.cat([core.start_token, pairs], dim=1)
        if causal_context:
            h = core.arnet.in_layers[0].attn
            empty = torch.zeros(1, h.heads, 0, h.head_dim)
            c, _ = core.arnet.step(seq, torch.arange(i + 1)[None], modulation, [(empty, empty)] * cfg.layers)
        else:
            c = core.arnet.full(seq, modulation)
        z = e
        for k in range(steps):
            t_hi, t_lo = grid[k], grid[k + 1]
            r_t = torch.tensor([t_lo]), torch.tensor([t_hi])
            u = core.velocity(a[:, i], z, c, *r_t)
            if scale != 1.0:
                u_null = core.velocity(torch.zeros_like(a[:, i]), z, torch.zeros_like(c), *r_t)
                u = u_null + scale * (u - u_null)
            z = z - np.float32(t_hi - t_lo) * u
        b_hist.append(z[0])
        c_hist.append(c[0])
    b = torch.stack(b_hist)[None]
    out = model.vae.decoder(b / torch.tensor(cfg.latent_scale, dtype=torch.float32))[0]
    if out.shape[0] < cfg.clip_frames:  # InterX: 37 tokens decode to 148 of 150 frames
        out = torch.cat([out, out[-1:].repeat(cfg.clip_frames - out.shape[0], 1)])
    return {
        "actor_latents": a[0].numpy().astype(np.float32),
        "reactor_latents": b[0].numpy().astype(np.float32),
        "contexts": torch.stack(c_hist).numpy().astype(np.float32),
        "frames": out.numpy().astype(np.float32),
    }
