"""ARFlow's exporter: the network into a troupe bundle (manifest + one ONNX graph [+ goldens]).

    python3 onnx/cli.py arflow export --preset tiny        --out onnx/bundles/arflow-tiny --golden         # committed
    python3 onnx/cli.py arflow export --preset tiny-online --out onnx/bundles/arflow-tiny-online --golden  # committed
    python3 onnx/cli.py arflow export --preset paper       --out onnx/bundles/arflow-paper                 # paper size, random
    python3 onnx/cli.py arflow export --preset tiny        --check onnx/bundles/arflow-tiny                # reproducible?

No official code or weights exist: the bundles carry seeded random weights of the architecture
`networks.py` reconstructs. The graph `denoiser` maps (x [B, T, 262], t [B]) to x̂_1 [B, T, 262]
with B and T symbolic; the online variant (`-online`) masks attention to earlier frames. The
manifest carries the feature normaliser (the flow runs on normalised features; the guidance
reads positions de-normalised) and the sampler's defaults (`sampler.py`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.shared.manifest import write_manifest
from troupe_onnx.arflow.networks import Arflow, ArflowConfig, FrameStep, init_random
from troupe_onnx.arflow.sampler import POSITIONS, STREAM_ARFLOW, Sampling, guidance_gradient, sample
from troupe_onnx.motion.skeleton import t2m22
from troupe_onnx.shared.export import FORMAT_VERSION, OPSET, export_graph, exporter_cli
from troupe_onnx.shared.penetration import D_SAFE, penetration_loss

TOOL = "onnx/cli.py arflow export"
MAX_ABS_ERROR = 1e-4
FRAME_DIM = 262

_TINY = dict(width=32, layers=2, heads=2, feedforward=64, max_frames=256)
_PAPER = dict(width=512, layers=8, heads=4, feedforward=1024, max_frames=1024)
PRESETS = {
    "tiny": ArflowConfig(**_TINY),
    "tiny-online": ArflowConfig(causal=True, **_TINY),
    "paper": ArflowConfig(**_PAPER),
    "paper-online": ArflowConfig(causal=True, **_PAPER),
}


def t(name: str, shape: list, dtype: str = "float32") -> dict:
    return {"name": name, "dtype": dtype, "shape": shape}


def graph_specs(cfg: ArflowConfig) -> dict:
    specs = {
        "denoiser": {
            "file": "denoiser.onnx",
            "inputs": [t("x", ["B", "T", cfg.dim]), t("t", ["B"])],
            "outputs": [t("x1", ["B", "T", cfg.dim])],
        }
    }
    if cfg.causal:  # the online variant streams one frame at a time
        cache = ["B", cfg.layers, cfg.heads, "C", cfg.width // cfg.heads]
        one = ["B", cfg.layers, cfg.heads, 1, cfg.width // cfg.heads]
        specs["denoiser_step"] = {
            "file": "denoiser_step.onnx",
            "inputs": [t("x", ["B", 1, cfg.dim]), t("t", ["B"]), t("position", ["B"], "int64"),
                       t("cache_k", cache), t("cache_v", cache), t("cache_mask", ["B", "C"])],
            "outputs": [t("x1", ["B", 1, cfg.dim]), t("k", one), t("v", one)],
        }
    return specs


def step_example(cfg: ArflowConfig, batch: int, cached: int, gen: torch.Generator) -> tuple:
    dh = cfg.width // cfg.heads
    cache = lambda: torch.randn(batch, cfg.layers, cfg.heads, cached, dh, generator=gen)  # noqa: E731
    mask = torch.ones(batch, cached)
    if batch > 1 and cached > 1:
        mask[0, : cached // 2] = 0.0
    return (torch.randn(batch, 1, cfg.dim, generator=gen), torch.rand(batch, generator=gen),
            torch.randint(0, cfg.max_frames, (batch,), generator=gen), cache(), cache(), mask)


def synthetic_clip(frames: int, seed: int) -> np.ndarray:
    """interhuman262-shaped features [frames, 262]: the neutral body's joints walking along +Z
    with small swings (positions, 0..66), smooth signals elsewhere."""
    rng = np.random.default_rng(seed)
    tt = np.arange(frames)[:, None] / 30.0
    rest = t2m22().rest_positions()  # [22, 3]
    swing = 0.03 * np.sin(2 * np.pi * rng.uniform(0.5, 1.5, (1, 22, 3)) * tt[..., None] + rng.uniform(0, 6, (1, 22, 3)))
    pos = rest[None] + swing + np.stack([np.zeros_like(tt), np.zeros_like(tt), 0.8 * tt], -1)
    rest_dims = FRAME_DIM - POSITIONS
    other = rng.uniform(0.2, 1.0, (1, rest_dims)) * np.sin(
        2 * np.pi * rng.uniform(0.2, 2.0, (1, rest_dims)) * tt + rng.uniform(0, 6, (1, rest_dims)))
    return np.concatenate([pos.reshape(frames, POSITIONS), other], axis=1).astype(np.float32)


def normaliser() -> tuple[np.ndarray, np.ndarray]:
    """A fixed normaliser for random bundles: the statistics of a long synthetic clip (stds
    floored at 0.1), so that normalised features are of order one."""
    clip = synthetic_clip(600, seed=11)
    return clip.mean(0).astype(np.float32), np.maximum(clip.std(0), 0.1).astype(np.float32)


def build_model(preset: str, seed: int) -> Arflow:
    model = Arflow(PRESETS[preset])
    init_random(model, seed)
    return model.eval()


def validate(model: Arflow, out_dir: Path) -> float:
    """onnxruntime against torch at two batch sizes and lengths; raises above MAX_ABS_ERROR."""
    import onnxruntime as ort

    sess = ort.InferenceSession(str(out_dir / "denoiser.onnx"), providers=["CPUExecutionProvider"])
    gen = torch.Generator().manual_seed(123)
    err = 0.0
    for batch, frames in ((1, 7), (3, 40)):
        x, tt = torch.randn(batch, frames, model.cfg.dim, generator=gen), torch.rand(batch, generator=gen)
        with torch.no_grad():
            want = model(x, tt).numpy()
        got = sess.run(None, {"x": x.numpy(), "t": tt.numpy()})[0]
        err = max(err, float(np.abs(got - want).max() / max(np.abs(want).max(), 1e-30)))
    if err > MAX_ABS_ERROR:
        raise RuntimeError(f"denoiser: onnxruntime differs from torch by {err:.2e}, above {MAX_ABS_ERROR}")
    return err


def validate_step(model: Arflow, out_dir: Path) -> float:
    """The step graph in onnxruntime, frame by frame with its caches (two streams of different
    lengths in one batch, the shorter padded), against torch's whole causal forward; raises
    above MAX_ABS_ERROR."""
    import onnxruntime as ort

    cfg = model.cfg
    sess = ort.InferenceSession(str(out_dir / "denoiser_step.onnx"), providers=["CPUExecutionProvider"])
    gen = torch.Generator().manual_seed(321)
    frames = (9, 6)
    xs = [torch.randn(1, n, cfg.dim, generator=gen) for n in frames]
    tt = torch.rand(2, generator=gen)
    with torch.no_grad():
        want = [model(x, tt[i : i + 1]).numpy()[0] for i, x in enumerate(xs)]
    dh = cfg.width // cfg.heads
    caches = [[np.zeros((cfg.layers, cfg.heads, 0, dh), np.float32)] * 2 for _ in frames]
    err = 0.0
    for n in range(max(frames)):
        rows = [i for i, f in enumerate(frames) if n < f]
        c = max(1, max(caches[i][0].shape[2] for i in rows))
        batch = {"x": [], "t": [], "position": [], "cache_k": [], "cache_v": [], "cache_mask": []}
        for i in rows:
            have = caches[i][0].shape[2]
            pad = lambda a: np.concatenate([np.zeros((cfg.layers, cfg.heads, c - have, dh), np.float32), a], 2)  # noqa: E731
            batch["x"].append(xs[i][0, n : n + 1].numpy())
            batch["t"].append(tt[i].numpy())
            batch["position"].append(np.int64(n))
            batch["cache_k"].append(pad(caches[i][0]))
            batch["cache_v"].append(pad(caches[i][1]))
            batch["cache_mask"].append(np.concatenate([np.zeros(c - have), np.ones(have)]).astype(np.float32))
        feed = {k: np.stack(v) for k, v in batch.items()}
        x1, k, v = sess.run(None, feed)
        for row, i in enumerate(rows):
            err = max(err, float(np.abs(x1[row, 0] - want[i][n]).max() / np.abs(want[i]).max()))
            caches[i] = [np.concatenate([caches[i][0], k[row]], 2), np.concatenate([caches[i][1], v[row]], 2)]
    if err > MAX_ABS_ERROR:
        raise RuntimeError(f"denoiser_step: differs from the whole causal forward by {err:.2e}")
    return err


def export_bundle(preset: str, out_dir: Path, seed: int = 0):
    model = build_model(preset, seed)
    cfg = model.cfg
    out_dir.mkdir(parents=True, exist_ok=True)
    specs = graph_specs(cfg)
    gen = torch.Generator().manual_seed(seed + 2)
    example = (torch.randn(2, 9, cfg.dim, generator=gen), torch.rand(2, generator=gen))
    export_graph(model, example, specs["denoiser"], out_dir)
    err = validate(model, out_dir)
    errors = {"denoiser": float(f"{err:.3g}")}
    if cfg.causal:
        step = FrameStep(model).eval()
        export_graph(step, step_example(cfg, 2, 3, gen), specs["denoiser_step"], out_dir)
        errors["denoiser_step"] = float(f"{validate_step(model, out_dir):.3g}")
    mean, std = normaliser()
    defaults = Sampling().to_json()
    del defaults["seed"]
    manifest = {
        "format": "troupe-bundle",
        "format_version": FORMAT_VERSION,
        "family": "arflow",
        "name": f"arflow-{preset}",
        "producer": {"tool": TOOL, "preset": preset, "opset": OPSET, "seed": seed,
                     "onnxruntime_max_error": errors},
        "motion": {"layout": "interhuman262", "frame_dim": FRAME_DIM, "fps": 30, "skeleton": "t2m22"},
        "condition": {"dim": 0},
        "model": cfg.to_json(),
        "normalizer": {"mean": [float(v) for v in mean], "std": [float(v) for v in std]},
        "sampler": defaults | {"stream": STREAM_ARFLOW},
        "graphs": specs,
    }
    manifest = write_manifest(out_dir, manifest)
    return model


GOLDEN_CASES = {
    "euler": Sampling(guidance=0.0, weight=1.0, seed=3),
    "guided": Sampling(seed=3),
    "stochastic": Sampling(eta=0.05, squared=True, sigma=0.01, mixing="variance_preserving",
                           guided_backprojection=False, d_safe=0.05, seed=4),
}


def write_golden(model: Arflow, out_dir: Path):
    """An actor clip (`actor.npy`, 40 frames), each case's reactor (`<case>_reactor.npy`) from
    the reference sampler with troupe's seeded draws, and one penetration case: an actor's and a
    reactor's joints with the loss and its autograd gradient."""
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    mean, std = normaliser()
    actor = synthetic_clip(40, seed=5)
    np.save(g / "actor.npy", actor)

    def denoise(x, tt):
        with torch.no_grad():
            return model(torch.from_numpy(x)[None], torch.tensor([tt]))[0].numpy()

    index = {}
    for name, s in GOLDEN_CASES.items():
        reactor = sample(denoise, actor, mean, std, s)
        np.save(g / f"{name}_reactor.npy", reactor)
        index[name] = s.to_json()
        print(f"  golden {name}: reactor {reactor.shape}, |reactor - actor| {np.abs(reactor - actor).mean():.3f}")
    # The penetration loss and its gradient on joints (float64): the actor against a reactor
    # pushed into it.
    a = actor[:, :POSITIONS].astype(np.float64).reshape(-1, 22, 3)
    rng = np.random.default_rng(9)
    r = a + np.array([0.12, 0.0, 0.05]) + rng.normal(0, 0.05, a.shape)
    for squared in (False, True):
        x = torch.tensor(r, requires_grad=True)
        loss = penetration_loss(torch.tensor(a), x, D_SAFE, squared)
        loss.backward()
        tag = "squared" if squared else "linear"
        np.save(g / f"penetration_{tag}_gradient.npy", x.grad.numpy())
        index[f"penetration_{tag}"] = {"loss": float(loss.detach()), "d_safe": D_SAFE, "squared": squared}
    np.save(g / "penetration_reactor.npy", r)
    # The guidance gradient in normalised feature space, as the sampler takes it.
    x1 = ((r.reshape(-1, POSITIONS) - mean[:POSITIONS]) / std[:POSITIONS]).astype(np.float32)
    full = np.zeros((x1.shape[0], FRAME_DIM), np.float32)
    full[:, :POSITIONS] = x1
    np.save(g / "guidance_x1.npy", full)
    np.save(g / "guidance_gradient.npy", guidance_gradient(full, actor, mean, std, D_SAFE, False))
    (g / "cases.json").write_text(json.dumps(index, indent=2) + "\n")


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py arflow export`."""
    exporter_cli(__doc__, PRESETS, export_bundle, write_golden, argv=argv, prog=prog)
