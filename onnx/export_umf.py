#!/usr/bin/env python3
"""Export a UMF model into a troupe bundle (manifest + ONNX graphs [+ golden outputs]).

    python onnx/export_umf.py --preset tiny          --out onnx/umf-tiny --golden            # committed
    python onnx/export_umf.py --preset tiny-temporal --out onnx/umf-tiny-temporal --golden   # committed
    python onnx/export_umf.py --preset paper         --out onnx/paper-umf                    # not committed
    python onnx/export_umf.py --preset tiny          --check onnx/umf-tiny                   # reproducible?

The weights, the feature normaliser and the null condition are random (seeded): these bundles
test and benchmark the runtime; they do not generate meaningful motion. The networks and the
reference sampler live in umf_ref.py; the graph export and the bundle comparison are shared with
the ARMFlow exporter (export.py).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from export import FORMAT_VERSION, OPSET, cli, export_graph  # noqa: E402
from umf_ref import (  # noqa: E402
    TIME_SCALE,
    Solver,
    Umf,
    UmfConfig,
    block_noise_from_normals,
    generate_group,
    seeded_noise,
    stage_tokens,
)

_TINY = dict(
    latent_dim=8, width=32, heads=2, ffn=64, time_dim=32, prior_layers=3, prior_expert_layers=1,
    reaction_layers=3, prior_text_dim=16, reaction_text_dim=16, pe_length=32, context_heads=2,
    context_ffn=32, decoder_width=32, decoder_layers=3, decoder_heads=2, decoder_ffn=64,
    decoder_pe_length=64, clip_frames=40,
)

PRESETS = {
    # Small enough to commit and to run the test-suite in seconds; every architectural feature
    # (skips, expert head, dataset token, context pooling, cross-attention decoder) is present.
    "tiny": UmfConfig(**_TINY),
    # The same widths on a sequence pyramid of three stages with mixed solvers, so that the
    # runtime's general paths (temporal layout, K > 2, Euler, another gamma) are exercised.
    "tiny-temporal": UmfConfig(
        **_TINY, tokens=8, layout="temporal", stages=3, gamma=-0.5,
        prior_solvers=[Solver("euler", 3), Solver("rk4", 2), Solver("rk4", 2)],
        reaction_solver=Solver("euler", 4), cfg_scale=2.0,
    ),
    # models.md 2: the official sizes (UmfConfig's defaults).
    "paper": UmfConfig(),
}

DATASET_NAMES = {0: "humanml3d", 1: "interhuman"}
MAX_ABS_ERROR = 1e-4  # ONNX Runtime vs torch, per graph


# --------------------------------------------------------------------------------------------
# Model and graphs
# --------------------------------------------------------------------------------------------


# Weight gains over PyTorch's default init. With default init the velocity barely depends on
# the timestep (the raw t in [0, 1] moves the sinusoidal features little) or on the text (near
# uniform attention averages the two conditioning tokens away among the sample tokens), so
# golden tests would not notice a wrong timestep table or a swapped guidance half. These gains
# make a timestep change of 0.01 or a text change move the velocity by about 1e-3 and 1e-1.
GAINS = {
    "time_embedding.linear_1.weight": 30.0,
    "time_embedding.linear_2.weight": 3.0,
    "emb_proj.1.weight": 3.0,
    # Every attention a little sharper, so tokens read specific others. Not more: at 3x the
    # softmaxes saturate and the sampler amplifies a 1e-6 change of its input ~100-fold (5-fold
    # at 1.5x), which would make parity depend on the runtime's rounding rather than its maths.
    "in_proj_weight": 1.5,
}


def build_model(preset: str, seed: int) -> Umf:
    torch.manual_seed(seed)
    model = Umf(PRESETS[preset]).eval()
    # Default init also leaves norm affines at 1/0 and attention biases at 0; spread them so
    # every parameter matters. The normaliser and the null condition stand in for InterHuman's
    # statistics and the encoded empty prompt.
    with torch.no_grad():
        for name, p in model.named_parameters():
            if "norm" in name:
                p.normal_(1.0 if name.endswith("weight") else 0.0, 0.1)
            elif name.endswith(("in_proj_bias", "out_proj.bias")):
                p.normal_(0.0, 0.1)
            for suffix, gain in GAINS.items():
                if name.endswith(suffix):
                    p.mul_(gain)
        model.motion_mean.normal_()
        model.motion_std.uniform_(0.5, 1.5)
        model.null_condition.normal_()
    return model


class GraphModule(torch.nn.Module):
    """One method of Umf (prior_velocity, reaction_velocity, context, decode) as a module, the
    unit torch.onnx.export traces."""

    def __init__(self, model: Umf, method: str):
        super().__init__()
        self.model, self.method = model, method

    def forward(self, *args):
        return getattr(self.model, self.method)(*args)


GRAPH_METHODS = {"prior": "prior_velocity", "reaction": "reaction_velocity", "context": "context", "decoder": "decode"}


def graph_specs(cfg: UmfConfig) -> dict:
    """Every graph's file, inputs and outputs as the manifest states them. Symbolic dims: B
    batch, N the stage's tokens, P persons so far."""
    t = lambda name, shape: {"name": name, "dtype": "float32", "shape": shape}  # noqa: E731
    d, n = cfg.latent_dim, cfg.tokens
    return {
        "prior": {
            "file": "prior.onnx",
            "inputs": [t("sample", ["B", "N", d]), t("timestep", ["B"]), t("text", ["B", cfg.prior_text_dim])],
            "outputs": [t("velocity", ["B", "N", d])],
        },
        "reaction": {
            "file": "reaction.onnx",
            "inputs": [t("state", ["B", n, 2 * d]), t("timestep", ["B"]), t("text", ["B", cfg.reaction_text_dim])],
            "outputs": [t("velocity", ["B", n, 2 * d])],
        },
        "context": {
            "file": "context.onnx",
            "inputs": [t("latents", [1, "P", n, d])],
            "outputs": [t("context", [1, n, d])],
        },
        "decoder": {
            "file": "decoder.onnx",
            "inputs": [t("latents", ["B", n, d])],
            "outputs": [t("motion", ["B", cfg.clip_frames, cfg.frame_dim])],
        },
    }


def example_inputs(cfg: UmfConfig, graph: str, batch: int, tokens: int | None = None):
    """Random inputs of a graph; `tokens` is N (prior) or P (context)."""
    d, n = cfg.latent_dim, cfg.tokens
    return {
        "prior": lambda: (torch.randn(batch, tokens or n, d), torch.rand(batch), torch.randn(batch, cfg.prior_text_dim)),
        "reaction": lambda: (torch.randn(batch, n, 2 * d), torch.rand(batch), torch.randn(batch, cfg.reaction_text_dim)),
        "context": lambda: (torch.randn(1, tokens or 2, n, d),),
        "decoder": lambda: (torch.randn(batch, n, d),),
    }[graph]()


def validate_graphs(model: Umf, out_dir: Path, specs: dict):
    """ONNX Runtime against torch on random inputs at several sizes of every dynamic dim."""
    import onnxruntime as ort

    cfg = model.cfg
    sizes = {
        "prior": [(b, n) for n in stage_tokens(cfg) for b in (1, 2)],
        "reaction": [(1, None), (2, None)],
        "context": [(1, 1), (1, 3)],
        "decoder": [(1, None), (2, None)],
    }
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    for name, spec in specs.items():
        session = ort.InferenceSession(str(out_dir / spec["file"]), opts, providers=["CPUExecutionProvider"])
        module = GraphModule(model, GRAPH_METHODS[name])
        figures = []
        for batch, tokens in sizes[name]:
            args = example_inputs(cfg, name, batch, tokens)
            with torch.no_grad():
                want = module(*args).numpy()
            feed = {x["name"]: a.numpy() for x, a in zip(spec["inputs"], args)}
            got = session.run(None, feed)[0]
            assert got.shape == want.shape, f"{name}: shape {got.shape} vs {want.shape}"
            err = float(np.abs(got - want).max())
            figures.append(f"{list(args[0].shape)}: {err:.2e} (|out| {np.abs(want).mean():.2f})")
            assert err < MAX_ABS_ERROR, f"{name} {list(args[0].shape)}: ONNX Runtime differs from torch by {err}"
        print(f"  {name:8s} onnxruntime vs torch, max |diff| per input shape: " + "; ".join(figures))


def export_bundle(preset: str, out_dir: Path, seed: int = 0) -> Umf:
    cfg = PRESETS[preset]
    model = build_model(preset, seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    specs = graph_specs(cfg)
    torch.manual_seed(seed + 1)  # example inputs: dynamic dims get sizes >= 2 so none is specialised
    for name, spec in specs.items():
        export_graph(GraphModule(model, GRAPH_METHODS[name]), example_inputs(cfg, name, 2), spec, out_dir)
    validate_graphs(model, out_dir, specs)
    manifest = {
        "format": "troupe-bundle",
        "format_version": FORMAT_VERSION,
        "family": "umf",
        "name": f"umf-{preset}",
        "producer": {
            "tool": "onnx/export_umf.py", "preset": preset, "seed": seed, "opset": OPSET,
            "dataset": DATASET_NAMES[cfg.dataset_label],
        },
        "motion": {"layout": "interhuman262", "frame_dim": cfg.frame_dim, "fps": cfg.fps},
        "condition": {"dim": cfg.condition_dim, "null": [float(v) for v in model.null_condition]},
        "latent": {"tokens": cfg.tokens, "dim": cfg.latent_dim},
        "clip_frames": cfg.clip_frames,
        "text": {"prior_dim": cfg.prior_text_dim, "reaction_dim": cfg.reaction_text_dim},
        "pyramid": {
            "layout": cfg.layout,
            "gamma": cfg.gamma,
            "time_scale": TIME_SCALE,
            "stages": [
                {"tokens": s.tokens, "start_t": s.start_t, "end_t": s.end_t, "timesteps": list(s.timesteps)}
                for s in model.stages
            ],
        },
        "sampler": {
            "prior": [s.to_json() for s in cfg.prior_solvers],
            "reaction": cfg.reaction_solver.to_json(),
            "cfg_scale": cfg.cfg_scale,
        },
        "graphs": specs,
    }
    (out_dir / "troupe.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return model


# --------------------------------------------------------------------------------------------
# Golden outputs
# --------------------------------------------------------------------------------------------

PAPER_SOLVERS = ([Solver("euler", 45), Solver("euler", 5)], Solver("euler", 10))  # UMF paper, Table 4


def golden_cases(cfg: UmfConfig) -> dict:
    """name -> (people, cfg_scale, has_condition, prior solvers, reaction solver, seed or None)."""
    default = (cfg.prior_solvers, cfg.reaction_solver)
    if cfg.layout == "temporal":
        return {
            "rk4_2p": (2, cfg.cfg_scale, True, *default, None),
            "seeded_3p": (3, cfg.cfg_scale, True, *default, 7),
        }
    return {
        "rk4_1p": (1, cfg.cfg_scale, True, *default, None),
        "rk4_2p": (2, cfg.cfg_scale, True, *default, None),
        "rk4_4p": (4, cfg.cfg_scale, True, *default, None),
        "euler_paper_2p": (2, 3.0, True, *PAPER_SOLVERS, None),
        "null_cfg1_3p": (3, 1.0, False, *default, None),
        "seeded_2p": (2, cfg.cfg_scale, True, *default, 7),
    }


def write_golden(model: Umf, out_dir: Path):
    """Per case: the condition and every noise (so a test can inject them) and the expected
    latents and motion. Unseeded cases use independent normals, with the jumps' normals turned
    into block noise as troupe does."""
    cfg = model.cfg
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    rng = np.random.default_rng(2)
    normals = lambda *shape: rng.standard_normal(shape).astype(np.float32)  # noqa: E731
    tokens, d = stage_tokens(cfg), cfg.latent_dim
    index = {}
    for name, (people, scale, has_condition, prior, reaction, seed) in golden_cases(cfg).items():
        condition = normals(cfg.condition_dim) if has_condition else None
        if seed is None:
            prior_noise = normals(tokens[0], d)
            jumps = [block_noise_from_normals(normals(n * d), cfg.layout, n, d, cfg.gamma) for n in tokens[1:]]
            reactions = [normals(cfg.tokens, d) for _ in range(people - 1)]
        else:
            prior_noise, jumps, reactions = seeded_noise(cfg, seed, people)
        latents, motion = generate_group(model, condition, people, prior, reaction, scale, prior_noise, jumps, reactions)
        arrays = {"prior_noise": prior_noise, **{f"jump{s}": j for s, j in enumerate(jumps, start=1)}}
        if condition is not None:
            arrays["condition"] = condition
        if reactions:
            arrays["reaction_noise"] = np.stack(reactions)
        for k, v in {**arrays, "latents": latents, "motion": motion}.items():
            np.save(g / f"{name}_{k}.npy", np.ascontiguousarray(v, dtype=np.float32))
        index[name] = {
            "people": people, "cfg_scale": scale, "has_condition": has_condition,
            "prior": [s.to_json() for s in prior], "reaction": reaction.to_json(), "seed": seed,
        }
        print(f"  golden {name}: |latents| {np.abs(latents).mean():.3f}, |motion| {np.abs(motion).mean():.3f}")
    (g / "cases.json").write_text(json.dumps(index, indent=2) + "\n")


if __name__ == "__main__":
    cli(__doc__, PRESETS, export_bundle, write_golden)
