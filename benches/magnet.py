#!/usr/bin/env python3
"""MAGNet at released size: troupe (through its Python binding) next to the same loop in PyTorch
eager on the same weights, per task, with the x0 guidance on and off (a benchmark, not a test).

    python3 onnx/cli.py magnet export --preset dd100 --write-checkpoint /tmp/magnet-release
    python3 onnx/cli.py magnet export --preset dd100 \
        --checkpoint /tmp/magnet-release/checkpoints/dfot/magnet_dd100/v0/checkpoints_500000 \
        --out onnx/bundles/magnet-dd100
    cargo build --release --lib
    TROUPE_LIBRARY_PATH=target/release/libtroupe.so python3 benches/magnet.py \
        --bundle onnx/bundles/magnet-dd100 \
        --checkpoint /tmp/magnet-release/checkpoints/dfot/magnet_dd100/v0/checkpoints_500000 \
        --json docs/magnet-dd100.json

Method. A full released run is 200 to 2,900 network calls at 10 samples (about 14 minutes for
DD100's joint task in troupe on this 2-core machine with guidance on), so each runtime's cost per
*iteration* (one denoiser call and DDIM step, with or without the two decoder-gradient graphs)
is measured from whole generations of the joint task over one window at two step counts (the
difference divided by the difference in iterations, which cancels the fixed costs of encoding
and decoding), at the released sample counts. Every task's iterations per generated frame are
exact: its reference sampler is run at its released length with a stub network that counts
calls (`docs/spec/magnet.md` §9; `onnx/tests/test_magnet.py` checks the same counts). The
per-frame cost of a task is its iterations per frame times the cost per iteration at its sample
count; one end-to-end troupe run of DD100's joint task (one sample, guidance off) checks the
prediction against a measurement.

The live partner (`dd100_motion_control`, one sample): every chunk runs its full schedule and
emits Tm - Tc tokens of the partner; the user's frames must reach the chunk's last token before
it starts, so the algorithmic latency is the chunk's span of user frames ahead of the first
generated frame, plus the chunk's compute time.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "onnx"))
sys.path.insert(0, str(ROOT / "bindings" / "python"))


def stub_calls(name: str, cfg, persons: int, window: int) -> tuple[int, int]:
    """(network calls, generated frames) of a released configuration at its released length."""
    from troupe_onnx.magnet import tasks as T
    from troupe_onnx.magnet.schedule import Schedule

    calls = [0]

    def stub(x, k):
        calls[0] += 1
        return np.zeros_like(x)

    class Draws:
        def normal(self, shape):
            return np.zeros(shape, np.float32)

    zero = np.zeros(9, np.float32)
    stats = T.TransformStats(zero, zero + 1, zero, zero + 1)
    cfg = replace(cfg, samples=1, guidance=replace(cfg.guidance, smoothing=None, foot_skating=None),
                  update_history_transforms=False, temporal_smoothing=None)
    run = T.Run(cfg, Schedule.cosine(), stub, Draws(), stats, window, persons, 8, np.zeros((persons, 10), np.float32))
    d = 8 + 36 * persons
    tc = cfg.context_tokens
    if cfg.task in ("joint", "agentic_turn_taking", "agentic_sync"):
        fn = {"joint": T.joint, "agentic_turn_taking": T.agentic_turn_taking, "agentic_sync": T.agentic_sync}[cfg.task]
        out = fn(run, np.zeros((tc, persons, d), np.float32), np.ones((tc, persons), bool))
        return calls[0], (out.shape[1] - tc) * 4
    if cfg.task == "inbetweening":
        keys = np.zeros(window, bool)
        keys[[0, window - 1]] = True
        T.inbetweening(run, np.zeros((window, persons, d), np.float32), keys)
        return calls[0], (window - 2) * 4
    t_gt = {"partner_inpainting": 37, "pp2joint": 100}.get(cfg.task, 50)
    gt = np.zeros((t_gt, persons, d), np.float32)
    if cfg.task == "pp2joint":
        out = T.pp2joint(run, gt, cfg.seq_len)
        return calls[0], (out.shape[1] - tc) * 4
    fn = {"partner_prediction": T.partner_prediction, "motion_control_live": T.motion_control_live,
          "partner_inpainting": T.partner_inpainting}[cfg.task]
    fn(run, gt)
    return calls[0], (t_gt - tc) * 4


def window_config(base: dict, steps: int, samples: int, guidance: bool) -> dict:
    """DD100's joint task over its first window only: `steps` iterations."""
    cfg = dict(base, steps=steps, samples=samples, seq_len=64)
    if not guidance:
        cfg["guidance"] = dict(cfg["guidance"], smoothing=None, foot_skating=None)
    return cfg


def median_seconds(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def per_iteration(run, base: dict, samples: int, guidance: bool, steps: tuple[int, int], repeats: int) -> float:
    """ms per iteration from two step counts (fixed costs cancel)."""
    lo, hi = steps
    t_lo = median_seconds(lambda: run(window_config(base, lo, samples, guidance)), repeats)
    t_hi = median_seconds(lambda: run(window_config(base, hi, samples, guidance)), repeats)
    return (t_hi - t_lo) / (hi - lo) * 1e3


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, required=True)
    ap.add_argument("--checkpoint", type=Path, required=True, help="the released-layout checkpoint the bundle came from")
    ap.add_argument("--steps", default="6,16", help="the two step counts per-iteration costs come from")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--samples", default="1,10", help="sample counts to measure")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)

    import torch

    import troupe
    from troupe_onnx.magnet.checkpoint import load_release
    from troupe_onnx.magnet.configs import RELEASED
    from troupe_onnx.magnet.decoder_gradients import weighted_gradient
    from troupe_onnx.magnet.draws import TorchDraws
    from troupe_onnx.magnet.export import random_frames
    from troupe_onnx.magnet.motion import clip_from_frames, decode_tokens, encode_clip
    from troupe_onnx.magnet.schedule import Schedule
    from troupe_onnx.magnet import tasks as T
    from troupe_onnx.magnet.tasks import Sampling

    torch.set_num_threads(1)
    torch.backends.mha.set_fastpath_enabled(False)
    model = troupe.Model(args.bundle)
    manifest = json.loads((args.bundle / "troupe.json").read_text())
    base = manifest["sampling"]["dd100"]
    persons, window = manifest["model"]["persons"], manifest["model"]["window"]
    frames = random_frames(persons, 256, seed=3)
    steps = tuple(int(s) for s in args.steps.split(","))
    sample_counts = [int(s) for s in args.samples.split(",")]

    ref, stats, _ = load_release(args.checkpoint)
    lat = ref.cfg.vq.d_latent
    clip = clip_from_frames(frames)
    betas = stats.normalize("betas", clip.betas)

    def torch_run(cfg_json: dict):
        cfg = Sampling(**{k: v for k, v in cfg_json.items() if k not in ("guidance", "keyframes")},
                       keyframes=tuple(cfg_json["keyframes"]),
                       guidance=_guidance(cfg_json["guidance"]))

        def denoise(x, k):
            with torch.no_grad():
                kk = torch.from_numpy(np.broadcast_to(k, x.shape[:-1]).astype(np.int64).copy())
                return ref.denoiser(torch.from_numpy(np.ascontiguousarray(x)), kk).numpy()

        run = T.Run(cfg, Schedule.cosine(), denoise, TorchDraws(cfg.seed), stats.transform_stats(), window, persons,
                    lat, betas, weighted_gradient(ref.vqvae.decoder, lat))
        context, mask = encode_clip(ref.vqvae, clip.slice(0, cfg.context_len), stats)
        out = T.joint(run, context, mask)
        decode_tokens(ref.vqvae, out, betas, stats, lat)

    def troupe_run(cfg_json: dict):
        model.magnet.generate(cfg_json, frames)

    # Warm up: optimise every graph (the guidance graphs are optimised on first use).
    troupe_run(window_config(base, 2, 1, True))
    torch_run(window_config(base, 2, 1, True))

    costs = {}
    for samples in sample_counts:
        for guidance in (False, True):
            for name, run in (("troupe", troupe_run), ("torch", torch_run)):
                ms = per_iteration(run, base, samples, guidance, steps, args.repeats)
                costs[(name, samples, guidance)] = ms
                print(f"{name:6s} S={samples:2d} guidance={'on ' if guidance else 'off'}: {ms:8.1f} ms per iteration", flush=True)

    rows = []
    for name, cfg in RELEASED.items():
        if (name == "meta_trio") != (persons == 3):
            continue
        calls, generated = stub_calls(name, cfg, persons, window)
        per_frame = calls / generated
        s = cfg.samples if cfg.samples in sample_counts else sample_counts[-1]
        row = {"config": name, "task": cfg.task, "samples": cfg.samples, "measured_at_samples": s, "calls": calls,
               "frames": generated, "calls_per_frame": per_frame}
        for guidance in (False, True):
            key = "on" if guidance else "off"
            for runtime in ("troupe", "torch"):
                row[f"{runtime}_ms_per_frame_guidance_{key}"] = per_frame * costs[(runtime, s, guidance)]
        rows.append(row)
    print()
    print("| configuration | task | S | calls (released length) | generated frames | calls per frame | troupe ms/frame, guidance off / on | torch eager ms/frame, off / on | torch / troupe, off / on |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['config']} | {r['task']} | {r['samples']} | {r['calls']} | {r['frames']} | {r['calls_per_frame']:.2f} "
              f"| {r['troupe_ms_per_frame_guidance_off']:.0f} / {r['troupe_ms_per_frame_guidance_on']:.0f} "
              f"| {r['torch_ms_per_frame_guidance_off']:.0f} / {r['torch_ms_per_frame_guidance_on']:.0f} "
              f"| {r['torch_ms_per_frame_guidance_off'] / r['troupe_ms_per_frame_guidance_off']:.2f} / "
              f"{r['torch_ms_per_frame_guidance_on'] / r['troupe_ms_per_frame_guidance_on']:.2f} |")

    live = {}
    if "dd100_motion_control" in RELEASED and persons == 2:
        from troupe_onnx.magnet.matrices import level_matrix

        cfg = RELEASED["dd100_motion_control"]
        tc = cfg.context_tokens
        chunk_tokens = window - tc
        # Every chunk runs the whole first-window schedule (g = P, §4.4).
        calls_per_chunk = level_matrix(cfg.schedule, cfg.steps, window, persons, persons, tc).shape[0] - 1
        for guidance in (False, True):
            key = "on" if guidance else "off"
            compute = calls_per_chunk * costs[("troupe", 1, guidance)] / 1e3
            motion = chunk_tokens * 4 / 30.0
            live[key] = {"calls_per_chunk": calls_per_chunk, "frames_per_chunk": chunk_tokens * 4,
                         "compute_s_per_chunk": compute, "real_time_factor": motion / compute,
                         "lookahead_frames": chunk_tokens * 4,
                         "latency_s": chunk_tokens * 4 / 30.0 + compute}
            print(f"live partner, guidance {key}: {calls_per_chunk} calls per chunk of {chunk_tokens * 4} frames, "
                  f"{compute:.2f} s compute, real-time factor {motion / compute:.3f}, "
                  f"latency {chunk_tokens * 4} frames of look-ahead + {compute:.2f} s")

    # One end-to-end check of the prediction: DD100 joint, one sample, guidance off.
    joint = next(r for r in rows if r["config"] == "dd100")
    start = time.perf_counter()
    model.magnet.generate("dd100", frames, samples=1, x0_guidance=False)
    measured = (time.perf_counter() - start) * 1e3 / joint["frames"]
    predicted = joint["calls_per_frame"] * costs[("troupe", 1, False)]
    print(f"\nend to end, dd100 at S = 1, guidance off: {measured:.1f} ms per generated frame "
          f"(predicted {predicted:.1f} from the per-iteration cost)")
    if args.json:
        args.json.write_text(json.dumps({
            "bundle": str(args.bundle), "steps": steps, "repeats": args.repeats,
            "per_iteration_ms": {f"{k[0]}_S{k[1]}_guidance_{'on' if k[2] else 'off'}": v for k, v in costs.items()},
            "tasks": rows, "live_partner": live,
            "end_to_end": {"config": "dd100", "samples": 1, "guidance": False, "measured_ms_per_frame": measured,
                           "predicted_ms_per_frame": predicted},
        }, indent=2) + "\n")


def _guidance(g: dict):
    from troupe_onnx.magnet.guidance import GuidanceConfig, X0Guidance

    x0 = lambda v: None if v is None else X0Guidance(**v)  # noqa: E731
    return GuidanceConfig(scales=tuple(tuple(s) for s in g["scales"]), subset_ratio=g["subset_ratio"],
                          partial_level=g["partial_level"], smoothing=x0(g["smoothing"]), foot_skating=x0(g["foot_skating"]))


if __name__ == "__main__":
    main()
