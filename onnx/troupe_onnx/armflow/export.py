"""ARMFlow's exporter: a model into a troupe bundle (manifest + ONNX graphs [+ golden outputs]).

    python3 onnx/cli.py armflow export --preset tiny  --out onnx/bundles/armflow-tiny --golden   # committed
    python3 onnx/cli.py armflow export --preset paper --out onnx/bundles/paper          # benchmarks, not committed
    python3 onnx/cli.py armflow export --preset tiny  --check onnx/bundles/armflow-tiny # reproducibility check

    # an official checkpoint (ZenGengChin/armflow_official), as released:
    python3 onnx/cli.py armflow export --preset interhuman --checkpoint armflow.ckpt --out onnx/bundles/armflow-interhuman
    python3 onnx/cli.py armflow export --preset interx     --checkpoint armflowx.ckpt --out onnx/bundles/armflow-interx

Without `--checkpoint` the weights are random (seeded): such bundles test and benchmark the
runtime; they do not generate meaningful motion. `--write-checkpoint FILE` saves those random
weights in the official layout (the parity harness's checkpoints). The bundle contract is
documented in onnx/README.md.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.shared.manifest import write_manifest
from troupe_onnx.armflow.reference import (
    STREAM_ACTOR_POSTERIOR,
    STREAM_REACTOR_NOISE,
    Armflow,
    ArmflowConfig,
    StreamOptions,
    VaeConfig,
    ChannelsLastVaeStep,
    VaeWindows,
    VelocityGraph,
    clip_reference,
    clip_tokens,
    null_condition,
    stream_reference,
)
from troupe_onnx.armflow.hparams import config_from_checkpoint, hyper_parameters, read_hyper_parameters
from troupe_onnx.shared.checkpoint import load_checkpoint
from troupe_onnx.shared.clip import (
    CONTEXT,
    FULL_MERGES,
    TextEncoderGraph,
    text_encoder_spec,
    tokenizer_manifest,
    vocab_size,
    write_merges,
    write_prompt_golden,
)
from troupe_onnx.shared.export import FORMAT_VERSION, OPSET, export_graph, exporter_cli
from troupe_onnx.shared.noise import philox_normals

TOOL = "onnx/cli.py armflow export"  # the manifest's `producer.tool`
TINY_MERGES = 1000  # the tiny official-layout bundles' tokenizer: the first 1,000 of CLIP's merges
LAYOUTS = {262: "interhuman262", 336: "interx336"}
# The skeleton each layout's features are defined on (troupe.json `motion.skeleton`).
SKELETONS = {"interhuman262": "t2m22", "interx336": "smplx55"}

PRESETS = {
    # Small enough to commit and to run the test-suite in seconds; every architectural feature
    # (skips, AdaLN, multi-head attention, dilated causal VAE) is present.
    "tiny": ArmflowConfig(
        latent_dim=16, cond_dim=32, layers=3, heads=2, mlp_blocks=2, context_capacity=64,
        vae=VaeConfig(encoder_width=32, decoder_width=16, depth=2, kernel=7, norm_groups=4, causal=True),
    ),
    # `docs/spec/armflow.md` §2: 7x512 DiT, 5x512 MLP, 256-d latents, 262-d frames, 768-d text
    # condition. The streaming VAE uses kernel 3 / dilations 9,3,1 so that its window stays short. The context
    # keeps 128 tokens (17 s): the official model trains on clips of at most 75 tokens, and the
    # bound keeps a session under 8 MB and its step cost flat however long it streams.
    "paper": ArmflowConfig(
        latent_dim=256, cond_dim=768, layers=7, heads=8, mlp_blocks=5, context_capacity=128,
        vae=VaeConfig(encoder_width=512, decoder_width=256, depth=3, kernel=3, norm_groups=32, causal=True),
    ),
}


def official(frame_dim: int, clip_frames: int, size: str, windows: VaeWindows) -> ArmflowConfig:
    """The official configuration (`cfg/armflow/armflow.yaml`, `armflowx.yaml`): non-causal
    VAE (k7, dilations 27/9/3/1, GroupNorm 32, widths 512/256), 7-layer context encoder, 5 MLP
    blocks, 768-d text branch. `tiny` keeps that layout at reduced width for the parity
    harness's committed checkpoints."""
    full = size == "full"
    return ArmflowConfig(
        frame_dim=frame_dim, latent_dim=256 if full else 16, cond_dim=768 if full else 32, layers=7,
        heads=8 if full else 2, mlp_blocks=5, context_capacity=128, clip_frames=clip_frames,
        text_branch=True, text_heads=8, text_ffn=2048 if full else 64,
        clip_layers=12 if full else 1, clip_heads=12 if full else 2, clip_merges=FULL_MERGES if full else TINY_MERGES,
        vae=VaeConfig(encoder_width=512 if full else 32, decoder_width=256 if full else 32, depth=4,
                      kernel=7, norm_groups=32, causal=False),
        stream_windows=windows,
    )


# Stream-mode windows of the non-causal official VAE (onnx/README.md, "Stream mode with the
# official VAE", for how they were chosen).
OFFICIAL_WINDOWS = VaeWindows(context_frames=96, lookahead_frames=16, context_tokens=16, lookahead_tokens=2)
PRESETS |= {
    "interhuman": official(262, 300, "full", OFFICIAL_WINDOWS),
    "interx": official(336, 150, "full", OFFICIAL_WINDOWS),
    "tiny-interhuman": official(262, 300, "tiny", OFFICIAL_WINDOWS),
    "tiny-interx": official(336, 150, "tiny", OFFICIAL_WINDOWS),
}

# Tensors of the official checkpoints that inference does not use, and why.
IGNORED = {
    "armflow.arnet.head_nm.": "constructed but never called by the official forward",
    "armflow.pe.": "sinusoidal table, recomputed",
    "vae.smpl_loss.": "SMPL-X body model of the InterX training loss",
    "normalizer.": "evaluation-time feature statistics",
    "loss_fn.": "training loss state",
}


# --------------------------------------------------------------------------------------------
# Export wrappers: one module per graph of the bundle
# --------------------------------------------------------------------------------------------


class ConditioningGraph(torch.nn.Module):
    """What is constant while the condition is: AdaLN modulation of every layer, and <sos>."""

    def __init__(self, model: Armflow):
        super().__init__()
        self.core = model.armflow

    def forward(self, condition):
        return self.core.arnet.modulation(condition), self.core.start_token * 1.0


class ContextLayerGraph(torch.nn.Module):
    """Graph `index` of the context encoder's split (`SkipAdaLNTransformer.layer_*`): the dense
    work between two attentions, over N token rows of any streams. The runtime runs each
    block's attention itself, over the key/value cache it owns."""

    def __init__(self, model: Armflow, index: int):
        super().__init__()
        self.arnet, self.index = model.armflow.arnet, index

    def forward(self, *inputs):
        if self.index == 0:
            return self.arnet.layer_entry(*inputs)
        if self.index == len(self.arnet.blocks()):
            return self.arnet.layer_exit(*inputs)
        return self.arnet.layer_link(self.index, *inputs)


class ContextStepGraph(torch.nn.Module):
    """The whole context encoder as one graph with the cache as inputs (attention inside): the
    form onnxruntime runs best, written only for the benchmarks' peers (`--peer-graphs`)."""

    def __init__(self, model: Armflow):
        super().__init__()
        self.arnet = model.armflow.arnet

    def forward(self, tokens, positions, modulation, key_mask, *past_flat):
        past = list(zip(past_flat[0::2], past_flat[1::2]))
        context, new = self.arnet.step(tokens, positions, modulation, past, key_mask)
        return (context, *[t for kv in new for t in kv])


def write_peer_graphs(model: Armflow, out_dir: Path):
    """`peers/context_step.onnx`: the one-graph context step of the same weights, `[B, S]`
    tokens against `past_*` caches `[B, heads, P, head_dim]`, returning the context and the new
    entries (`benches/peers.py`)."""
    cfg = model.cfg
    c, h, dh, L = cfg.width, cfg.heads, cfg.head_dim, cfg.layers
    t = lambda name, shape, dtype="float32": {"name": name, "dtype": dtype, "shape": shape}  # noqa: E731
    kv = lambda prefix, n: [t(f"{prefix}_{x}_{i}", ["B", h, n, dh]) for i in range(L) for x in ("key", "value")]  # noqa: E731
    spec = {
        "file": "peers/context_step.onnx",
        "inputs": [t("tokens", ["B", "S", c]), t("positions", ["B", "S"], "int64"),
                   t("modulation", ["B", L, 6, c]), t("key_mask", ["B", "P"]), *kv("past", "P")],
        "outputs": [t("context", ["B", c]), *kv("new", "S")],
    }
    (out_dir / "peers").mkdir(parents=True, exist_ok=True)
    past = [torch.randn(2, h, 3, dh) for _ in range(2 * L)]
    args = (torch.randn(2, 2, c), torch.tensor([[3, 4], [3, 4]]), torch.randn(2, L, 6, c), torch.zeros(2, 3), *past)
    export_graph(ContextStepGraph(model), args, spec, out_dir)


class ContextFullGraph(torch.nn.Module):
    """The official context call: the whole prefix, no attention mask, no cache."""

    def __init__(self, model: Armflow):
        super().__init__()
        self.arnet = model.armflow.arnet

    def forward(self, tokens, modulation):
        return self.arnet.full(tokens, modulation)


class EncoderStepGraph(torch.nn.Module):
    """The encoder's per-token step, its output split into the posterior's mean and logvar."""

    def __init__(self, model: Armflow):
        super().__init__()
        self.step = ChannelsLastVaeStep(model.vae.encoder)
        self.latent_dim = model.cfg.latent_dim

    def forward(self, motion, *state):
        out, *next_state = self.step(motion, *state)
        return (out[..., : self.latent_dim], out[..., self.latent_dim :], *next_state)


def dims(*d):
    return list(d)


def graph_specs(model: Armflow) -> dict:
    """Every graph's file, inputs and outputs as the manifest states them. Symbolic dims are
    strings: T frames, N tokens, S new tokens, P cached tokens, B batch."""
    cfg = model.cfg
    c, lat, d, h, dh, L = cfg.width, cfg.latent_dim, cfg.frame_dim, cfg.heads, cfg.head_dim, cfg.layers
    fpt = cfg.frames_per_token
    t = lambda name, shape, dtype="float32": {"name": name, "dtype": dtype, "shape": shape}  # noqa: E731
    # The context encoder is `layers + 1` graphs over N token rows (the tokens of every stream
    # of a round): the runtime runs attention between them over the cache it owns.
    rows = lambda *names: [t(n, dims("N", c)) for n in names]  # noqa: E731
    mod = lambda name: t(name, dims(6, "N", c))  # noqa: E731  (component-major: contiguous slices)
    qkv = rows("query", "key", "value")
    layers = [{
        "file": "context_layer_0.onnx",
        "inputs": [*rows("tokens"), t("positions", dims("N"), "int64"), mod("modulation")],
        "outputs": [*rows("next_x"), *qkv],
    }]
    for i in range(1, L):
        skip = rows("skip") if i > L // 2 else []
        layers.append({
            "file": f"context_layer_{i}.onnx",
            "inputs": [*rows("x", "attention"), mod("finish_modulation"), mod("modulation"), *skip],
            "outputs": [*rows("next_x"), *qkv],
        })
    layers.append({
        "file": f"context_layer_{L}.onnx",
        "inputs": [*rows("x", "attention"), mod("finish_modulation")],
        "outputs": rows("context"),
    })

    def state(stack, prefix):
        shapes = ChannelsLastVaeStep(stack).state_shapes()
        return [t(f"{prefix}state_{i}", ["B", k, ch]) for i, (_, k, ch) in enumerate(shapes)]

    specs = {
        "conditioning": {
            "file": "conditioning.onnx",
            "inputs": [t("condition", dims(1, cfg.cond_dim))],  # with feedback: the caller's, then the fed back
            "outputs": [t("modulation", dims(1, L, 6, c)), t("start_token", dims(1, 1, c))],
        },
        "context_layers": layers,
        "velocity": {
            "file": "velocity.onnx",
            "inputs": [
                t("actor", dims("B", lat)),
                t("noisy", dims("B", lat)),
                t("context", dims("B", c)),
                t("r", dims("B")),
                t("t", dims("B")),
            ],
            "outputs": [t("velocity", dims("B", lat))],
        },
        "vae_encoder": {
            "file": "vae_encoder.onnx",
            "inputs": [t("motion", dims(1, "T", d))],
            "outputs": [t("mean", dims(1, "N", lat)), t("logvar", dims(1, "N", lat))],
        },
        "vae_decoder": {
            "file": "vae_decoder.onnx",
            "inputs": [t("latents", dims(1, "N", lat))],
            "outputs": [t("motion", dims(1, "T", d))],
        },
    }
    if cfg.clip_frames:  # the official clip loop re-runs the whole prefix with no mask
        specs["context_full"] = {
            "file": "context_full.onnx",
            "inputs": [t("tokens", dims("B", "S", c)), t("modulation", dims("B", L, 6, c))],
            "outputs": [t("context", dims("B", c))],
        }
    if cfg.text_branch:  # the official text encoder: CLIP's tower, then the trainable branch
        specs["text_encoder"] = text_encoder_spec(cfg.cond_dim)
        specs["text_branch"] = {
            "file": "text_branch.onnx",
            "inputs": [t("clip_tokens", dims("B", "T", cfg.cond_dim)), t("eot_index", dims("B"), "int64")],
            "outputs": [t("condition", dims("B", cfg.cond_dim))],
        }
    if cfg.vae.causal:  # a causal VAE also streams token by token with explicit conv state
        enc, dec = model.vae.encoder, model.vae.decoder
        specs["vae_encoder_step"] = {
            "file": "vae_encoder_step.onnx",
            "inputs": [t("motion", dims("B", fpt, d)), *state(enc, "")],
            "outputs": [t("mean", dims("B", 1, lat)), t("logvar", dims("B", 1, lat)), *state(enc, "next_")],
        }
        specs["vae_decoder_step"] = {
            "file": "vae_decoder_step.onnx",
            "inputs": [t("latents", dims("B", 1, lat)), *state(dec, "")],
            "outputs": [t("motion", dims("B", fpt, d)), *state(dec, "next_")],
        }
    return specs


def traced_inputs(spec: dict, rows: int = 3) -> tuple:
    """Example inputs of a graph's declared shapes to trace it with: `rows` (>= 2, so that it is
    not specialised away) for every symbol, positions for int64 inputs."""
    size = lambda d: rows if isinstance(d, str) else d  # noqa: E731
    return tuple(
        torch.arange(rows) + 3 if x["dtype"] == "int64" else torch.randn(*map(size, x["shape"]))
        for x in spec["inputs"]
    )


def build_model(preset: str, seed: int, checkpoint: Path | None = None, config: ArmflowConfig | None = None) -> Armflow:
    """The preset's model (or `config`'s) with seeded random weights, or the weights of `checkpoint`."""
    torch.manual_seed(seed)
    cfg = config or PRESETS[preset]
    if checkpoint is not None:
        cfg = checkpoint_config(checkpoint, cfg)
    model = Armflow(cfg).eval()
    if checkpoint is not None:
        load_checkpoint(model, checkpoint, IGNORED)
        return model
    # Random init leaves AdaLN gates and biases near zero; widen them so every path matters.
    with torch.no_grad():
        for name, p in model.named_parameters():
            if name.endswith(("q_bias", "v_bias")) or ("norm" in name and name.endswith("bias")):
                p.normal_(0.0, 0.1)
            if "norm" in name and name.endswith("weight"):
                p.normal_(1.0, 0.1)
    return model


def checkpoint_config(checkpoint: Path, preset: ArmflowConfig) -> ArmflowConfig:
    """The preset with the configuration the checkpoint stores; says what it took from where."""
    hp = read_hyper_parameters(checkpoint)
    if hp is None:
        print(f"{checkpoint.name}: no stored configuration (hyper_parameters); using the preset as it is")
        return preset
    cfg, notes = config_from_checkpoint(hp, preset)
    for note in notes:
        print(f"{checkpoint.name}: {note}")
    return cfg


def export_bundle(
    preset: str, out_dir: Path, seed: int = 0, checkpoint: Path | None = None,
    config: ArmflowConfig | None = None, manifest_extra: dict | None = None,
) -> Armflow:
    """Write the bundle of `preset` (or of `config`, named `preset`). `manifest_extra` adds to
    the manifest's sections (a trained model's `producer.training`, `condition.labels`)."""
    model = build_model(preset, seed, checkpoint, config)
    cfg = model.cfg  # the checkpoint's own configuration where it stores one
    out_dir.mkdir(parents=True, exist_ok=True)
    specs = graph_specs(model)
    c, lat, h, dh = cfg.width, cfg.latent_dim, cfg.heads, cfg.head_dim
    examples = {  # dynamic dims get example sizes >= 2: a size of 1 can be specialised away
        "conditioning": (ConditioningGraph(model), (torch.randn(1, cfg.cond_dim),)),
        "velocity": (
            VelocityGraph(model.armflow),
            (torch.randn(2, lat), torch.randn(2, lat), torch.randn(2, c), torch.rand(2), torch.rand(2)),
        ),
        "vae_encoder": (model.vae.encoder, (torch.randn(1, 8 * cfg.frames_per_token, cfg.frame_dim),)),
        "vae_decoder": (model.vae.decoder, (torch.randn(1, 8, lat),)),
    }
    if "context_full" in specs:
        examples["context_full"] = (ContextFullGraph(model), (torch.randn(2, 3, c), torch.randn(2, cfg.layers, 6, c)))
    if "text_encoder" in specs:
        ids = torch.randint(0, vocab_size(cfg.clip_merges), (2, CONTEXT))
        examples["text_encoder"] = (TextEncoderGraph(model.text_encoder, "clip_features"), (ids,))
    if "text_branch" in specs:
        examples["text_branch"] = (model.text_encoder, (torch.randn(2, 5, cfg.cond_dim), torch.tensor([4, 2])))
    if "vae_encoder_step" in specs:
        states = lambda stack: [torch.randn(s) for s in ChannelsLastVaeStep(stack).state_shapes(2)]  # noqa: E731
        fpt = cfg.frames_per_token
        examples["vae_encoder_step"] = (
            EncoderStepGraph(model), (torch.randn(2, fpt, cfg.frame_dim), *states(model.vae.encoder)),
        )
        examples["vae_decoder_step"] = (
            ChannelsLastVaeStep(model.vae.decoder), (torch.randn(2, 1, lat), *states(model.vae.decoder)),
        )
    for name, (module, args) in examples.items():
        # Folding would turn the constant `start_token` output into a nameless initializer.
        export_graph(module, args, specs[name], out_dir, fold_constants=name != "conditioning")
    for i, spec in enumerate(specs["context_layers"]):
        export_graph(ContextLayerGraph(model, i), traced_inputs(spec), spec, out_dir)
    windows = VaeWindows.of(model)
    source = {"checkpoint": checkpoint.name} if checkpoint else {"seed": seed}
    producer = {"tool": TOOL, "preset": preset, **source, "opset": OPSET}
    manifest = {
        "format": "troupe-bundle",
        "format_version": FORMAT_VERSION,
        "family": "armflow",
        "name": f"armflow-{preset}",
        "producer": producer,
        "motion": {"layout": LAYOUTS[cfg.frame_dim], "frame_dim": cfg.frame_dim, "fps": cfg.fps,
                   "skeleton": SKELETONS[LAYOUTS[cfg.frame_dim]]},
        "latent": {"dim": lat, "scale": cfg.latent_scale, "frames_per_token": cfg.frames_per_token},
        "condition": condition_manifest(model),
        "context": {
            "width": c, "layers": cfg.layers, "heads": h, "head_dim": dh,
            "capacity_tokens": cfg.context_capacity,
        },
        "vae": {
            "streaming": cfg.vae.causal,
            "encoder": {"context_frames": windows.context_frames, "lookahead_frames": windows.lookahead_frames},
            "decoder": {"context_tokens": windows.context_tokens, "lookahead_tokens": windows.lookahead_tokens},
        },
        "sampler": {"steps": cfg.steps, "cfg_scale": cfg.cfg_scale, "actor_latent": "sample"},
        "graphs": specs,
    }
    if cfg.clip_frames:
        manifest["clip"] = {"frames": cfg.clip_frames, "tokens": clip_tokens(cfg)}
    if cfg.text_branch:
        write_merges(out_dir, cfg.clip_merges)
        manifest["tokenizer"] = tokenizer_manifest(cfg.clip_merges)
    for section, values in (manifest_extra or {}).items():
        merge = isinstance(values, dict) and isinstance(manifest.get(section), dict)
        manifest[section] = {**manifest[section], **values} if merge else values
    manifest = write_manifest(out_dir, manifest)
    return model


def condition_manifest(model: Armflow) -> dict:
    """The manifest's `condition`: the width a caller passes, and what "no condition" is and
    where it comes from (`null_source`): the empty prompt through the checkpoint's CLIP and text
    branch (the official meaning), a vector the configuration gives, or zeros. A model with
    condition feedback adds `feedback` (its kind and width): the conditioning graph reads the
    caller's `dim` floats followed by those."""
    cfg = model.cfg
    dim = {"dim": cfg.caller_cond_dim}
    if cfg.condition_feedback is not None:
        dim["feedback"] = {"kind": cfg.condition_feedback, "dim": cfg.feedback_dim}
    if cfg.text_branch:
        null = null_condition(model)[0].tolist()
        return dim | {"null": [float(v) for v in null], "null_source": "empty_prompt"}
    if cfg.null_condition is not None:
        return dim | {"null": list(cfg.null_condition), "null_source": "vector"}
    return dim | {"null_source": "zeros"}


# --------------------------------------------------------------------------------------------
# Golden outputs
# --------------------------------------------------------------------------------------------

GOLDEN_TOKENS = 48
SEEDED_NOISE = {"seed": 7, "tokens": [0, 1, 2, 1000], "dim_extra": 3}


def synthetic_actor(frames: int, dim: int, seed: int = 1) -> np.ndarray:
    """Smooth multi-frequency motion-like signal, float32 [frames, dim]."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / 30.0
    freq = rng.uniform(0.2, 2.0, size=(1, dim))
    phase = rng.uniform(0, 2 * np.pi, size=(1, dim))
    amp = rng.uniform(0.2, 1.0, size=(1, dim))
    return (amp * np.sin(2 * np.pi * freq * t + phase)).astype(np.float32)


def write_golden(model: Armflow, out_dir: Path, actor: np.ndarray | None = None):
    """Goldens of the stream loop; `actor` (features, at least 194 frames) replaces the synthetic
    actor (a trained model is better held to real motion). A model with condition feedback gets
    its feedback loop's goldens (`stream_reference`), and `{case}_feedback.npy` [N, 5]: what each
    token's condition was given after the caller's."""
    if model.cfg.clip_frames:
        return write_clip_golden(model, out_dir)
    cfg = model.cfg
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    rng = np.random.default_rng(2)
    frames = GOLDEN_TOKENS * cfg.frames_per_token + 2  # two trailing frames of an unfinished token
    actor = synthetic_actor(frames, cfg.frame_dim) if actor is None else np.ascontiguousarray(actor[:frames], np.float32)
    assert actor.shape == (frames, cfg.frame_dim), f"the golden actor needs {frames} frames"
    np.save(g / "actor.npy", actor)
    cases = {
        "default": dict(steps=1, cfg_scale=1.0, capacity=None,
                        condition=rng.standard_normal(cfg.caller_cond_dim).astype(np.float32)),
        "cfg_steps_window": dict(steps=2, cfg_scale=2.5, capacity=16, condition=None),
    }
    index = {}
    for name, case in cases.items():
        xi = rng.standard_normal((GOLDEN_TOKENS, cfg.latent_dim)).astype(np.float32)
        eps = rng.standard_normal((GOLDEN_TOKENS, cfg.latent_dim)).astype(np.float32)
        out = stream_reference(model, actor, xi, eps, StreamOptions(**case))
        arrays = {"xi": xi, "eps": eps, **out}
        if case["condition"] is not None:
            arrays["condition"] = case["condition"]
        for k, v in arrays.items():
            np.save(g / f"{name}_{k}.npy", v)
        index[name] = {k: case[k] for k in ("steps", "cfg_scale", "capacity")} | {
            "has_condition": case["condition"] is not None
        }
    # Cross-language check of the portable noise generator.
    s = SEEDED_NOISE
    n = cfg.latent_dim + s["dim_extra"]
    for stream in (STREAM_ACTOR_POSTERIOR, STREAM_REACTOR_NOISE):
        rows = [philox_normals(s["seed"], tok, stream, n) for tok in s["tokens"]]
        np.save(g / f"philox_seed{s['seed']}_stream{stream}.npy", np.stack(rows))
    index["philox"] = s
    (g / "cases.json").write_text(json.dumps(index, indent=2) + "\n")
    check_windows_match_full_clip(model, actor)


GUIDED_SCALE = 2.0  # the CFG scale of the `clip_guided` and `stream_guided` goldens
CLIP_TEXT_TOKENS, CLIP_EOT = 77, 9  # CLIP's context length; the end-of-text token of a short prompt


@torch.no_grad()
def write_clip_golden(model: Armflow, out_dir: Path):
    """Goldens of an official-layout bundle, all from the PyTorch reference on the same weights:
    - `text`: the text branch on random CLIP token features;
    - `clip`: the official clip loop on a short actor (zero-padded to the clip length),
      conditioned on that text, with injected posterior noise and noise token;
    - `clip_null`: a full-length actor, null condition, other noise;
    - `stream`: the stream loop with the bundle's windows (non-causal VAE, lookahead);
    - `clip_guided`, `stream_guided`: the `clip` actor and text with classifier-free guidance
      at scale 2 (what a checkpoint saved with `mf.cfg_scale: 2` runs), other noise."""
    cfg = model.cfg
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    rng = np.random.default_rng(3)
    n, lat = clip_tokens(cfg), cfg.latent_dim
    arrays = {
        "text_clip_tokens": rng.standard_normal((CLIP_TEXT_TOKENS, cfg.cond_dim)).astype(np.float32),
        "text_eot_index": np.array([CLIP_EOT], np.int64),
    }
    tokens = torch.from_numpy(arrays["text_clip_tokens"])[None]
    condition = model.text_encoder(tokens, torch.tensor([CLIP_EOT]))[0].numpy().astype(np.float32)
    arrays["text_condition"] = condition
    write_prompt_golden(out_dir, model.text_encoder.clip_features, model.text_encoder)
    short = cfg.clip_frames * 2 // 3
    cases = {"clip": (synthetic_actor(short, cfg.frame_dim), condition),
             "clip_null": (synthetic_actor(cfg.clip_frames, cfg.frame_dim, seed=4), None)}
    for name, (actor, cond) in cases.items():
        xi = rng.standard_normal((n, lat)).astype(np.float32)
        eps = rng.standard_normal(lat).astype(np.float32)
        out = clip_reference(model, actor, xi, eps, cond)
        arrays |= {f"{name}_actor": actor, f"{name}_xi": xi, f"{name}_eps": eps}
        arrays |= {f"{name}_{k}": v for k, v in out.items()}
    actor = cases["clip"][0]
    w = VaeWindows.of(model)
    tokens_stream = (actor.shape[0] - w.lookahead_frames) // cfg.frames_per_token
    xi = rng.standard_normal((tokens_stream, lat)).astype(np.float32)
    eps = rng.standard_normal((tokens_stream, lat)).astype(np.float32)
    out = stream_reference(model, actor, xi, eps, StreamOptions(condition=condition), w)
    arrays |= {"stream_xi": xi, "stream_eps": eps} | {f"stream_{k}": v for k, v in out.items()}
    xi = rng.standard_normal((n, lat)).astype(np.float32)
    eps = rng.standard_normal(lat).astype(np.float32)
    out = clip_reference(model, actor, xi, eps, condition, cfg_scale=GUIDED_SCALE)
    arrays |= {"clip_guided_actor": actor, "clip_guided_xi": xi, "clip_guided_eps": eps}
    arrays |= {f"clip_guided_{k}": v for k, v in out.items()}
    xi = rng.standard_normal((tokens_stream, lat)).astype(np.float32)
    eps = rng.standard_normal((tokens_stream, lat)).astype(np.float32)
    out = stream_reference(model, actor, xi, eps, StreamOptions(condition=condition, cfg_scale=GUIDED_SCALE), w)
    arrays |= {"stream_guided_xi": xi, "stream_guided_eps": eps} | {f"stream_guided_{k}": v for k, v in out.items()}
    for k, v in arrays.items():  # C order: the C ABI test reads them with a minimal reader
        np.save(g / f"{k}.npy", np.ascontiguousarray(v))


@torch.no_grad()
def check_windows_match_full_clip(model: Armflow, actor: np.ndarray):
    """The manifest's window sizes must make windowed VAE calls equal one causal pass, and so
    must stepping token by token with explicit state."""
    cfg, fpt = model.cfg, model.cfg.frames_per_token
    w = VaeWindows.of(model)
    ctx_f, ctx_t = w.context_frames, w.context_tokens
    x = torch.from_numpy(actor)[None]
    n = actor.shape[0] // fpt
    full_mean, _ = model.vae.encoder(x[:, : n * fpt])
    lat = torch.randn(1, n, cfg.latent_dim)
    full_frames = model.vae.decoder(lat)
    for j in range(n):
        m, _ = model.vae.encoder(x[:, max(0, j * fpt - ctx_f) : (j + 1) * fpt])
        assert torch.allclose(m[0, -1], full_mean[0, j], atol=1e-5), f"encoder window, token {j}"
        f = model.vae.decoder(lat[:, max(0, j - ctx_t) : j + 1])
        assert torch.allclose(f[0, -fpt:], full_frames[0, j * fpt : (j + 1) * fpt], atol=1e-5), f"decoder window, token {j}"
    if not cfg.vae.causal:
        return
    # The step graphs' own (channels-last) form against the full causal pass.
    enc, dec = ChannelsLastVaeStep(model.vae.encoder), ChannelsLastVaeStep(model.vae.decoder)
    enc_state = [torch.zeros(s) for s in enc.state_shapes()]
    dec_state = [torch.zeros(s) for s in dec.state_shapes()]
    for j in range(n):
        out, *enc_state = enc(x[:, j * fpt : (j + 1) * fpt], *enc_state)
        assert torch.allclose(out[0, 0, : cfg.latent_dim], full_mean[0, j], atol=1e-5), f"encoder step, token {j}"
        f, *dec_state = dec(lat[:, j : j + 1], *dec_state)
        assert torch.allclose(f[0], full_frames[0, j * fpt : (j + 1) * fpt], atol=1e-5), f"decoder step, token {j}"


# --------------------------------------------------------------------------------------------
# Official-layout checkpoints of random weights (the parity harness)
# --------------------------------------------------------------------------------------------


def write_checkpoint(preset: str, seed: int, path: Path, extras: bool = True):
    """Save the preset's seeded random weights as an official checkpoint: a Lightning-style
    `{"state_dict": ...}` under the official names. With `extras`, also tensors the official
    checkpoints carry that inference ignores (`IGNORED`), so that the loader meets them."""
    model = build_model(preset, seed)
    state = model.state_dict()
    if extras:
        cfg = PRESETS[preset]
        state |= {
            "armflow.arnet.head_nm.ada_lin.1.weight": torch.zeros(2 * cfg.width, cfg.cond_dim),
            "armflow.arnet.head_nm.ada_lin.1.bias": torch.zeros(2 * cfg.width),
        }
    saved = {"state_dict": state, "epoch": 0}
    if model.cfg.text_branch:  # the official layout: Lightning's copy of the training configuration
        saved["hyper_parameters"] = hyper_parameters(model.cfg)
    torch.save(saved, path)


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py armflow export`."""
    os.environ.setdefault("PYTHONHASHSEED", "0")
    exporter_cli(
        __doc__, PRESETS, export_bundle, write_golden, write_checkpoint, argv=argv, prog=prog,
        peer_graphs=write_peer_graphs,
    )
