"""MAGNet's exporter: a model into a troupe bundle (manifest + ONNX graphs + codebook [+ goldens]).

    python3 onnx/cli.py magnet export --preset tiny      --out onnx/bundles/magnet-tiny --golden       # committed
    python3 onnx/cli.py magnet export --preset tiny-trio --out onnx/bundles/magnet-tiny-trio --golden  # committed
    python3 onnx/cli.py magnet export --preset dd100     --out onnx/bundles/magnet-dd100             # released size, random
    python3 onnx/cli.py magnet export --preset tiny      --check onnx/bundles/magnet-tiny            # reproducible?

    # a released checkpoint (the DFoT checkpoints_<step> folder; config.yaml, the VQ-VAE and the
    # statistics are found from it as the official code finds them):
    python3 onnx/cli.py magnet export --preset dd100 \
        --checkpoint checkpoints/dfot/magnet_dd100/v0/checkpoints_500000 --out onnx/bundles/magnet-dd100

    # random weights in the released layout (what the loader reads), under a root directory:
    python3 onnx/cli.py magnet export --preset tiny --write-checkpoint /tmp/magnet-release

Graphs (`docs/spec/magnet.md` §2.4): `denoiser` (x, levels -> x0; batch dynamic, the window
and P fixed), `vq_encoder` and `vq_decoder` (batch and length dynamic), and the two x0-guidance
gradients through the decoder in one graph (`guidance`: the weighted sum of both, §6.5 option (a),
written out by hand in `decoder_gradients.py`). The codebook ships as `codebook.f32` (little-endian
float32, `[code_nb, latent]`); the statistics, the schedule tables, the level table of every
released config's step count and every released sampling configuration are in the manifest.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.shared.manifest import write_manifest
from troupe_onnx.magnet.checkpoint import load_release, write_release
from troupe_onnx.magnet.configs import released_for
from troupe_onnx.magnet.decoder_gradients import DecoderVjp, weighted_gradient
from troupe_onnx.magnet.draws import RecordingDraws, SeededDraws
from troupe_onnx.magnet.guidance import GuidanceConfig, X0Guidance
from troupe_onnx.magnet.live import LiveSettings, LiveStream, make_live_run
from troupe_onnx.magnet.motion import (
    FRAME_DIM, FRAME_LAYOUT, Clip, Stats, anchor_frame, clip_from_frames, decode_tokens, encode_clip, frames_from_decoded,
    key_tokens, overwrite_key_frames, world_roots,
)
from troupe_onnx.magnet.transforms import rotation_to_6d, to_9d
from troupe_onnx.magnet.layout import BODY_JOINTS, DECODER_COND_DIM, ENCODER_COND_DIM, FRAMES_PER_TOKEN, POSE_DIM
from troupe_onnx.magnet.networks import Magnet, MagnetConfig, VqConfig, init_random
from troupe_onnx.magnet.schedule import COSINE_S, Schedule, level_table
from troupe_onnx.magnet.tasks import Run, Sampling
from troupe_onnx.magnet import tasks as T
from troupe_onnx.shared.checkpoint import CheckpointError
from troupe_onnx.shared.export import FORMAT_VERSION, OPSET, export_graph, exporter_cli

TOOL = "onnx/cli.py magnet export"
MAX_ABS_ERROR = 1e-4  # onnxruntime against torch, per graph, relative to the output's scale
CODEBOOK_FILE = "codebook.f32"

_TINY = dict(layers=2, heads=2, d_feedforward=64, embed_dim=16, vq=VqConfig(d_latent=32, d_hidden=32, code_nb=64))
PRESETS = {
    # The official layout at reduced width, committed with goldens for every task.
    "tiny": MagnetConfig(persons=2, **_TINY),
    # Three people, the `add` person embedding: the other architecture branch and P = 3.
    "tiny-trio": MagnetConfig(persons=3, person_embedding_mode="add", **_TINY),
    # Released sizes (§5.12, §9): DD100 (P = 2) and the Embody3D trio (P = 3, embedding mode from
    # its config; `concat` as DD100's training YAML until a checkpoint says otherwise).
    "dd100": MagnetConfig(persons=2),
    "trio": MagnetConfig(persons=3),
}


def build_model(preset: str, seed: int, checkpoint: Path | None = None) -> tuple[Magnet, Stats, str]:
    torch.backends.mha.set_fastpath_enabled(False)  # the math path: what the graphs compute
    if checkpoint is not None:
        model, stats, _ = load_release(checkpoint, PRESETS[preset])
        return model, stats, str(checkpoint)
    return init_random(Magnet(PRESETS[preset]), seed).eval(), Stats.random(seed + 1), ""


def t(name: str, shape: list, dtype: str = "float32") -> dict:
    return {"name": name, "dtype": dtype, "shape": shape}


def graph_specs(cfg: MagnetConfig) -> dict:
    """Every graph's file, inputs and outputs. Symbolic dims: B batch, N person-sequences,
    T frames, Z tokens."""
    w, p, d, lat = cfg.window, cfg.persons, cfg.token_dim, cfg.vq.d_latent
    return {
        "denoiser": {
            "file": "denoiser.onnx",
            "inputs": [t("x", ["B", w, p, d]), t("levels", ["B", w, p], "int64")],
            "outputs": [t("x0", ["B", w, p, d])],
        },
        "vq_encoder": {
            "file": "vq_encoder.onnx",
            "inputs": [t("pose", ["N", "T", POSE_DIM]), t("condition", ["N", "T", ENCODER_COND_DIM])],
            "outputs": [t("latents", ["N", "Z", lat])],
        },
        "vq_decoder": {
            "file": "vq_decoder.onnx",
            "inputs": [t("latents", ["N", "Z", lat]), t("condition", ["N", "Z", DECODER_COND_DIM])],
            "outputs": [t("pose", ["N", "T", POSE_DIM])],
        },
        "guidance": {
            "file": "guidance.onnx",
            "inputs": [t("x0", ["N", w, d]), t("betas", ["N", 10]), t("weights", [2])],
            "outputs": [t("latent_gradient", ["N", w, lat])],
        },
    }


class _VqCall(torch.nn.Module):
    """One method of the pose VQ-VAE as a graph (`encode_continuous` or `decode`)."""

    def __init__(self, model: Magnet, method: str):
        super().__init__()
        self.vq, self.method = model.vqvae, method

    def forward(self, tokens, condition):
        return getattr(self.vq, self.method)(tokens, condition)


def graph_modules(model: Magnet) -> dict:
    lat = model.cfg.vq.d_latent
    return {
        "denoiser": model.denoiser,
        "vq_encoder": _VqCall(model, "encode_continuous"),
        "vq_decoder": _VqCall(model, "decode"),
        "guidance": DecoderVjp(model.vqvae.decoder, lat),
    }


def example_inputs(cfg: MagnetConfig, name: str, batch: int, gen: torch.Generator) -> tuple:
    w, p, d, lat = cfg.window, cfg.persons, cfg.token_dim, cfg.vq.d_latent
    r = lambda *s: torch.randn(*s, generator=gen)  # noqa: E731
    if name == "denoiser":
        return (r(batch, w, p, d), torch.randint(-1, cfg.max_t, (batch, w, p), generator=gen))
    if name == "vq_encoder":
        return (r(batch, 8 * FRAMES_PER_TOKEN, POSE_DIM), r(batch, 8 * FRAMES_PER_TOKEN, ENCODER_COND_DIM))
    if name == "vq_decoder":
        return (r(batch, 8, lat), r(batch, 8, DECODER_COND_DIM))
    return (r(batch * p, w, d), r(batch * p, 10), torch.rand(2, generator=gen) * 3)


def validate_graphs(model: Magnet, out_dir: Path, specs: dict, modules: dict | None = None) -> dict:
    """onnxruntime against the graphs' torch modules (`graph_modules(model)` unless `modules`
    are given) on fresh inputs at two batch sizes; raises above MAX_ABS_ERROR relative to the
    output's largest value. Returns the worst error per graph.

    The reference is each module run in float64, not float32: torch's own float32 forward can
    be far from the exact result where onnxruntime is not (a DD100-size checkpoint with the
    official initialisation), and a float32 reference would then refuse a correct export."""
    import copy

    import onnxruntime as ort

    gen = torch.Generator().manual_seed(123)
    worst = {}
    for name, module in (modules or graph_modules(model)).items():
        sess = ort.InferenceSession(str(out_dir / specs[name]["file"]), providers=["CPUExecutionProvider"])
        names = [i["name"] for i in specs[name]["inputs"]]
        exact = copy.deepcopy(module).double()
        err = 0.0
        for batch in (1, 3):
            args = example_inputs(model.cfg, name, batch, gen)
            with torch.no_grad():
                want = exact(*[a.double() if a.is_floating_point() else a for a in args]).numpy()
            got = sess.run(None, {n: a.numpy() for n, a in zip(names, args)})[0]
            err = max(err, float(np.abs(got - want).max() / max(np.abs(want).max(), 1e-30)))
        del exact
        if err > MAX_ABS_ERROR:
            raise RuntimeError(
                f"{name}: onnxruntime differs from torch (float64) by {err:.2e} (relative), above {MAX_ABS_ERROR}")
        worst[name] = err
    return worst


def export_bundle(preset: str, out_dir: Path, seed: int = 0, checkpoint: Path | None = None):
    model, stats, source = build_model(preset, seed, checkpoint)
    cfg = model.cfg
    out_dir.mkdir(parents=True, exist_ok=True)
    specs = graph_specs(cfg)
    gen = torch.Generator().manual_seed(seed + 2)
    for name, module in graph_modules(model).items():
        export_graph(module, example_inputs(cfg, name, 2, gen), specs[name], out_dir)
    errors = validate_graphs(model, out_dir, specs)
    codebook = model.vqvae.quantizer.codebook.numpy().astype("<f4")
    (out_dir / CODEBOOK_FILE).write_bytes(codebook.tobytes())
    sched = Schedule.cosine(cfg.max_t)
    configs = released_for(cfg.persons)
    steps = sorted({c.steps for c in configs.values()})
    manifest = {
        "format": "troupe-bundle",
        "format_version": FORMAT_VERSION,
        "family": "magnet",
        "name": f"magnet-{preset}",
        "producer": {
            "tool": TOOL, "preset": preset, "opset": OPSET,
            **({"checkpoint": Path(source).name} if source else {"seed": seed}),
            "onnxruntime_max_error": {k: float(f"{v:.3g}") for k, v in errors.items()},
        },
        # Per person and frame: betas, the 21 body joints' 6-D rotations, the root in the world
        # (9-D), y up (`motion.py`, FRAME); no condition.
        "motion": {"layout": FRAME_LAYOUT, "frame_dim": FRAME_DIM, "fps": 30, "skeleton": "smplx-body21"},
        "condition": {"dim": 0},
        "model": cfg.to_json() | {"frames_per_token": FRAMES_PER_TOKEN, "body_joints": BODY_JOINTS},
        "codebook": {"file": CODEBOOK_FILE, "dtype": "float32", "shape": list(codebook.shape)},
        "statistics": {"mean": [float(v) for v in stats.mean], "std": [float(v) for v in stats.std]},
        "schedule": {
            "kind": "cosine", "s": COSINE_S, "max_t": cfg.max_t,
            **sched.to_json(),
            "levels": {str(n): [int(v) for v in level_table(n, cfg.max_t)] for n in steps},
        },
        "sampling": {name: c.to_json() for name, c in configs.items()},
        "graphs": specs,
    }
    manifest = write_manifest(out_dir, manifest)
    return model, stats


# --------------------------------------------------------------------------------------------
# Golden outputs (tiny presets)
# --------------------------------------------------------------------------------------------


def random_frames(persons: int, frames: int, seed: int) -> np.ndarray:
    """troupe frames [F, P, 145] of plausible motion: body rotations near identity, each person
    walking a smooth curve a metre or two from the others, turning as it goes."""
    rng = np.random.default_rng(seed)
    out = np.zeros((frames, persons, FRAME_DIM), np.float32)
    out[..., :10] = rng.standard_normal((1, persons, 10)).astype(np.float32)
    angles = np.cumsum(rng.standard_normal((frames, persons, BODY_JOINTS, 3)) * 0.02, axis=0) + rng.standard_normal((1, persons, BODY_JOINTS, 3)) * 0.2
    out[..., 10:136] = rotation_to_6d(rotation_xyz(angles)).reshape(frames, persons, -1)
    t = np.arange(frames)[:, None] / 30.0
    heading = rng.uniform(-np.pi, np.pi, (1, persons)) + 0.3 * np.sin(t * rng.uniform(0.5, 1.5, (1, persons)))
    tilt = rng.standard_normal((frames, persons, 2)) * 0.03
    root = rotation_xyz(np.stack([tilt[..., 0], heading, tilt[..., 1]], -1))
    start = rng.standard_normal((1, persons, 3)) * 1.5
    step = np.stack([np.cos(heading), np.zeros_like(heading), -np.sin(heading)], -1) * 0.03
    pos = start + np.cumsum(step, axis=0)
    pos[..., 1] = 0.9 + 0.02 * np.sin(t * 6.0)
    m = np.zeros((frames, persons, 4, 4), np.float32)
    m[..., :3, :3], m[..., :3, 3], m[..., 3, 3] = root, pos, 1.0
    out[..., 136:145] = to_9d(m)
    return out


def rotation_xyz(angles: np.ndarray) -> np.ndarray:
    """Rotations about x, then y, then z: [..., 3] angles -> [..., 3, 3] (R = Rz Ry Rx)."""
    x, y, z = angles[..., 0], angles[..., 1], angles[..., 2]
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    r = np.zeros(angles.shape[:-1] + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = -sy, cy * sx, cy * cx
    return r.astype(np.float32)


def golden_sampling(task: str) -> Sampling:
    """Each task at golden size: 4 DDIM steps, 2 samples, guidance on (weights as released),
    lengths that give the AR and rolling loops more than one window."""
    guidance = GuidanceConfig(smoothing=X0Guidance(2.0, 0.0, 1.0), foot_skating=X0Guidance(2.0, 0.0, 1.0))
    base = Sampling(task=task.removesuffix("_eta").removesuffix("_off_grid"), steps=4, samples=2, guidance=guidance, seed=5)
    per_task = {
        "joint": dict(subseq_len=4, ar_seq_stride=16, seq_len=96, root_mode="temporal_partner"),
        "joint_eta": dict(subseq_len=2, ar_seq_stride=16, seq_len=96, eta=1.0, root_mode="temporal",
                          guidance=GuidanceConfig(scales=(("clean", 1.5), ("full", -0.5)), smoothing=None, foot_skating=None)),
        "partner_prediction": dict(subseq_len=1, ar_seq_stride=8, seq_len=96),
        "motion_control_live": dict(subseq_len=4, ar_seq_stride=8, seq_len=96, samples=1, root_mode="temporal"),
        "partner_inpainting": dict(schedule="full_sequence", subseq_len=2, ar_seq_stride=32, seq_len=96),
        "inbetweening": dict(subseq_len=2, ar_seq_stride=4, seq_len=64, samples=1, keyframes=(0, 60), root_mode="temporal"),
        "inbetweening_off_grid": dict(subseq_len=2, ar_seq_stride=4, seq_len=64, samples=2, keyframes=(0, 63),
                                      root_mode="temporal"),
        "agentic_turn_taking": dict(subseq_len=4, ar_seq_stride=8, seq_len=80, root_mode="temporal"),
        "agentic_sync": dict(subseq_len=4, ar_seq_stride=8, seq_len=80, root_mode="temporal"),
        "pp2joint": dict(subseq_len=1, ar_seq_stride=8, seq_len=64),
    }
    return replace(base, **per_task[task])


def run_task(model: Magnet, stats: Stats, sampling: Sampling, name: str, clip: Clip, draws) -> np.ndarray:
    """The reference run of one task on `clip`, its tokens prepared as §5.0 prepares them: the
    context frames encoded on their own (joint, turn-taking, sync), the ground-truth span in one
    pass (the rolling tasks, pp2joint), each key frame's 4 frames on their own (in-betweening)."""
    cfg = model.cfg
    lat = cfg.vq.d_latent
    betas = stats.normalize("betas", clip.betas)

    def denoise(x, k):
        with torch.no_grad():
            kk = torch.from_numpy(np.broadcast_to(k, x.shape[:-1]).astype(np.int64).copy())
            return model.denoiser(torch.from_numpy(np.ascontiguousarray(x)), kk).numpy()

    run = Run(sampling, Schedule.cosine(cfg.max_t), denoise, draws, stats.transform_stats(), cfg.window,
              cfg.persons, lat, betas, weighted_gradient(model.vqvae.decoder, lat))
    if sampling.task in ("joint", "agentic_turn_taking", "agentic_sync"):
        context, mask = encode_clip(model.vqvae, clip.slice(0, sampling.context_len), stats)
        fn = {"joint": T.joint, "agentic_turn_taking": T.agentic_turn_taking, "agentic_sync": T.agentic_sync}[sampling.task]
        return fn(run, context, mask)
    if sampling.task == "inbetweening":
        keys, key_mask = key_tokens(model.vqvae, clip, sampling.keyframes, stats, cfg.window, lat)
        return T.inbetweening(run, keys, key_mask)
    span = min(clip.frames, sampling.seq_len) // FRAMES_PER_TOKEN * FRAMES_PER_TOKEN
    gt, _ = encode_clip(model.vqvae, clip.slice(0, span), stats)
    if sampling.task == "pp2joint":
        return T.pp2joint(run, gt, sampling.seq_len)
    return {"partner_prediction": T.partner_prediction, "motion_control_live": T.motion_control_live,
            "partner_inpainting": T.partner_inpainting}[sampling.task](run, gt)


def run_live(model: Magnet, stats: Stats, sampling: Sampling, frames: np.ndarray, early: bool, draws):
    """The live partner stream (`live.py`) over `frames` [F, 2, 145]: the user is person 0, the
    partner's opening frames are person 1's first `context_len`. The user's frames arrive 20 at a
    time (the output does not depend on how they are cut). Returns (partner frames, tokens)."""
    cfg = model.cfg
    lat = cfg.vq.d_latent

    def denoise(x, k):
        with torch.no_grad():
            kk = torch.from_numpy(np.broadcast_to(k, x.shape[:-1]).astype(np.int64).copy())
            return model.denoiser(torch.from_numpy(np.ascontiguousarray(x)), kk).numpy()

    parts = (Schedule.cosine(cfg.max_t), denoise, stats.transform_stats(), cfg.window, cfg.persons, lat,
             weighted_gradient(model.vqvae.decoder, lat))
    stream = LiveStream(
        LiveSettings(sampling, early=early), stats,
        encode=lambda clip: encode_clip(model.vqvae, clip, stats)[0],
        decode=lambda x, betas: decode_tokens(model.vqvae, x, betas, stats, lat),
        make_run=lambda s, d, b: make_live_run(parts, s, d, b),
        draws=draws, partner=frames[: sampling.context_len, 1],
    )
    out = [stream.push(frames[a : a + 20, 0], cfg.window, cfg.persons, lat) for a in range(0, len(frames), 20)]
    return np.concatenate(out), np.array(stream.tokens_out, np.float32)


def write_golden(exported, out_dir: Path):
    """One clip of troupe frames (`frames.npy` [F, P, 145], every person present) and its tokens;
    per task, the sampled tokens and the frames they decode to (each person's root anchored as
    the reference anchors it, §7.2). Draws come from troupe's seeded generator, so the runtime
    regenerates them; `cases.json` holds each task's configuration and number of draws."""
    model, stats = exported
    cfg = model.cfg
    g = out_dir / "golden"
    g.mkdir(exist_ok=True)
    frames = random_frames(cfg.persons, 128, seed=3)
    clip = clip_from_frames(frames)
    tokens, _ = encode_clip(model.vqvae, clip, stats)
    np.save(g / "frames.npy", frames)
    np.save(g / "tokens.npy", tokens)
    tasks = ["joint", "joint_eta"] if cfg.persons != 2 else [
        "joint", "joint_eta", "partner_prediction", "motion_control_live", "partner_inpainting", "inbetweening",
        "inbetweening_off_grid", "agentic_turn_taking", "agentic_sync", "pp2joint"]
    index = {}
    betas = stats.normalize("betas", clip.betas)
    for name in tasks:
        sampling = golden_sampling(name)
        draws = RecordingDraws(SeededDraws(sampling.seed))
        out = run_task(model, stats, sampling, name, clip, draws)
        decoded = decode_tokens(model.vqvae, out, betas, stats, cfg.vq.d_latent)
        if sampling.task == "inbetweening":
            keys, _ = key_tokens(model.vqvae, clip, sampling.keyframes, stats, cfg.window, cfg.vq.d_latent)
            decoded = overwrite_key_frames(model.vqvae, decoded, out, keys, sampling.keyframes, betas, stats,
                                           cfg.vq.d_latent)
        c = anchor_frame(sampling.context_len)
        roots = world_roots(decoded, c, clip.world_canonical[c], clip.world_root)
        result = frames_from_decoded(decoded, roots, clip.betas)
        np.save(g / f"{name}_tokens.npy", np.ascontiguousarray(out, dtype=np.float32))
        np.save(g / f"{name}_frames.npy", np.ascontiguousarray(result, dtype=np.float32))
        index[name] = {"sampling": sampling.to_json(), "draws": draws.count, "tokens_shape": list(out.shape),
                       "anchor_frame": c}
        print(f"  golden {name}: {out.shape}, {draws.count} draws, |tokens| {np.abs(out).mean():.3f}")
    if cfg.persons == 2:
        for name, early in (("live_stream", False), ("live_stream_early", True)):
            sampling = golden_sampling("motion_control_live")
            draws = RecordingDraws(SeededDraws(sampling.seed))
            out_frames, out_tokens = run_live(model, stats, sampling, frames, early, draws)
            np.save(g / f"{name}_tokens.npy", np.ascontiguousarray(out_tokens, dtype=np.float32))
            np.save(g / f"{name}_frames.npy", np.ascontiguousarray(out_frames, dtype=np.float32))
            index[name] = {"sampling": sampling.to_json(), "draws": draws.count, "early": early,
                           "tokens_shape": list(out_tokens.shape), "frames_shape": list(out_frames.shape)}
            print(f"  golden {name}: {out_frames.shape} frames, {draws.count} draws")
    (g / "cases.json").write_text(json.dumps(index, indent=2) + "\n")


def write_checkpoint(preset: str, seed: int, path: Path):
    """The preset's seeded random weights and statistics in the released layout under `path`."""
    model, stats, _ = build_model(preset, seed)
    folder = write_release(model, stats, path, f"magnet_{preset.replace('-', '_')}")
    print(f"DFoT checkpoint folder: {folder}")


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py magnet export`."""
    try:
        exporter_cli(__doc__, PRESETS, export_bundle, write_golden, write_checkpoint, argv=argv, prog=prog)
    except CheckpointError as e:
        raise SystemExit(f"error: {e}") from e

