"""MAGNet's two networks in PyTorch, at any size, under the official module and parameter names
(`docs/spec/magnet.md` §1.4, §2, §8.2): the DFoT denoiser and the pose VQ-VAE.

The denoiser is the forward *as trained* (no attention mask, §2.3): the latest official code
builds a causal mask of the batch's size, a regression that crashes or masks what training
never masked; it is not reproduced. Everything else follows §2.2 operation for operation.

Written from the specification; nothing is copied from the official repository.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch
import torch.nn as nn
import torch.nn.functional as F

from troupe_onnx.magnet.layout import DECODER_COND_DIM, ENCODER_COND_DIM, POSE_DIM, TOKEN_TRANSFORMS



@dataclass(frozen=True)
class VqConfig:
    """The pose VQ-VAE (`configs/train/vqvae/dd100.yaml`; §1.4)."""

    d_latent: int = 512
    d_hidden: int = 512
    code_nb: int = 1024
    depth: int = 3  # residual blocks per Resnet1D, dilations 3^(depth-1) .. 1
    r_max: float = 45.0  # codebook rows have L2 norm <= r_max

    def to_json(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True)
class MagnetConfig:
    """One checkpoint's architecture (§2.2, §8.2); the defaults are the released DD100 sizes."""

    persons: int = 2  # P, fixed by the checkpoint (`person_num`)
    window: int = 16  # Tm tokens (`sequence_length` 64 frames / 4)
    layers: int = 6
    heads: int = 8
    d_feedforward: int = 2048
    embed_dim: int = 256  # the noise-level embedding's width (and the person table's, concat mode)
    person_embedding_mode: str = "concat"  # or "add"
    max_t: int = 1000
    vq: VqConfig = field(default_factory=VqConfig)

    @property
    def d_model(self) -> int:
        return self.vq.d_latent  # the transformer runs at the latent width (§2.2: d = d_latent)

    @property
    def token_dim(self) -> int:
        """D = latent + 36 (own tm1_t) + 36 per partner (§1.5)."""
        return self.vq.d_latent + TOKEN_TRANSFORMS * self.persons

    def to_json(self) -> dict:
        out = {k: v for k, v in self.__dict__.items() if k != "vq"}
        return out | {"vq": self.vq.to_json(), "token_dim": self.token_dim}


# --------------------------------------------------------------------------------------------
# Denoiser (`diffusion_transformer.py:TransformerModel`, §2.2)
# --------------------------------------------------------------------------------------------


def level_embedding(levels: torch.Tensor, dim: int) -> torch.Tensor:
    """e(k) = [sin(k f_i), cos(k f_i)], f_i = exp(-i ln(10000)/(dim/2 - 1)), i < dim/2 (§2.2 step
    1). Levels are cast to float; -1 (clean) is used as it is."""
    half = dim // 2
    c = math.log(10000.0) / (half - 1)
    freqs = torch.exp(torch.arange(half, dtype=torch.float32) * -c)
    angles = levels.to(torch.float32)[..., None] * freqs
    return torch.cat([torch.sin(angles), torch.cos(angles)], dim=-1)


def rope_add(h: torch.Tensor) -> torch.Tensor:
    """rot(h) over the window-relative time axis (dim 1 of [B, T, P, d]); halves concatenated,
    not re-interleaved (§2.2 step 4)."""
    t, d = h.shape[1], h.shape[-1]
    omega = 1.0 / torch.pow(torch.tensor(10000.0), torch.arange(0, d, 2, dtype=torch.float32) / d)
    theta = torch.arange(t, dtype=torch.float32)[:, None] * omega  # [T, d/2]
    cos, sin = torch.cos(theta)[None, :, None, :], torch.sin(theta)[None, :, None, :]
    a, b = h[..., 0::2], h[..., 1::2]
    return torch.cat([a * cos - b * sin, a * sin + b * cos], dim=-1)


class PersonEmbedding(nn.Module):
    def __init__(self, persons: int, width: int):
        super().__init__()
        self.person_emb = nn.Embedding(persons, width)


class TransformerModel(nn.Module):
    """x [B, T, P, D] and levels k [B, T, P] (int, -1 = clean) -> x0 [B, T, P, D]."""

    def __init__(self, cfg: MagnetConfig):
        super().__init__()
        self.cfg = cfg
        d, concat = cfg.d_model, cfg.person_embedding_mode == "concat"
        if cfg.person_embedding_mode not in ("concat", "add"):
            raise ValueError(f"person_embedding_mode {cfg.person_embedding_mode!r}: concat or add")
        width_in = cfg.token_dim + cfg.embed_dim + (cfg.embed_dim if concat else 0)
        self.init_mlp = nn.Sequential(
            nn.Linear(width_in, d), nn.GELU(), nn.Linear(d, d), nn.GELU(), nn.Linear(d, d)
        )
        self.p_embed = PersonEmbedding(cfg.persons, cfg.embed_dim if concat else d)
        layer = nn.TransformerEncoderLayer(
            d, cfg.heads, cfg.d_feedforward, dropout=0.0, activation="relu", batch_first=True, norm_first=False
        )
        self.transformer = nn.TransformerEncoder(layer, cfg.layers, enable_nested_tensor=False)
        self.out = nn.Linear(d, cfg.token_dim)

    def forward(self, x: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
        b, t, p, _ = x.shape
        person = self.p_embed.person_emb.weight  # [P, width]
        first, rest = self.init_mlp[0], self.init_mlp[1:]
        h = torch.cat([x, level_embedding(k, self.cfg.embed_dim)], dim=-1)
        if self.cfg.person_embedding_mode == "concat":
            # Linear([x, e(k), E_p]) with the person's columns applied to E alone: the same sum
            # (to float rounding) without concatenating a broadcast table, which tract 0.23.9
            # mis-shapes when it splits the product.
            width = h.shape[-1]
            h = F.linear(h, first.weight[:, :width], first.bias) + F.linear(person, first.weight[:, width:])
        else:
            h = first(h)
        h = rest(h)
        h = h + rope_add(h)
        if self.cfg.person_embedding_mode == "add":
            h = h + person
        h = self.transformer(h.reshape(b, t * p, -1))  # no mask: bidirectional, as trained (§2.3)
        return self.out(h).reshape(b, t, p, -1)


# --------------------------------------------------------------------------------------------
# Pose VQ-VAE (`libs/model/vqvae/*`, §1.4)
# --------------------------------------------------------------------------------------------


class ChannelNorm(nn.LayerNorm):
    """LayerNorm over the channel axis of [N, C, T] (eps 1e-5)."""

    def forward(self, x):
        return super().forward(x.transpose(1, 2)).transpose(1, 2)


class ResConv1DBlock(nn.Module):
    """x + conv2(GELU(norm2(conv1(GELU(norm1(x)))))); conv1 k3 dilated, conv2 k1."""

    def __init__(self, width: int, dilation: int):
        super().__init__()
        self.norm1 = ChannelNorm(width)
        self.conv1 = nn.Conv1d(width, width, 3, padding=dilation, dilation=dilation)
        self.norm2 = ChannelNorm(width)
        self.conv2 = nn.Conv1d(width, width, 1)

    def forward(self, x):
        h = self.conv1(F.gelu(self.norm1(x)))
        return x + self.conv2(F.gelu(self.norm2(h)))


class Resnet1D(nn.Module):
    def __init__(self, width: int, depth: int):
        super().__init__()
        self.model = nn.Sequential(*[ResConv1DBlock(width, 3**i) for i in reversed(range(depth))])

    def forward(self, x):
        return self.model(x)


class Upsample(nn.Module):
    def forward(self, x):
        return F.interpolate(x, scale_factor=2.0, mode="nearest")


class Encoder(nn.Module):
    """[N, C_in, T] -> [N, T/4, d_latent]: conv, ReLU, 2 x (stride-2 conv, Resnet1D), conv,
    LayerNorm over channels."""

    def __init__(self, vq: VqConfig, width_in: int):
        super().__init__()
        w = vq.d_hidden
        self.model = nn.Sequential(
            nn.Conv1d(width_in, w, 3, padding=1),
            nn.ReLU(),
            *[nn.Sequential(nn.Conv1d(w, w, 4, stride=2, padding=1), Resnet1D(w, vq.depth)) for _ in range(2)],
            nn.Conv1d(w, vq.d_latent, 3, padding=1),
        )
        self.last_ln = nn.LayerNorm(vq.d_latent)

    def forward(self, x):
        return self.last_ln(self.model(x).transpose(1, 2))


class Decoder(nn.Module):
    """[N, C_in, Tz] -> [N, 4 Tz, 135]: conv, ReLU, 2 x (Resnet1D, upsample, conv), conv, ReLU,
    conv."""

    def __init__(self, vq: VqConfig, width_in: int):
        super().__init__()
        w = vq.d_hidden
        self.model = nn.Sequential(
            nn.Conv1d(width_in, w, 3, padding=1),
            nn.ReLU(),
            *[nn.Sequential(Resnet1D(w, vq.depth), Upsample(), nn.Conv1d(w, w, 3, padding=1)) for _ in range(2)],
            nn.Conv1d(w, w, 3, padding=1),
            nn.ReLU(),
            nn.Conv1d(w, POSE_DIM, 3, padding=1),
        )

    def forward(self, x):
        return self.model(x).transpose(1, 2)


class Quantizer(nn.Module):
    """QuantizeEMAReset's inference side: the codebook (the EMA buffers ride along, unused)."""

    def __init__(self, vq: VqConfig):
        super().__init__()
        self.register_buffer("codebook", torch.zeros(vq.code_nb, vq.d_latent))
        self.register_buffer("code_sum", torch.zeros(vq.code_nb, vq.d_latent))
        self.register_buffer("code_count", torch.zeros(vq.code_nb))

    def quantize(self, z: torch.Tensor) -> torch.Tensor:
        """Nearest code by ||z||^2 - 2 z.c + ||c||^2 in float32; ties to the first (argmin)."""
        flat = z.reshape(-1, z.shape[-1])
        dist = (flat**2).sum(-1, keepdim=True) - 2 * flat @ self.codebook.T + (self.codebook**2).sum(-1)[None]
        return dist.argmin(dim=-1).reshape(z.shape[:-1])

    def snap(self, z: torch.Tensor) -> torch.Tensor:
        return self.codebook[self.quantize(z)]


class PoseVQVAE(nn.Module):
    def __init__(self, vq: VqConfig):
        super().__init__()
        self.encoder = Encoder(vq, POSE_DIM + ENCODER_COND_DIM)
        self.decoder = Decoder(vq, vq.d_latent + DECODER_COND_DIM)
        self.quantizer = Quantizer(vq)

    def encode_continuous(self, val: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """val [N, T, 135], cond [N, T, 19] (normalised) -> z_e [N, T/4, d_latent], not snapped."""
        return self.encoder(torch.cat([val, cond], dim=-1).transpose(1, 2))

    def decode(self, z: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """z [N, Tz, d_latent] (not snapped here), cond [N, Tz, 46] -> [N, 4 Tz, 135]."""
        return self.decoder(torch.cat([z, cond], dim=-1).transpose(1, 2))


class VqHolder(nn.Module):
    """The DFoT checkpoint's copy of the VQ-VAE (`_vqvae.vqvae.*`, `_vqvae.z_mask`)."""

    def __init__(self, vq: VqConfig):
        super().__init__()
        self.vqvae = PoseVQVAE(vq)
        self.register_buffer("z_mask", torch.zeros(1, 1, vq.d_latent))  # unused at inference


class Diffuser(nn.Module):
    def __init__(self, cfg: MagnetConfig):
        super().__init__()
        self.model = TransformerModel(cfg)


class Magnet(nn.Module):
    """The DFoT checkpoint's module tree: `diffuser.model.*` and `_vqvae.*` (§8.2)."""

    def __init__(self, cfg: MagnetConfig):
        super().__init__()
        self.cfg = cfg
        self.diffuser = Diffuser(cfg)
        self._vqvae = VqHolder(cfg.vq)

    @property
    def denoiser(self) -> TransformerModel:
        return self.diffuser.model

    @property
    def vqvae(self) -> PoseVQVAE:
        return self._vqvae.vqvae


def init_random(model: Magnet, seed: int) -> Magnet:
    """Seeded random weights with a codebook inside the r_max band, as training keeps it."""
    torch.manual_seed(seed)
    for m in model.modules():
        if isinstance(m, (nn.Linear, nn.Conv1d)):
            m.reset_parameters()
        elif isinstance(m, nn.MultiheadAttention):
            m._reset_parameters()  # its packed in_proj is no Linear
        elif isinstance(m, nn.LayerNorm):
            nn.init.normal_(m.weight, 1.0, 0.1)
            nn.init.normal_(m.bias, 0.0, 0.1)
        elif isinstance(m, nn.Embedding):
            nn.init.normal_(m.weight)
    q = model.vqvae.quantizer
    codes = torch.randn_like(q.codebook)
    norms = codes.norm(dim=-1, keepdim=True)
    q.codebook.copy_(codes / norms * torch.rand_like(norms) * model.cfg.vq.r_max * 0.2)
    q.code_sum.copy_(q.codebook)
    q.code_count.fill_(1.0)
    return model
