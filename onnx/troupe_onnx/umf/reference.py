"""PyTorch reference of UMF's networks and of troupe's group sampler (text to a group of people).

This module is the ground truth the Rust runtime (`src/umf/group.rs`, `src/umf/pyramid.rs`,
`src/shared/solver.rs`) is tested against. The networks follow `docs/spec/umf.md` (read
from the official code, `Githubhgh/UMF_CVPR`) at any width and depth; the sampler runs the
official numerics operation for operation in float32, so that given the same noise troupe and
this reference agree to float32 rounding:

* P-Flow (first person): a pyramid of stages from few tokens to all of them, each solved in its
  own local time with the stage's timestep table, joined by "jumps" (nearest upsampling plus
  block-correlated noise).
* S-Flow (every further person): the state `[noise ; context]` flows to `[context ; reaction]`;
  the context pools everyone generated before.
* One decode of every person's latent by the MLD-style VAE decoder, then denormalisation.

Modules and parameters carry the official names (`indi_denoiser.expert_ih_blocks.0.linear1`,
`reac_denoiser.encoder.input_blocks.0.self_attn`, `clipTransEncoder_react.layers.1`,
`vae.decoder.middle_block.multihead_attn`, ...; read from `umf/models/modeltype/umf.py`,
`architectures/umf_denoiser.py`, `umf_vae.py` and `operator/cross_attention.py`), so an official
checkpoint loads as it is (`cli.py umf export --checkpoint`).

Nothing here is copied from the official repository; it is written from the specification and
the names read there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from troupe_onnx.shared.clip import CONTEXT, FULL_MERGES, ClipTransformer, clip_features, empty_prompt, vocab_size
from troupe_onnx.shared.noise import philox_normals
from troupe_onnx.shared.transformer import Attention, EncoderLayer, EncoderStack, pick_token

# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------

TRAIN_TIMESTEPS = 1000  # FlowModel's N: the tables the stage timesteps come from
TIME_SCALE = 1000.0  # the denoiser sees the table value divided by this
BLOCK = {"grid2d": 4, "temporal": 2}  # tokens one coarse token becomes at a jump

# troupe's seeded draws (src/umf/group.rs): stream ids of Philox normals, keyed by token index.
STREAM_PRIOR_NOISE = 2  # token 0: the first person's starting noise at the coarsest stage
STREAM_JUMP_NOISE = 3  # token k: the standard normals behind the jump into stage k
STREAM_REACTION_NOISE = 4  # token p: person p's (0-based, p >= 1) semi-noise start


@dataclass(frozen=True)
class Solver:
    """A fixed-grid ODE rule over tau in [0, 1]: "euler" or "rk4" (torchdiffeq's 3/8 rule)."""

    method: str
    steps: int

    def to_json(self) -> dict:
        return {"method": self.method, "steps": self.steps}


@dataclass
class UmfConfig:
    """Hyper-parameters; the defaults are the official sizes (`docs/spec/umf.md` §1, §5, §6)."""

    frame_dim: int = 262
    fps: int = 30
    tokens: int = 16  # latent tokens per person at full resolution
    latent_dim: int = 64  # floats per latent token
    # Denoisers (P-Flow and S-Flow share the design; `docs/spec/umf.md` §5)
    width: int = 512
    heads: int = 4
    ffn: int = 1024
    time_dim: int = 768  # sinusoidal timestep features
    prior_layers: int = 9  # P-Flow backbone skip-transformer layers (odd); official num_layers 13 = 9 + 2 x 2
    prior_expert_layers: int = 2  # layers of each P-Flow expert head (official dh_depth)
    reaction_layers: int = 13  # S-Flow skip-transformer layers (odd)
    prior_text_dim: int = 768
    reaction_text_dim: int = 768
    pe_length: int = 500  # learned positions of the denoisers
    dataset_label: int = 1  # P-Flow's dataset: 1 = InterHuman ("ih" expert), 0 = HumanML3D ("t2m")
    # Text: CLIP ViT-L/14@336px's text tower (the bundle's `text_encoder` graph; its tokenizer
    # has `clip_merges` byte-pair merges) and the official 2-layer encoders after it
    clip_layers: int = 12
    clip_heads: int = 12
    clip_merges: int = FULL_MERGES
    text_layers: int = 2
    text_heads: int = 8
    text_ffn: int = 2048
    # Context adapter (runs at latent_dim)
    context_layers: int = 2
    context_heads: int = 4
    context_ffn: int = 1024
    # VAE (encoder and decoder share these sizes)
    vae_width: int = 512
    vae_layers: int = 9
    vae_heads: int = 4
    vae_ffn: int = 1024
    vae_pe_length: int = 500
    clip_frames: int = 300
    # P-Flow pyramid and the default sampler (the official code)
    layout: str = "grid2d"
    stages: int = 2
    gamma: float = -0.2
    prior_solvers: list[Solver] = field(default_factory=lambda: [Solver("rk4", 4)] * 2)
    reaction_solver: Solver = Solver("rk4", 4)
    cfg_scale: float = 3.0

    @property
    def clip_vocab(self) -> int:
        """CLIP's tokens: bytes, bytes ending a word, merges, <|startoftext|>, <|endoftext|>."""
        return vocab_size(self.clip_merges)

    @property
    def text_dim(self) -> int:
        """CLIP's width: the features both text encoders read and give."""
        return self.prior_text_dim

    @property
    def condition_dim(self) -> int:
        """The condition vector is [prior text ; reaction text]."""
        return self.prior_text_dim + self.reaction_text_dim


# --------------------------------------------------------------------------------------------
# Pyramid: stage tables (umf/models/flow.py FlowModel), layouts, jumps and block noise
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Stage:
    """One P-Flow stage: its resolution, its window of flow time and its timestep table."""

    tokens: int
    original_start_t: float  # where the stage's window starts before the jump's correction
    start_t: float
    end_t: float
    timesteps: tuple[float, float]  # table value at local tau = 0 and tau = 1 (before / 1000)


def rectify_ratio(o: float, gamma: float) -> float:
    """The jump's scale alpha for a stage starting at o: 1 / (sqrt(1 - 1/gamma)(1 - o) + o)."""
    return 1.0 / (math.sqrt(1.0 - 1.0 / gamma) * (1.0 - o) + o)


def stage_tokens(cfg: UmfConfig) -> list[int]:
    """Tokens per stage, coarsest first: each jump multiplies them by the layout's block."""
    return [cfg.tokens // BLOCK[cfg.layout] ** (cfg.stages - 1 - s) for s in range(cfg.stages)]


def stage_tables(cfg: UmfConfig) -> list[Stage]:
    """FlowModel.initialize_stage_t with the official float32/float64 mix.

    Windows [start_t, end_t] split [0, 1] evenly (stage s starts at float32 s/K); every stage
    but the first starts earlier, at o * rectify_ratio(o). The stages' lengths then share the
    1000-entry timestep table out in proportion, and each stage's table is a float64 linspace
    over its share."""
    n, k = TRAIN_TIMESTEPS, cfg.stages
    table = torch.linspace(0, n - 1, n, dtype=torch.float32)
    t = table / n
    edges = [s / k for s in range(k + 1)]
    windows = []
    for s in range(k):
        start_idx = max(int(n * edges[s]), 0)
        end_idx = min(int(n * edges[s + 1]), n)
        original = t[start_idx].item()
        end = t[end_idx].item() if end_idx < n else 1.0
        start = original * rectify_ratio(original, cfg.gamma) if s > 0 else original
        windows.append((original, start, end))
    lengths = [end - start for _, start, end in windows]
    total = sum(lengths)
    stages = []
    for s, (tokens, (original, start, end)) in enumerate(zip(stage_tokens(cfg), windows)):
        start_ratio = 0.0 if s == 0 else sum(lengths[:s]) / total
        end_ratio = 1.0 if s == k - 1 else sum(lengths[: s + 1]) / total
        first = table[int(n * start_ratio)].item()
        last = table[min(int(n * end_ratio), n - 1)].item()
        if s == k - 1:
            steps = torch.linspace(first, last, n, dtype=torch.float64)
        else:
            steps = torch.linspace(first, last, n + 1, dtype=torch.float64)[:-1]
        stages.append(Stage(tokens, original, start, end, (steps[0].item(), steps[-1].item())))
    return stages


def _check_official_tables():
    """`docs/spec/umf.md` §3: the code's K = 2, gamma = -0.2 tables."""
    s0, s1 = stage_tables(UmfConfig())
    assert (s0.start_t, s0.end_t, s0.timesteps[0]) == (0.0, 0.5, 0.0)
    assert abs(s0.timesteps[1] - 412.587) < 1e-9
    assert abs(s1.start_t - 0.2898979486) < 1e-10 and s1.end_t == 1.0
    assert s1.timesteps == (413.0, 999.0) and s1.original_start_t == 0.5


_check_official_tables()


def stage_timestep(stage: Stage, tau: torch.Tensor) -> torch.Tensor:
    """The denoiser's time at local tau (0-dim float32) of a stage: (k tau + b) / 1000 with
    Python-float k and b, i.e. float32 arithmetic (umf.py rescale_timesteps)."""
    first, last = stage.timesteps
    return ((last - first) * tau + first) / TIME_SCALE


def fine_to_block(layout: str, fine_tokens: int) -> tuple[np.ndarray, np.ndarray]:
    """For each fine token, its block (= coarse token) and its place in the block.

    grid2d: the tokens form an h x h grid (token row * h + col); block (r, c) of the coarse
    (h/2 x h/2) grid is r * h/2 + c and holds fine (2r + p, 2c + q) at place 2p + q.
    temporal: block i holds fine tokens 2i (place 0) and 2i + 1 (place 1)."""
    i = np.arange(fine_tokens)
    if layout == "grid2d":
        h = math.isqrt(fine_tokens)
        assert h * h == fine_tokens and h % 2 == 0, f"{fine_tokens} tokens are not an even square"
        row, col = i // h, i % h
        return (row // 2) * (h // 2) + col // 2, 2 * (row % 2) + col % 2
    assert layout == "temporal" and fine_tokens % 2 == 0, f"{layout} / {fine_tokens} tokens"
    return i // 2, i % 2


def upsample(z: torch.Tensor, layout: str) -> torch.Tensor:
    """Nearest-neighbour Up: [B, n, D] -> [B, n * block, D], each coarse token into its block
    (what F.interpolate(mode="nearest") does on the 2-D grid)."""
    block, _ = fine_to_block(layout, z.shape[1] * BLOCK[layout])
    return z[:, torch.from_numpy(block)]


def jump_coefficients(o: float, gamma: float) -> tuple[float, float]:
    """alpha and beta of the jump z <- alpha Up(z) + beta n' out of a stage ending at o."""
    alpha = rectify_ratio(o, gamma)
    return alpha, alpha * (1.0 - o) / math.sqrt(-gamma)


def block_cholesky(layout: str, gamma: float) -> np.ndarray:
    """Lower Cholesky factor of Sigma = (1 - gamma) I + gamma 1 1^T + 1e-6 I, Sigma built in
    float32 as the official `sample_block_noise` builds it, factored in float64 and rounded
    once to float32 (src/umf/pyramid.rs)."""
    b, f = BLOCK[layout], np.float32
    sigma = np.full((b, b), f(gamma), np.float32)
    np.fill_diagonal(sigma, f(f(f(1.0 - gamma) + f(gamma)) + f(1e-6)))
    return np.linalg.cholesky(sigma.astype(np.float64)).astype(np.float32)


def block_noise_from_normals(e: np.ndarray, layout: str, fine_tokens: int, dim: int, gamma: float) -> np.ndarray:
    """The jump's block-correlated noise n' [fine_tokens, dim] from tokens * dim standard normals.

    Block (channel c, block k) takes e[(c * blocks + k) * b : ... + b] (the order of the
    official `sample_block_noise` loop) and becomes L e; element `place` of that vector goes to
    the block's fine token at that place. Float32, summed term by term like src/umf/pyramid.rs."""
    b = BLOCK[layout]
    blocks = fine_tokens // b
    chol = block_cholesky(layout, gamma)
    eps = np.asarray(e, dtype=np.float32).reshape(dim, blocks, b)
    vec = np.zeros((dim, blocks, b), dtype=np.float32)
    for j in range(b):
        vec += chol[None, None, :, j] * eps[:, :, j : j + 1]
    block, place = fine_to_block(layout, fine_tokens)
    return np.ascontiguousarray(vec[:, block, place].T)


def seeded_noise(cfg: UmfConfig, seed: int, people: int):
    """The noise troupe draws for a seed (src/umf/group.rs group_noise): prior [T0, D], jumps
    [[T_s, D] for s >= 1] (block noise of Philox normals), reactions [[tokens, D] per person
    after the first]."""
    d = cfg.latent_dim
    tokens = stage_tokens(cfg)
    prior = philox_normals(seed, 0, STREAM_PRIOR_NOISE, tokens[0] * d).reshape(tokens[0], d)
    jumps = [
        block_noise_from_normals(philox_normals(seed, s, STREAM_JUMP_NOISE, n * d), cfg.layout, n, d, cfg.gamma)
        for s, n in enumerate(tokens[1:], start=1)
    ]
    reactions = [
        philox_normals(seed, p, STREAM_REACTION_NOISE, cfg.tokens * d).reshape(cfg.tokens, d)
        for p in range(1, people)
    ]
    return prior, jumps, reactions


# --------------------------------------------------------------------------------------------
# Networks under the official module and parameter names (`docs/spec/umf.md` §1, §5, §6)
# --------------------------------------------------------------------------------------------

class LearnedPositions(nn.Module):
    """MLD's learned 1-D positions: x [B, S, C] + pe[:S] (pe is stored [max_len, 1, C])."""

    def __init__(self, width: int, max_len: int):
        super().__init__()
        self.pe = nn.Parameter(torch.rand(max_len, 1, width))

    def forward(self, x):
        return x + self.pe[: x.shape[1]].transpose(0, 1)


def timestep_features(t: torch.Tensor, dim: int) -> torch.Tensor:
    """diffusers get_timestep_embedding(flip_sin_to_cos=True, downscale_freq_shift=0): [cos, sin]
    of t * exp(-ln(10000) k / (dim/2)). t is used raw (no x1000)."""
    half = dim // 2
    exponent = -math.log(10000.0) * torch.arange(half, dtype=torch.float32)
    args = t[:, None].float() * torch.exp(exponent / half)[None]
    return torch.cat([torch.cos(args), torch.sin(args)], dim=-1)


class TimestepEmbedding(nn.Module):
    def __init__(self, in_dim: int, width: int):
        super().__init__()
        self.linear_1 = nn.Linear(in_dim, width)
        self.linear_2 = nn.Linear(width, width)

    def forward(self, x):
        return self.linear_2(F.silu(self.linear_1(x)))


class DecoderLayer(EncoderLayer):
    """Post-norm decoder layer: self-attention -> norm1, cross-attention to the memory (no
    positions) -> norm2, feed-forward -> norm3."""

    def __init__(self, width: int, heads: int, ffn: int):
        super().__init__(width, heads, ffn)
        self.multihead_attn = Attention(width, heads)
        self.norm3 = nn.LayerNorm(width)

    def forward(self, x, memory):
        x = self.norm1(x + self.self_attn(x))
        x = self.norm2(x + self.multihead_attn(x, memory))
        return self.norm3(x + self.feed_forward(x))


class SkipTransformer(nn.Module):
    """MLD's SkipTransformerEncoder/Decoder: (L-1)/2 input blocks whose outputs are kept, a
    middle block, (L-1)/2 output blocks each fed Linear([x, last kept output]) (LIFO), then a
    final LayerNorm. `memory` is passed to every layer (decoder layers)."""

    def __init__(self, make_layer, layers: int, width: int):
        super().__init__()
        assert layers % 2 == 1, "a skip transformer has an odd number of layers"
        n = layers // 2
        self.input_blocks = nn.ModuleList(make_layer() for _ in range(n))
        self.middle_block = make_layer()
        self.output_blocks = nn.ModuleList(make_layer() for _ in range(n))
        self.linear_blocks = nn.ModuleList(nn.Linear(2 * width, width) for _ in range(n))
        self.norm = nn.LayerNorm(width)

    def forward(self, x, *memory):
        skips = []
        for block in self.input_blocks:
            x = block(x, *memory)
            skips.append(x)
        x = self.middle_block(x, *memory)
        for block, linear in zip(self.output_blocks, self.linear_blocks):
            x = block(linear(torch.cat([x, skips.pop()], dim=-1)), *memory)
        return self.norm(x)


EXPERTS = {0: "t2m", 1: "ih"}  # dataset label -> the official name of its expert head and text encoder


class Denoiser(nn.Module):
    """UmfDenoiser (`umf_denoiser.py`): velocity of `state_dim`-wide tokens given a timestep
    and text tokens.

    Sequence [time, text tokens, state tokens] + learned positions through a skip transformer.
    With expert heads (P-Flow, `expert_layers` > 0, the official `dh_depth`) the state tokens
    leave through the head of `expert` ("ih" InterHuman or "t2m" HumanML3D; both heads exist,
    as in the official model); otherwise (S-Flow) through a plain projection. `mem_pos` is
    built by the official model and never used; it is here so that checkpoints load as they are."""

    def __init__(self, cfg: UmfConfig, state_dim: int, layers: int, expert_layers: int, expert: str = "ih"):
        super().__init__()
        w, text_dim = cfg.width, cfg.text_dim
        self.time_dim, self.expert = cfg.time_dim, expert if expert_layers > 0 else None
        self.latent_pre = nn.Linear(state_dim, w)
        if self.expert:
            self.latent_post_t2m = nn.Linear(w, state_dim)
            self.latent_post_ih = nn.Linear(w, state_dim)
        else:
            self.latent_post = nn.Linear(w, state_dim)
        self.time_embedding = TimestepEmbedding(cfg.time_dim, w)
        self.emb_proj = nn.Sequential(nn.ReLU(), nn.Linear(text_dim, w))
        self.query_pos = LearnedPositions(w, cfg.pe_length)
        self.mem_pos = LearnedPositions(w, cfg.pe_length)
        self.encoder = SkipTransformer(lambda: EncoderLayer(w, cfg.heads, cfg.ffn), layers, w)
        if self.expert:
            for name in EXPERTS.values():
                blocks = nn.ModuleList(EncoderLayer(w, cfg.heads, cfg.ffn) for _ in range(expert_layers))
                setattr(self, f"expert_{name}_blocks", blocks)
                setattr(self, f"expert_{name}_norm", nn.LayerNorm(w))

    def forward(self, sample, timestep, text):  # [B, N, state], [B], [B, K, text] -> [B, N, state]
        time = self.time_embedding(timestep_features(timestep, self.time_dim))[:, None]
        x = torch.cat([time, self.emb_proj(text), self.latent_pre(sample)], dim=1)
        x = self.encoder(self.query_pos(x))[:, 1 + text.shape[1] :]
        if not self.expert:
            return self.latent_post(x)
        for block in getattr(self, f"expert_{self.expert}_blocks"):
            x = block(x)
        x = getattr(self, f"expert_{self.expert}_norm")(x)
        return getattr(self, f"latent_post_{self.expert}")(x)


class Vae(nn.Module):
    """UmfVae, MLD's `encoder_decoder` VAE (`umf_vae.py`). Only the decoder runs here: `clip_frames`
    zero queries + learned positions attend to the projected latent tokens and give normalised
    features [B, F, frame_dim]. The encoder's modules are built so that checkpoints load as they
    are. Every frame is decoded: the official decode at length 300 (the official code masks
    frames past a shorter length; troupe returns whole clips)."""

    def __init__(self, cfg: UmfConfig):
        super().__init__()
        w, d = cfg.vae_width, cfg.latent_dim
        self.frames, self.width = cfg.clip_frames, w
        layer = dict(width=w, heads=cfg.vae_heads, ffn=cfg.vae_ffn)
        self.latent_pre = nn.Linear(w, d) if w != d else nn.Identity()
        self.latent_post = nn.Linear(d, w) if w != d else nn.Identity()
        self.query_pos_encoder = LearnedPositions(w, cfg.vae_pe_length)
        self.encoder = SkipTransformer(lambda: EncoderLayer(**layer), cfg.vae_layers, w)
        self.query_pos_decoder = LearnedPositions(w, cfg.vae_pe_length)
        self.decoder = SkipTransformer(lambda: DecoderLayer(**layer), cfg.vae_layers, w)
        self.global_motion_token = nn.Parameter(torch.randn(2 * cfg.tokens, w))
        self.skel_embedding = nn.Linear(cfg.frame_dim, w)
        self.final_layer = nn.Linear(w, cfg.frame_dim)

    def forward(self, z):
        memory = self.latent_post(z)
        queries = self.query_pos_decoder(torch.zeros(z.shape[0], self.frames, self.width))
        return self.final_layer(self.decoder(queries, memory))


class Umf(nn.Module):
    """Every network of UMF as the official `UMF` module names it (`umf/models/modeltype/umf.py`):
    CLIP's text tower (`token_embedding`, `clip_transformer`, `positional_embedding`,
    `ln_final`), the trainable text encoders (`clipTransEncoder_{t2m,ih,react}`,
    `clip_ln_*`), `vae`, `reac_denoiser` (S-Flow), `indi_denoiser` (P-Flow),
    `dataset_embedding` and `motion_context_encoder`. The methods are what the exported graphs
    run. Not in the state dict: the feature normaliser (a file of the dataset) and the null
    condition, which is computed from the weights (`refresh_null_condition`)."""

    def __init__(self, cfg: UmfConfig):
        super().__init__()
        assert cfg.prior_text_dim == cfg.reaction_text_dim, "both text encoders read CLIP's features"
        self.cfg = cfg
        self.stages = stage_tables(cfg)
        c, d = cfg.text_dim, cfg.latent_dim
        self.expert = EXPERTS[cfg.dataset_label]
        self.token_embedding = nn.Embedding(cfg.clip_vocab, c)
        self.clip_transformer = ClipTransformer(c, cfg.clip_layers, cfg.clip_heads)
        self.positional_embedding = nn.Parameter(torch.randn(CONTEXT, c) * 0.01)
        self.ln_final = nn.LayerNorm(c)
        for name in ("t2m", "ih", "react"):
            setattr(self, f"clipTransEncoder_{name}", EncoderStack(c, cfg.text_heads, cfg.text_ffn, cfg.text_layers))
            setattr(self, f"clip_ln_{name}", nn.LayerNorm(c))
        self.vae = Vae(cfg)
        self.reac_denoiser = Denoiser(cfg, 2 * d, cfg.reaction_layers, 0)
        self.indi_denoiser = Denoiser(cfg, d, cfg.prior_layers, cfg.prior_expert_layers, self.expert)
        self.dataset_embedding = nn.Embedding(2, c)
        self.motion_context_encoder = EncoderStack(d, cfg.context_heads, cfg.context_ffn, cfg.context_layers)
        # Feature normaliser (InterHuman mean/std) and the encoded empty prompt, per bundle.
        self.register_buffer("motion_mean", torch.zeros(cfg.frame_dim), persistent=False)
        self.register_buffer("motion_std", torch.ones(cfg.frame_dim), persistent=False)
        self.register_buffer("null_condition", torch.zeros(cfg.condition_dim), persistent=False)

    def clip_features(self, ids):
        """CLIP's text tower: token ids [B, T] -> the features after ln_final [B, T, C]."""
        return clip_features(self.token_embedding, self.positional_embedding, self.clip_transformer, self.ln_final, ids)

    def text_condition(self, clip_tokens, eot_index):
        """The official text branches: CLIP's token features [B, T, C] and the end-of-text index
        [B] -> the condition [B, prior ; reaction] (the P-Flow encoder of the bundle's dataset,
        and the S-Flow encoder, each followed by its LayerNorm, at the end-of-text token)."""
        branch = lambda name: getattr(self, f"clip_ln_{name}")(getattr(self, f"clipTransEncoder_{name}")(clip_tokens))  # noqa: E731
        return torch.cat([pick_token(branch(self.expert), eot_index), pick_token(branch("react"), eot_index)], dim=-1)

    @torch.no_grad()
    def refresh_null_condition(self):
        """The unconditional half of guidance is the empty prompt "" through CLIP and the text
        branches, as the official `_apply_cfg_tokens` does."""
        ids, eot = empty_prompt(self.cfg.clip_vocab)
        self.null_condition.copy_(self.text_condition(self.clip_features(ids), eot)[0])

    def prior_velocity(self, sample, timestep, text):
        """P-Flow: [B, N, D] at any stage's N; text tokens are [text, dataset embedding]."""
        dataset = self.dataset_embedding.weight[self.cfg.dataset_label]
        tokens = torch.stack([text, dataset.expand_as(text)], dim=1)
        return self.indi_denoiser(sample, timestep, tokens)

    def reaction_velocity(self, state, timestep, text):
        """S-Flow: [B, tokens, 2D] state [noise->context ; context->reaction], one text token."""
        return self.reac_denoiser(state, timestep, text[:, None])

    def context(self, latents):
        """[1, persons, tokens, D] -> [1, tokens, D]: the adapter runs on the persons concatenated
        on the token axis, and its output is averaged over persons (`type_context="mean"`).
        Persons are an axis of their own so that the reshapes are exact in symbolic shape
        inference (a runtime cannot prove that persons * tokens splits by tokens)."""
        b, p, n, d = latents.shape
        h = self.motion_context_encoder(latents.reshape(b, p * n, d))
        return h.reshape(latents.shape).mean(dim=1)

    def decode(self, latents):
        """[B, tokens, D] -> denormalised motion features [B, clip_frames, frame_dim]."""
        return self.vae(latents) * self.motion_std + self.motion_mean


# --------------------------------------------------------------------------------------------
# troupe's group sampler (mirrors src/umf/group.rs)
# --------------------------------------------------------------------------------------------

_ONE_THIRD, _TWO_THIRDS = 1 / 3, 2 / 3  # torchdiffeq's Python floats


def solve(solver: Solver, y: torch.Tensor, f) -> torch.Tensor:
    """Integrate dy/dtau = f(tau, y) over tau_j = j / steps (float64, rounded once to float32),
    in float32 in torchdiffeq's operation order (euler; rk4 = rk4_alt_step_func)."""
    grid = [torch.tensor(np.float32(j / solver.steps)) for j in range(solver.steps + 1)]
    for t0, t1 in zip(grid, grid[1:]):
        dt = t1 - t0
        if solver.method == "euler":
            y = y + dt * f(t0, y)
        elif solver.method == "rk4":
            k1 = f(t0, y)
            k2 = f(t0 + dt * _ONE_THIRD, y + dt * k1 * _ONE_THIRD)
            k3 = f(t0 + dt * _TWO_THIRDS, y + dt * (k2 - k1 * _ONE_THIRD))
            k4 = f(t1, y + dt * (k1 - k2 + k3))
            y = y + (k1 + 3 * (k2 + k3) + k4) * dt * 0.125
        else:
            raise ValueError(f"unknown solver method {solver.method!r}")
    return y


def guided(net, text: torch.Tensor, null_text: torch.Tensor, scale: float):
    """Classifier-free guidance G = G_null + w (G_cond - G_null) on one batch [null ; cond]
    (unconditional half first, as the official code). troupe's convention: with w == 1 exactly
    only the conditional half runs (the official code would still run both)."""

    def velocity(y, timestep):  # y [1, N, W], timestep 0-dim
        if scale == 1.0:
            return net(y, timestep.expand(1), text[None])
        out = net(torch.cat([y, y]), timestep.expand(2), torch.stack([null_text, text]))
        uncond, cond = out.chunk(2)
        return uncond + scale * (cond - uncond)

    return velocity


@torch.no_grad()
def generate_group(
    model: Umf,
    condition: np.ndarray | None,
    people: int,
    prior_solvers: list[Solver],
    reaction_solver: Solver,
    cfg_scale: float,
    prior_noise: np.ndarray,
    jump_noises: list[np.ndarray],
    reaction_noises: list[np.ndarray],
):
    """Generate a group from injected noise. prior_noise [T0, D]; jump_noises: the correlated
    n' [T_s, D] into each stage s >= 1; reaction_noises: [tokens, D] per person after the first. condition None
    uses the bundle's null condition. Returns (latents [people, tokens, D], motion [people, F,
    frame_dim]) as float32 arrays."""
    cfg = model.cfg
    d, p_dim = cfg.latent_dim, cfg.prior_text_dim
    null = model.null_condition
    cond = null if condition is None else torch.from_numpy(np.asarray(condition, np.float32))
    prior = guided(model.prior_velocity, cond[:p_dim], null[:p_dim], cfg_scale)
    reaction = guided(model.reaction_velocity, cond[p_dim:], null[p_dim:], cfg_scale)

    z = torch.from_numpy(prior_noise)[None]
    for s, (stage, solver) in enumerate(zip(model.stages, prior_solvers)):
        if s > 0:
            alpha, beta = jump_coefficients(stage.original_start_t, cfg.gamma)
            z = alpha * upsample(z, cfg.layout) + beta * torch.from_numpy(jump_noises[s - 1])[None]
        z = solve(solver, z, lambda tau, y, stage=stage: prior(y, stage_timestep(stage, tau)))
    latents = [z[0]]
    for p in range(1, people):
        context = model.context(torch.stack(latents)[None])
        w = torch.cat([torch.from_numpy(reaction_noises[p - 1])[None], context], dim=-1)
        w = solve(reaction_solver, w, lambda tau, y: reaction(y, tau))
        latents.append(w[0, :, d:])
    latents = torch.stack(latents)
    return latents.numpy(), model.decode(latents).numpy()
