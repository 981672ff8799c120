"""The x0-guidance gradients through the VQ decoder: by autograd (the ground truth), and written
out by hand so that they export as plain ONNX (`docs/spec/magnet.md` §6.4, §6.5 option (a)): the decoder's forward keeps what its
backward needs, then the loss's gradient runs back through transposed convolutions, the
LayerNorm and GELU derivatives, ReLU masks and the upsampling's pair sums. Only the gradient
with respect to the latents leaves the graph; the transform dims' analytic term is the runtime's
(`guidance.transform_smoothing_gradient`).

`onnx/tests/test_magnet_torch.py` checks the two against each other.
"""

from __future__ import annotations

import math

import torch
import torch.nn as nn
import torch.nn.functional as F

import numpy as np

from troupe_onnx.magnet.layout import BETAS, BODY_JOINTS, FOOT_JOINTS, FRAMES_PER_TOKEN, TRANSFORM
from troupe_onnx.magnet.networks import Decoder, ResConv1DBlock

def decoded_rotations(decoder, x0: torch.Tensor, betas: torch.Tensor, latent: int) -> torch.Tensor:
    """R = Dec(x0's latents, [betas, x0's tm1_t])[..., :126] per person's window, unsnapped:
    x0 [S, T, P, D], betas [S, P, 10] -> [S, 4T, P, 126]."""
    s, t, p, _ = x0.shape
    z = x0[..., :latent]
    tm1_t = x0[..., latent : latent + FRAMES_PER_TOKEN * TRANSFORM]
    cond = torch.cat([betas[:, None].expand(s, t, p, BETAS), tm1_t], dim=-1)
    fold = lambda a: a.permute(0, 2, 1, 3).reshape(s * p, t, -1)  # noqa: E731 - persons into the batch
    out = decoder(torch.cat([fold(z), fold(cond)], dim=-1).transpose(1, 2))  # [S*P, 4T, 135]
    return out.reshape(s, p, FRAMES_PER_TOKEN * t, -1).permute(0, 2, 1, 3)[..., : BODY_JOINTS * 6]


def smoothing_loss(r: torch.Tensor) -> torch.Tensor:
    return ((r[:, :-2] - 2 * r[:, 1:-1] + r[:, 2:]) ** 2).mean()


def foot_skating_loss(r: torch.Tensor) -> torch.Tensor:
    s, f, p, _ = r.shape
    feet = r.reshape(s, f, p, BODY_JOINTS, 6)[:, :, :, list(FOOT_JOINTS)]
    return ((feet[:, 1:] - feet[:, :-1]) ** 2).mean()


def weighted_gradient(decoder, latent: int):
    """The reference's decoder_grad for `guidance.Guidance`: autograd of
    w_s * smoothing + w_f * foot skating, on the latents."""

    def grad(x0, betas, ws, wf):
        loss = lambda r: float(ws) * smoothing_loss(r) + float(wf) * foot_skating_loss(r)  # noqa: E731
        return pose_gradient(decoder, loss, x0, betas, latent)

    return grad


def pose_gradient(decoder, loss, x0: np.ndarray, betas: np.ndarray, latent: int) -> np.ndarray:
    """d loss(R(x0)) / d x0 on the latent dims only (the rest zero), by autograd (§6.4)."""
    xt = torch.from_numpy(np.ascontiguousarray(x0, dtype=np.float32)).requires_grad_(True)
    value = loss(decoded_rotations(decoder, xt, torch.from_numpy(betas.astype(np.float32)), latent))
    (grad,) = torch.autograd.grad(value, xt)
    out = np.zeros_like(x0, dtype=np.float32)
    out[..., :latent] = grad[..., :latent].numpy()
    return out


_INV_SQRT2 = 1.0 / math.sqrt(2.0)
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


def _gelu_grad(x):
    return 0.5 * (1.0 + torch.erf(x * _INV_SQRT2)) + x * torch.exp(-0.5 * x * x) * _INV_SQRT_2PI


class DecoderVjp(nn.Module):
    """The bundle's `guidance` graph, per person-sequence and channels-last: x0 `[N, T, D]` (one
    person of one sample a row), betas `[N, 10]`, weights `[2]` -> the gradient on the latents
    `[N, T, latent]`, the losses' means taken over the N sequences given (a runtime that leaves
    out sequences whose gradient it will not use scales the weights by the share it passes).
    Activations are `[N, frames, channels]`; every convolution is one matrix product over the
    rows of all sequences and frames (`[rows, k·C_in] @ [k·C_in, C_out]`, taps gathered by
    static slices of the zero-padded input), every transposed convolution the same with the taps
    reversed and the channel axes swapped, every norm and its backward over the last axis. The
    weights are laid out for both products when the module is built (plain initializers in the
    graph, nothing for the runtime to fold at load). No convolution op and no broadcast over a
    strided axis is left: an earlier channels-first form spent a third of its time outside the
    matrix products in tract."""

    def __init__(self, decoder: Decoder, latent: int):
        super().__init__()
        self.latent = latent
        m = decoder.model
        rows = lambda conv, **cut: _RowConv(conv, **cut)  # noqa: E731
        self.first, self.head = rows(m[0], inputs=latent), rows(m[4])
        self.out = rows(m[6], outputs=BODY_JOINTS * 6)  # d/d(out) is zero on the root dims
        self.stages = nn.ModuleList(
            nn.ModuleList([nn.ModuleList([_RowBlock(b) for b in stage[0].model]), rows(stage[2])])
            for stage in (m[2], m[3])
        )

    def forward(self, x0, betas, weights):
        n, t, _ = x0.shape
        lat = self.latent
        tm1_t = x0[..., lat : lat + FRAMES_PER_TOKEN * TRANSFORM]  # the person's own transforms
        h = torch.cat([x0[..., :lat], betas[:, None].expand(n, t, BETAS), tm1_t], dim=-1)  # [N, T, C]
        tape = []
        a = self.first(h)
        tape.append(a)
        h = F.relu(a)
        for blocks, conv in self.stages:
            for block in blocks:
                h = block(h, tape)
            n, frames, c = h.shape
            h = conv(h[:, :, None].expand(n, frames, 2, c).reshape(n, 2 * frames, c))  # nearest x2
        a4 = self.head(h)
        r = self.out(F.relu(a4))  # [N, F, 126]: the rotations (the root rows are not computed)
        g = weights[0] * _smoothing_grad(r) + weights[1] * _foot_skating_grad(r)
        g = self.out.input_grad(g) * (a4 > 0).to(g.dtype)
        g = self.head.input_grad(g)
        for blocks, conv in reversed(self.stages):
            g = conv.input_grad(g)
            n, frames, c = g.shape
            pairs = g.reshape(n, frames // 2, 2 * c)  # nearest x2's backward: frames 2i and 2i+1
            g = pairs[..., :c] + pairs[..., c:]
            for block in reversed(blocks):
                g = block.backward(g, tape)
        g = g * (tape.pop() > 0).to(g.dtype)
        return self.first.input_grad(g)  # [N, T, latent]


class _RowConv(nn.Module):
    """A stride-1 `Conv1d` on channels-last `[N, T, C]` as one matrix product each way: its
    output (the first `outputs` channels) and the input gradient on the first `inputs` input
    channels (the convolution with the taps reversed, the channel axes swapped and the padding
    mirrored). The weights are copied into both layouts once, here."""

    def __init__(self, conv: nn.Conv1d, inputs: int | None = None, outputs: int | None = None):
        super().__init__()
        assert conv.stride[0] == 1
        self.k, self.d, self.p = conv.kernel_size[0], conv.dilation[0], conv.padding[0]
        w = conv.weight.detach()[:outputs]  # [C_out, C_in, k]
        self.register_buffer("weight", w.permute(2, 1, 0).reshape(-1, w.shape[0]).contiguous())  # [k·C_in, C_out]
        self.register_buffer("bias", conv.bias.detach()[:outputs].clone())
        w = w[:, :inputs].flip(2)
        self.register_buffer("grad_weight", w.permute(2, 0, 1).reshape(-1, w.shape[1]).contiguous())  # [k·C_out, C_in]

    def forward(self, h):
        return _taps(h, self.k, self.d, self.p, self.p) @ self.weight + self.bias

    def input_grad(self, g):
        edge = (self.k - 1) * self.d - self.p
        return _taps(g, self.k, self.d, edge, edge) @ self.grad_weight


class _RowBlock(nn.Module):
    """A `ResConv1DBlock` channels-last: the forward keeps what the backward needs on the tape."""

    def __init__(self, block: ResConv1DBlock):
        super().__init__()
        self.norm1, self.norm2 = block.norm1, block.norm2
        self.conv1, self.conv2 = _RowConv(block.conv1), _RowConv(block.conv2)

    def forward(self, x, tape):
        u, xhat1, inv1 = _ln_forward(self.norm1, x)
        c1 = self.conv1(F.gelu(u))
        w, xhat2, inv2 = _ln_forward(self.norm2, c1)
        tape.append((u, xhat1, inv1, w, xhat2, inv2))
        return x + self.conv2(F.gelu(w))

    def backward(self, g, tape):
        u, xhat1, inv1, w, xhat2, inv2 = tape.pop()
        gw = self.conv2.input_grad(g) * _gelu_grad(w)
        gu = self.conv1.input_grad(_ln_backward(self.norm2, gw, xhat2, inv2)) * _gelu_grad(u)
        return g + _ln_backward(self.norm1, gu, xhat1, inv1)


def _taps(h, kernel: int, dilation: int, left: int, right: int):
    """`[N, T, C]` -> `[N, T_out, kernel·C]`: the input zero-padded along frames, then the
    `kernel` views `dilation` frames apart side by side (tap-major)."""
    if kernel == 1 and left == right == 0:
        return h
    padded = F.pad(h, (0, 0, left, right))
    frames = padded.shape[1] - (kernel - 1) * dilation
    return torch.cat([padded[:, i * dilation : i * dilation + frames] for i in range(kernel)], dim=2)


def _ln_forward(norm: nn.LayerNorm, x):
    """LayerNorm over the last axis of `[N, T, C]`; returns (output, x_hat, 1/sigma)."""
    mean = x.mean(dim=-1, keepdim=True)
    centred = x - mean
    inv = torch.rsqrt((centred * centred).mean(dim=-1, keepdim=True) + norm.eps)
    xhat = centred * inv
    return xhat * norm.weight + norm.bias, xhat, inv


def _ln_backward(norm: nn.LayerNorm, g, xhat, inv):
    """The input gradient of `_ln_forward`'s output `g`."""
    gh = g * norm.weight
    return inv * (gh - gh.mean(dim=-1, keepdim=True) - xhat * (gh * xhat).mean(dim=-1, keepdim=True))


def _smoothing_grad(r):
    """d mean(Lap^2) / dR for R `[N, F, 126]` (frames second); the mean is over the whole batch,
    so its count comes from the tensors' shapes (the batch is dynamic)."""
    lap = r[:, :-2] - 2 * r[:, 1:-1] + r[:, 2:]
    c = 2.0 / torch.ones_like(lap).sum()
    return c * (F.pad(lap, (0, 0, 0, 2)) - 2 * F.pad(lap, (0, 0, 1, 1)) + F.pad(lap, (0, 0, 2, 0)))


def _foot_skating_grad(r):
    """d mean(diff^2) / dR of the foot joints' rotations `R` `[N, F, 126]`, zero on every other
    joint."""
    feet = torch.cat([r[..., 6 * j : 6 * j + 6] for j in FOOT_JOINTS], dim=-1)  # [N, F, 24]
    diff = feet[:, 1:] - feet[:, :-1]
    c = 2.0 / torch.ones_like(diff).sum()
    gf = c * (F.pad(diff, (0, 0, 1, 0)) - F.pad(diff, (0, 0, 0, 1)))
    parts, at = [], 0
    for j, joint in enumerate(FOOT_JOINTS):  # ascending joints
        parts += [torch.zeros_like(r[..., at : 6 * joint]), gf[..., 6 * j : 6 * j + 6]]
        at = 6 * joint + 6
    parts.append(torch.zeros_like(r[..., at:]))
    return torch.cat(parts, dim=-1)
