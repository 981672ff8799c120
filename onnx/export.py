#!/usr/bin/env python3
"""Export an ARMFlow model into a troupe bundle (manifest + ONNX graphs [+ golden outputs]).

    python onnx/export.py --preset tiny  --out onnx/armflow-tiny --golden   # the committed bundle
    python onnx/export.py --preset paper --out onnx/paper                   # benchmarks, not committed
    python onnx/export.py --preset tiny  --check onnx/armflow-tiny          # reproducibility check

The weights are random (seeded): these bundles test and benchmark the runtime; they do not
generate meaningful motion. The bundle contract is documented in onnx/README.md.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from armflow_ref import (  # noqa: E402
    STREAM_ACTOR_POSTERIOR,
    STREAM_REACTOR_NOISE,
    Armflow,
    ArmflowConfig,
    StreamOptions,
    VaeConfig,
    VaeStep,
    decoder_context_tokens,
    encoder_context_frames,
    philox_normals,
    stream_reference,
)

FORMAT_VERSION = 1
OPSET = 17

PRESETS = {
    # Small enough to commit and to run the test-suite in seconds; every architectural feature
    # (skips, AdaLN, multi-head attention, dilated causal VAE) is present.
    "tiny": ArmflowConfig(
        latent_dim=16, cond_dim=32, layers=3, heads=2, mlp_blocks=2, context_capacity=64,
        vae=VaeConfig(encoder_width=32, decoder_width=16, depth=2, kernel=7, norm_groups=4, causal=True),
    ),
    # models.md 1.2: 7x512 DiT, 5x512 MLP, 256-d latents, 262-d frames, 768-d text condition. The
    # streaming VAE uses kernel 3 / dilations 9,3,1 so that its window stays short. The context
    # keeps 128 tokens (17 s): the official model trains on clips of at most 75 tokens, and the
    # bound keeps a session under 8 MB and its step cost flat however long it streams.
    "paper": ArmflowConfig(
        latent_dim=256, cond_dim=768, layers=7, heads=8, mlp_blocks=5, context_capacity=128,
        vae=VaeConfig(encoder_width=512, decoder_width=256, depth=3, kernel=3, norm_groups=32, causal=True),
    ),
}


# --------------------------------------------------------------------------------------------
# Export wrappers: one module per graph of the bundle
# --------------------------------------------------------------------------------------------


class ConditioningGraph(torch.nn.Module):
    """What is constant while the condition is: AdaLN modulation of every layer, and <sos>."""

    def __init__(self, model: Armflow):
        super().__init__()
        self.context = model.context

    def forward(self, condition):
        return self.context.modulation(condition), self.context.start_token * 1.0


class ContextStepGraph(torch.nn.Module):
    def __init__(self, model: Armflow):
        super().__init__()
        self.context = model.context

    def forward(self, tokens, positions, modulation, key_mask, *past_flat):
        past = list(zip(past_flat[0::2], past_flat[1::2]))
        context, present = self.context.step(tokens, positions, modulation, past, key_mask)
        return (context, *[t for kv in present for t in kv])


class EncoderStepGraph(torch.nn.Module):
    """The encoder's per-token step, its output split into the posterior's mean and logvar."""

    def __init__(self, model: Armflow):
        super().__init__()
        self.step = VaeStep(model.vae_encoder)
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
    # Streaming graphs take a batch of B streams, so that many sessions read the weights once.
    past = [t(f"past_{kv}_{i}", dims("B", h, "P", dh)) for i in range(L) for kv in ("key", "value")]
    present = [t(f"present_{kv}_{i}", dims("B", h, "P+S", dh)) for i in range(L) for kv in ("key", "value")]

    def state(stack, prefix):
        shapes = VaeStep(stack).state_shapes()
        return [t(f"{prefix}state_{i}", ["B", ch, k]) for i, (_, ch, k) in enumerate(shapes)]

    specs = {
        "conditioning": {
            "file": "conditioning.onnx",
            "inputs": [t("condition", dims(1, cfg.cond_dim))],
            "outputs": [t("modulation", dims(1, L, 6, c)), t("start_token", dims(1, 1, c))],
        },
        "context_step": {
            "file": "context_step.onnx",
            "inputs": [
                t("tokens", dims("B", "S", c)),
                t("positions", dims("B", "S"), "int64"),
                t("modulation", dims("B", L, 6, c)),
                t("key_mask", dims("B", "P")),
                *past,
            ],
            "outputs": [t("context", dims("B", c)), *present],
        },
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
    if cfg.vae.causal:  # a causal VAE also streams token by token with explicit conv state
        enc, dec = model.vae_encoder, model.vae_decoder
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


def export_graph(module, args, spec, out_dir: Path, fold_constants: bool = True):
    names_in = [x["name"] for x in spec["inputs"]]
    names_out = [x["name"] for x in spec["outputs"]]
    dynamic = {}
    for x in spec["inputs"] + spec["outputs"]:
        axes = {i: str(v).replace("+", "_plus_") for i, v in enumerate(x["shape"]) if isinstance(v, str)}
        if axes:
            dynamic[x["name"]] = axes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the legacy exporter's deprecation notice
        torch.onnx.export(
            module, args, str(out_dir / spec["file"]), input_names=names_in, output_names=names_out,
            dynamic_axes=dynamic, opset_version=OPSET, do_constant_folding=fold_constants, dynamo=False,
        )


def build_model(preset: str, seed: int) -> Armflow:
    torch.manual_seed(seed)
    model = Armflow(PRESETS[preset]).eval()
    # Random init leaves AdaLN gates and biases near zero; widen them so every path matters.
    with torch.no_grad():
        for name, p in model.named_parameters():
            if name.endswith(("q_bias", "v_bias")) or ("norm" in name and name.endswith("bias")):
                p.normal_(0.0, 0.1)
            if "norm" in name and name.endswith("weight"):
                p.normal_(1.0, 0.1)
    return model


def export_bundle(preset: str, out_dir: Path, seed: int = 0) -> Armflow:
    cfg = PRESETS[preset]
    model = build_model(preset, seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    specs = graph_specs(model)
    c, lat, h, dh = cfg.width, cfg.latent_dim, cfg.heads, cfg.head_dim
    past = [torch.randn(2, h, 3, dh) for _ in range(2 * cfg.layers)]
    examples = {  # dynamic dims get example sizes >= 2: a size of 1 can be specialised away
        "conditioning": (ConditioningGraph(model), (torch.randn(1, cfg.cond_dim),)),
        "context_step": (
            ContextStepGraph(model),
            (torch.randn(2, 2, c), torch.tensor([[3, 4], [3, 4]]), torch.randn(2, cfg.layers, 6, c),
             torch.zeros(2, 3), *past),
        ),
        "velocity": (
            model.velocity,
            (torch.randn(2, lat), torch.randn(2, lat), torch.randn(2, c), torch.rand(2), torch.rand(2)),
        ),
        "vae_encoder": (model.vae_encoder, (torch.randn(1, 8 * cfg.frames_per_token, cfg.frame_dim),)),
        "vae_decoder": (model.vae_decoder, (torch.randn(1, 8, lat),)),
    }
    if "vae_encoder_step" in specs:
        states = lambda stack: [torch.randn(s) for s in VaeStep(stack).state_shapes(2)]  # noqa: E731
        fpt = cfg.frames_per_token
        examples["vae_encoder_step"] = (
            EncoderStepGraph(model), (torch.randn(2, fpt, cfg.frame_dim), *states(model.vae_encoder)),
        )
        examples["vae_decoder_step"] = (
            VaeStep(model.vae_decoder), (torch.randn(2, 1, lat), *states(model.vae_decoder)),
        )
    for name, (module, args) in examples.items():
        # Folding would turn the constant `start_token` output into a nameless initializer.
        export_graph(module, args, specs[name], out_dir, fold_constants=name != "conditioning")
    manifest = {
        "format": "troupe-bundle",
        "format_version": FORMAT_VERSION,
        "family": "armflow",
        "name": f"armflow-{preset}",
        "producer": {"tool": "onnx/export.py", "preset": preset, "seed": seed, "opset": OPSET},
        "motion": {"layout": "interhuman262", "frame_dim": cfg.frame_dim, "fps": cfg.fps},
        "latent": {"dim": lat, "scale": cfg.latent_scale, "frames_per_token": cfg.frames_per_token},
        "condition": {"dim": cfg.cond_dim},
        "context": {
            "width": c, "layers": cfg.layers, "heads": h, "head_dim": dh,
            "capacity_tokens": cfg.context_capacity,
        },
        "vae": {
            "streaming": cfg.vae.causal,
            "encoder": {
                "context_frames": encoder_context_frames(model.vae_encoder, cfg.frames_per_token),
                "lookahead_frames": 0,
            },
            "decoder": {
                "context_tokens": decoder_context_tokens(model.vae_decoder, cfg.frames_per_token),
                "lookahead_tokens": 0,
            },
        },
        "sampler": {"steps": 1, "cfg_scale": 1.0, "actor_latent": "sample"},
        "graphs": specs,
    }
    (out_dir / "troupe.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return model


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


def write_golden(model: Armflow, out_dir: Path):
    cfg = model.cfg
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    rng = np.random.default_rng(2)
    frames = GOLDEN_TOKENS * cfg.frames_per_token + 2  # two trailing frames of an unfinished token
    actor = synthetic_actor(frames, cfg.frame_dim)
    np.save(g / "actor.npy", actor)
    cases = {
        "default": dict(steps=1, cfg_scale=1.0, capacity=None,
                        condition=rng.standard_normal(cfg.cond_dim).astype(np.float32)),
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


@torch.no_grad()
def check_windows_match_full_clip(model: Armflow, actor: np.ndarray):
    """The manifest's window sizes must make windowed VAE calls equal one causal pass, and so
    must stepping token by token with explicit state."""
    cfg, fpt = model.cfg, model.cfg.frames_per_token
    ctx_f = encoder_context_frames(model.vae_encoder, fpt)
    ctx_t = decoder_context_tokens(model.vae_decoder, fpt)
    x = torch.from_numpy(actor)[None]
    n = actor.shape[0] // fpt
    full_mean, _ = model.vae_encoder(x[:, : n * fpt])
    lat = torch.randn(1, n, cfg.latent_dim)
    full_frames = model.vae_decoder(lat)
    for j in range(n):
        m, _ = model.vae_encoder(x[:, max(0, j * fpt - ctx_f) : (j + 1) * fpt])
        assert torch.allclose(m[0, -1], full_mean[0, j], atol=1e-5), f"encoder window, token {j}"
        f = model.vae_decoder(lat[:, max(0, j - ctx_t) : j + 1])
        assert torch.allclose(f[0, -fpt:], full_frames[0, j * fpt : (j + 1) * fpt], atol=1e-5), f"decoder window, token {j}"
    if not cfg.vae.causal:
        return
    enc, dec = VaeStep(model.vae_encoder), VaeStep(model.vae_decoder)
    enc_state = [torch.zeros(s) for s in enc.state_shapes()]
    dec_state = [torch.zeros(s) for s in dec.state_shapes()]
    for j in range(n):
        out, *enc_state = enc(x[:, j * fpt : (j + 1) * fpt], *enc_state)
        assert torch.allclose(out[0, 0, : cfg.latent_dim], full_mean[0, j], atol=1e-5), f"encoder step, token {j}"
        f, *dec_state = dec(lat[:, j : j + 1], *dec_state)
        assert torch.allclose(f[0], full_frames[0, j * fpt : (j + 1) * fpt], atol=1e-5), f"decoder step, token {j}"


# --------------------------------------------------------------------------------------------
# Reproducibility check
# --------------------------------------------------------------------------------------------


def compare_bundles(committed: Path, fresh: Path) -> list[str]:
    """Differences between two bundle directories. ONNX files are compared byte-wise, then (as
    a fallback across torch versions) node by node and initializer by initializer; goldens
    within 1e-6."""
    import onnx
    from onnx import numpy_helper

    problems = []
    names = sorted(p.relative_to(fresh).as_posix() for p in fresh.rglob("*") if p.is_file())
    have = sorted(p.relative_to(committed).as_posix() for p in committed.rglob("*") if p.is_file())
    if names != have:
        problems.append(f"file lists differ: committed {have} vs exported {names}")
    for name in set(names) & set(have):
        a, b = committed / name, fresh / name
        if filecmp.cmp(a, b, shallow=False):
            continue
        if name.endswith(".npy"):
            x, y = np.load(a), np.load(b)
            if x.shape != y.shape or not np.allclose(x, y, atol=1e-6, rtol=0):
                problems.append(f"{name}: arrays differ")
        elif name.endswith(".onnx"):
            ma, mb = onnx.load(a), onnx.load(b)
            ops = lambda m: [(n.op_type, list(n.input), list(n.output)) for n in m.graph.node]  # noqa: E731
            inits = lambda m: {i.name: numpy_helper.to_array(i) for i in m.graph.initializer}  # noqa: E731
            ia, ib = inits(ma), inits(mb)
            if ops(ma) != ops(mb):
                problems.append(f"{name}: graph nodes differ")
            elif ia.keys() != ib.keys() or any(not np.array_equal(ia[k], ib[k]) for k in ia):
                problems.append(f"{name}: weights differ")
        else:
            problems.append(f"{name}: contents differ")
    return problems


def cli(doc: str, presets: dict, export_bundle, write_golden):
    """The command line every exporter shares: `--preset P --out DIR [--golden]` writes a
    bundle; `--preset P --check DIR` re-exports into a temporary directory and exits non-zero
    unless it is byte-identical to DIR (goldens included when DIR has them)."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", choices=sorted(presets), required=True)
    ap.add_argument("--out", type=Path, help="bundle directory to write")
    ap.add_argument("--golden", action="store_true", help="also write golden outputs (tiny presets)")
    ap.add_argument("--seed", type=int, default=0, help="weight initialisation seed")
    ap.add_argument("--check", type=Path, help="re-export and compare with this committed bundle")
    args = ap.parse_args()
    torch.set_num_threads(1)
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / "bundle"
            model = export_bundle(args.preset, fresh, args.seed)
            if (args.check / "golden").exists():
                write_golden(model, fresh)
            problems = compare_bundles(args.check, fresh)
        for p in problems:
            print(f"MISMATCH {p}")
        print("reproducible" if not problems else f"{len(problems)} difference(s)")
        sys.exit(1 if problems else 0)
    if not args.out:
        ap.error("--out or --check is required")
    model = export_bundle(args.preset, args.out, args.seed)
    if args.golden:
        write_golden(model, args.out)
    size = sum(f.stat().st_size for f in args.out.rglob("*.onnx"))
    print(f"wrote {args.out} ({size / 1e6:.1f} MB of ONNX)")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    cli(__doc__, PRESETS, export_bundle, write_golden)
