"""UMF's exporter: a model into a troupe bundle (manifest + ONNX graphs [+ golden outputs]).

    python3 onnx/cli.py umf export --preset tiny          --out onnx/bundles/umf-tiny --golden            # committed
    python3 onnx/cli.py umf export --preset tiny-temporal --out onnx/bundles/umf-tiny-temporal --golden   # committed
    python3 onnx/cli.py umf export --preset interhuman    --out onnx/bundles/paper-umf                    # not committed
    python3 onnx/cli.py umf export --preset tiny          --check onnx/bundles/umf-tiny                   # reproducible?

    # the official checkpoint (Githubhgh/UMF_CVPR, the S-Flow stage's, which holds every network)
    # and InterHuman's feature statistics:
    python3 onnx/cli.py umf export --preset interhuman --checkpoint umf.ckpt \
        --mean global_mean.npy --std global_std.npy --out onnx/bundles/umf-interhuman

Our modules (`troupe_onnx.umf.reference`) carry the official module and parameter names, so an
official state dict loads as it is, strictly (`troupe_onnx.shared.checkpoint`). Without
`--checkpoint` the weights, the feature normaliser and the null condition are random (seeded):
such bundles test and benchmark the runtime; they do not generate meaningful motion.
`--write-checkpoint FILE` saves those weights in the official layout, with the normaliser beside
it as `global_mean.npy` / `global_std.npy` (the parity harness's checkpoints). The graph export,
the bundle comparison and the command line are shared with every family's exporter
(`troupe_onnx.shared.export`).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.shared.manifest import write_manifest
from troupe_onnx.shared.checkpoint import CheckpointError, load_checkpoint
from troupe_onnx.shared.clip import CONTEXT, text_encoder_spec, tokenizer_manifest, write_merges, write_prompt_golden
from troupe_onnx.shared.export import FORMAT_VERSION, OPSET, export_graph, exporter_cli
from troupe_onnx.umf.reference import (
    TIME_SCALE,
    Solver,
    Umf,
    UmfConfig,
    block_noise_from_normals,
    generate_group,
    seeded_noise,
    stage_tokens,
)

TOOL = "onnx/cli.py umf export"  # the manifest's `producer.tool`

TINY_MERGES = 1000  # the tiny bundles' tokenizer: the first 1,000 of CLIP's merges
_TINY = dict(
    latent_dim=8, width=32, heads=2, ffn=64, time_dim=32, prior_layers=3, prior_expert_layers=1,
    reaction_layers=3, prior_text_dim=16, reaction_text_dim=16, pe_length=32, clip_layers=1,
    clip_heads=2, clip_merges=TINY_MERGES, text_heads=2, text_ffn=32, context_heads=2, context_ffn=32, vae_width=32,
    vae_layers=3, vae_heads=2, vae_ffn=64, vae_pe_length=64, clip_frames=40,
)

PRESETS = {
    # The official layout at reduced width, the official sampler (grid pyramid, gamma -0.2, RK4
    # 3/8 with 4 intervals, CFG 3): small enough to commit and to test in seconds; every
    # architectural feature (skips, both expert heads, dataset token, text branches, context
    # pooling, cross-attention decoder) is present. The parity bundle of official checkpoints.
    "tiny": UmfConfig(**_TINY),
    # The same widths on a sequence pyramid of three stages with mixed solvers, so that the
    # runtime's general paths (temporal layout, K > 2, Euler, another gamma) are exercised.
    "tiny-temporal": UmfConfig(
        **_TINY, tokens=8, layout="temporal", stages=3, gamma=-0.5,
        prior_solvers=[Solver("euler", 3), Solver("rk4", 2), Solver("rk4", 2)],
        reaction_solver=Solver("euler", 4), cfg_scale=2.0,
    ),
    # `docs/spec/umf.md`: the configuration as released (UmfConfig's defaults): 16 x 64 latents.
    "interhuman": UmfConfig(),
}
PRESETS["paper"] = PRESETS["interhuman"]  # the name the benchmarks use

DATASET_NAMES = {0: "humanml3d", 1: "interhuman"}
MAX_ABS_ERROR = 1e-4  # ONNX Runtime vs torch, per graph

# Tensors of the official checkpoints that inference does not use, and why.
IGNORED = {
    "t2m_textencoder.": "the HumanML3D evaluator's text encoder (metrics only)",
    "t2m_moveencoder.": "the HumanML3D evaluator's movement encoder (metrics only)",
    "t2m_motionencoder.": "the HumanML3D evaluator's motion encoder (metrics only)",
}
# FlowModel holds the network it integrates, so the official state dict repeats each denoiser.
ALIASES = {"flow_scheduler.net.": "indi_denoiser.", "flow_scheduler_org.net.": "reac_denoiser."}


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


def randomise(model: Umf):
    """Seeded random weights that make every parameter matter. Default init leaves norm affines
    at 1/0 and attention biases at 0; spread them, and apply GAINS. The normaliser stands in for
    InterHuman's statistics."""
    with torch.no_grad():
        norms = {f"{m}.{p}" for m, mod in model.named_modules() if isinstance(mod, torch.nn.LayerNorm) for p in ("weight", "bias")}
        for name, p in model.named_parameters():
            if name in norms:
                p.normal_(1.0 if name.endswith("weight") else 0.0, 0.1)
            elif name.endswith(("in_proj_bias", "out_proj.bias")):
                p.normal_(0.0, 0.1)
            for suffix, gain in GAINS.items():
                if name.endswith(suffix):
                    p.mul_(gain)
        model.motion_mean.normal_()
        model.motion_std.uniform_(0.5, 1.5)


def load_normaliser(model: Umf, mean_path: Path, std_path: Path):
    """InterHuman's feature statistics (`global_mean.npy`, `global_std.npy`), which the official
    code reads from the dataset, not from the checkpoint."""
    n = model.cfg.frame_dim
    arrays = []
    for path in (mean_path, std_path):
        try:
            a = np.load(path).astype(np.float32).reshape(-1)
        except Exception as e:  # noqa: BLE001 - numpy raises many types for a bad file
            raise CheckpointError(f"{path}: not a readable .npy array ({e})") from e
        if a.shape != (n,) or not np.isfinite(a).all():
            raise CheckpointError(f"{path}: expected {n} finite floats, got shape {a.shape}")
        arrays.append(torch.from_numpy(a))
    if not (arrays[1] > 0).all():
        raise CheckpointError(f"{std_path}: the standard deviations must be positive")
    model.motion_mean.copy_(arrays[0])
    model.motion_std.copy_(arrays[1])


def configuration(preset: str, checkpoint: Path | None, config_file: Path | None) -> UmfConfig:
    """The preset, with the fields of `config_file` (JSON) replacing its own. UMF's checkpoints
    store no configuration, so a checkpoint exported without a config file takes the preset, and
    the exporter says so."""
    cfg = PRESETS[preset]
    if config_file is None:
        if checkpoint is not None:
            print(f"{checkpoint.name}: UMF checkpoints store no configuration; exporting with preset "
                  f"`{preset}` (pass --config FILE to state the model's own)")
        return cfg
    fields = json.loads(config_file.read_text())
    known = {f.name for f in dataclasses.fields(UmfConfig)}
    unknown = sorted(set(fields) - known)
    if not isinstance(fields, dict) or unknown:
        raise CheckpointError(f"{config_file}: unknown configuration fields {unknown} (known: {sorted(known)})")
    for name in ("prior_solvers", "reaction_solver"):
        if name in fields:
            solvers = [Solver(**s) for s in (fields[name] if name == "prior_solvers" else [fields[name]])]
            fields[name] = solvers if name == "prior_solvers" else solvers[0]
    for name, value in fields.items():
        print(f"{config_file.name}: {name} = {value!r} (the preset has {getattr(cfg, name)!r})")
    return dataclasses.replace(cfg, **fields)


def build_model(
    preset: str, seed: int, checkpoint: Path | None = None, normaliser: tuple[Path, Path] | None = None,
    config_file: Path | None = None,
) -> Umf:
    """The preset's model (with `config_file`'s fields) with seeded random weights, or the
    weights of an official `checkpoint`. The normaliser comes from `normaliser` (mean, std
    files), else it is random with random weights and the identity with a checkpoint. The null
    condition is computed from the weights: the empty prompt through CLIP and the text branches."""
    torch.manual_seed(seed)
    model = Umf(configuration(preset, checkpoint, config_file)).eval()
    if checkpoint is not None:
        load_checkpoint(model, checkpoint, IGNORED, ALIASES)
    else:
        randomise(model)
    if normaliser is not None:
        load_normaliser(model, *normaliser)
    elif checkpoint is not None:
        print("warning: no --mean/--std: the bundle's motion stays in normalised feature units")
    model.refresh_null_condition()
    return model


class GraphModule(torch.nn.Module):
    """One method of Umf (prior_velocity, reaction_velocity, context, decode, text_condition) as
    a module, the unit torch.onnx.export traces."""

    def __init__(self, model: Umf, method: str):
        super().__init__()
        self.model, self.method = model, method

    def forward(self, *args):
        return getattr(self.model, self.method)(*args)


GRAPH_METHODS = {
    "prior": "prior_velocity", "reaction": "reaction_velocity", "context": "context", "decoder": "decode",
    "text_encoder": "clip_features", "text_branch": "text_condition",
}


def graph_specs(cfg: UmfConfig) -> dict:
    """Every graph's file, inputs and outputs as the manifest states them. Symbolic dims: B
    batch, N the stage's tokens, P persons so far, T CLIP tokens."""
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
        # CLIP's text tower: a prompt's token ids -> the features the text branches read.
        "text_encoder": text_encoder_spec(cfg.text_dim),
        # CLIP's token features -> the condition, exactly the official text branches.
        "text_branch": {
            "file": "text_branch.onnx",
            "inputs": [t("clip_tokens", ["B", "T", cfg.text_dim]), {"name": "eot_index", "dtype": "int64", "shape": ["B"]}],
            "outputs": [t("condition", ["B", cfg.condition_dim])],
        },
    }


def example_inputs(cfg: UmfConfig, graph: str, batch: int, tokens: int | None = None):
    """Random inputs of a graph; `tokens` is N (prior), P (context) or T (text_branch)."""
    d, n = cfg.latent_dim, cfg.tokens
    return {
        "prior": lambda: (torch.randn(batch, tokens or n, d), torch.rand(batch), torch.randn(batch, cfg.prior_text_dim)),
        "reaction": lambda: (torch.randn(batch, n, 2 * d), torch.rand(batch), torch.randn(batch, cfg.reaction_text_dim)),
        "context": lambda: (torch.randn(1, tokens or 2, n, d),),
        "text_encoder": lambda: (torch.randint(0, cfg.clip_vocab, (batch, CONTEXT)),),
        "decoder": lambda: (torch.randn(batch, n, d),),
        "text_branch": lambda: (
            torch.randn(batch, tokens or 7, cfg.text_dim), torch.arange(batch, dtype=torch.int64) * 3 % (tokens or 7)
        ),
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
        "text_encoder": [(1, None), (2, None)],
        "text_branch": [(1, CONTEXT), (2, 5)],
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


def export_bundle(
    preset: str, out_dir: Path, seed: int = 0, checkpoint: Path | None = None,
    normaliser: tuple[Path, Path] | None = None, config_file: Path | None = None,
) -> Umf:
    model = build_model(preset, seed, checkpoint, normaliser, config_file)
    cfg = model.cfg
    out_dir.mkdir(parents=True, exist_ok=True)
    specs = graph_specs(cfg)
    torch.manual_seed(seed + 1)  # example inputs: dynamic dims get sizes >= 2 so none is specialised
    for name, spec in specs.items():
        export_graph(GraphModule(model, GRAPH_METHODS[name]), example_inputs(cfg, name, 2), spec, out_dir)
    validate_graphs(model, out_dir, specs)
    write_merges(out_dir, cfg.clip_merges)
    manifest = {
        "format": "troupe-bundle",
        "format_version": FORMAT_VERSION,
        "family": "umf",
        "name": f"umf-{preset}",
        "producer": {
            "tool": TOOL, "preset": preset, "opset": OPSET,
            **({"checkpoint": checkpoint.name} if checkpoint else {"seed": seed}),
            **({"config": config_file.name} if config_file else {}),
            "dataset": DATASET_NAMES[cfg.dataset_label],
        },
        "motion": {"layout": "interhuman262", "frame_dim": cfg.frame_dim, "fps": cfg.fps, "skeleton": "t2m22"},
        "condition": {
            "dim": cfg.condition_dim, "null": [float(v) for v in model.null_condition], "null_source": "empty_prompt",
        },
        "tokenizer": tokenizer_manifest(cfg.clip_merges),
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
    manifest = write_manifest(out_dir, manifest)
    return model


# --------------------------------------------------------------------------------------------
# Golden outputs
# --------------------------------------------------------------------------------------------

PAPER_SOLVERS = ([Solver("euler", 45), Solver("euler", 5)], Solver("euler", 10))  # UMF paper, Table 4


def golden_cases(cfg: UmfConfig) -> dict:
    """name -> (people, cfg_scale, condition, prior solvers, reaction solver, seed or None).
    condition: "normals" (a random vector), "text" (the text branch on random CLIP token
    features, the `text_*` goldens) or None (the null condition)."""
    default = (cfg.prior_solvers, cfg.reaction_solver)
    if cfg.layout == "temporal":
        return {
            "rk4_2p": (2, cfg.cfg_scale, "normals", *default, None),
            "seeded_3p": (3, cfg.cfg_scale, "normals", *default, 7),
        }
    return {
        "rk4_1p": (1, cfg.cfg_scale, "normals", *default, None),
        "rk4_2p": (2, cfg.cfg_scale, "normals", *default, None),
        "text_3p": (3, cfg.cfg_scale, "text", *default, None),
        "rk4_4p": (4, cfg.cfg_scale, "normals", *default, None),
        "euler_paper_2p": (2, 3.0, "normals", *PAPER_SOLVERS, None),
        "null_cfg1_3p": (3, 1.0, None, *default, None),
        "seeded_2p": (2, cfg.cfg_scale, "normals", *default, 7),
    }


def write_golden(model: Umf, out_dir: Path):
    """Per case: the condition and every noise (so a test can inject them) and the expected
    latents and motion. Unseeded cases use independent normals, with the jumps' normals turned
    into block noise as troupe does. Also the text branch: CLIP token features, the end-of-text
    index and the condition they give."""
    cfg = model.cfg
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    rng = np.random.default_rng(2)
    normals = lambda *shape: rng.standard_normal(shape).astype(np.float32)  # noqa: E731
    tokens, d = stage_tokens(cfg), cfg.latent_dim
    text = {"text_clip_tokens": normals(CONTEXT, cfg.text_dim), "text_eot_index": np.array([9], np.int64)}
    with torch.no_grad():
        text["text_condition"] = model.text_condition(
            torch.from_numpy(text["text_clip_tokens"])[None], torch.from_numpy(text["text_eot_index"])
        )[0].numpy()
    for k, v in text.items():
        np.save(g / f"{k}.npy", np.ascontiguousarray(v))
    write_prompt_golden(out_dir, model.clip_features, model.text_condition)
    index = {}
    for name, (people, scale, source, prior, reaction, seed) in golden_cases(cfg).items():
        condition = {"normals": lambda: normals(cfg.condition_dim), "text": lambda: text["text_condition"]}
        condition = condition[source]() if source else None
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
            "people": people, "cfg_scale": scale, "has_condition": source is not None, "condition": source,
            "prior": [s.to_json() for s in prior], "reaction": reaction.to_json(), "seed": seed,
        }
        print(f"  golden {name}: |latents| {np.abs(latents).mean():.3f}, |motion| {np.abs(motion).mean():.3f}")
    (g / "cases.json").write_text(json.dumps(index, indent=2) + "\n")


def write_checkpoint(preset: str, seed: int, path: Path, extras: bool = True):
    """Save the preset's seeded random weights as an official checkpoint: a Lightning-style
    `{"state_dict": ...}` under the official names, with the schedulers' copies of the denoisers
    the official state dict carries (`ALIASES`), and the normaliser beside it as
    `global_mean.npy` / `global_std.npy`. With `extras`, also tensors the official checkpoints
    carry that inference ignores (`IGNORED`), so that the loader meets them."""
    model = build_model(preset, seed)
    state = model.state_dict()
    for alias, target in ALIASES.items():
        state |= {alias + k[len(target) :]: v for k, v in list(state.items()) if k.startswith(target)}
    if extras:
        state |= {
            "t2m_textencoder.input_emb.weight": torch.zeros(4, 3),
            "t2m_motionencoder.out_net.0.bias": torch.zeros(4),
        }
    torch.save({"state_dict": state, "epoch": 0}, path)
    np.save(path.parent / "global_mean.npy", model.motion_mean.numpy())
    np.save(path.parent / "global_std.npy", model.motion_std.numpy())


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py umf export`."""
    exporter_cli(
        __doc__, PRESETS, export_bundle, write_golden, write_checkpoint, normaliser=True, config_file=True,
        argv=argv, prog=prog,
    )
