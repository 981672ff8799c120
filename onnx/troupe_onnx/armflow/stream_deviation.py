"""How far ARMFlow's stream mode is from the official clip loop, by VAE window size.

    python3 onnx/cli.py armflow stream-deviation --preset interhuman [--checkpoint armflow.ckpt] [--json F]

The official VAE is not causal: every token depends on the whole padded clip (GroupNorm over
time, dilated convolutions reaching hundreds of frames). A stream cannot wait for the clip, so
stream mode encodes each actor token from a window of `context_frames` before it and
`lookahead_frames` after it, and decodes each reactor token from `context_tokens` before it and
`lookahead_tokens` after it (the bundle's `vae` section). The stream also runs the context
encoder causally with a key/value cache, where the official loop re-runs the unmasked prefix.

This tool runs both loops of the PyTorch reference (`troupe_onnx.armflow.reference`; troupe
equals it within 1e-4, `tests/official.rs`) on one 300-frame actor clip with the same draws: the
same posterior noise per token and the official single noise token for every token. It reports
the reactor features' error per token (max-abs, and the mean over tokens of the per-token
mean-abs error) for a range of windows, and the latency each window costs. Without
`--checkpoint` the weights are random, which says how the windows behave, not what a trained
model's error is.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.armflow.export import OFFICIAL_WINDOWS, build_model, synthetic_actor
from troupe_onnx.armflow.reference import StreamOptions, VaeWindows, clip_reference, clip_tokens, stream_reference

SWEEP = [  # context_frames, lookahead_frames, context_tokens, lookahead_tokens
    VaeWindows(16, 0, 4, 0),
    VaeWindows(32, 4, 8, 1),
    VaeWindows(64, 8, 12, 1),
    OFFICIAL_WINDOWS,
    VaeWindows(160, 32, 32, 4),
    VaeWindows(224, 64, 48, 8),
    VaeWindows(300, 128, 75, 16),  # all of the past, a long lookahead
]


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py armflow stream-deviation`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="interhuman", choices=["interhuman", "interx", "tiny-interhuman", "tiny-interx"])
    ap.add_argument("--checkpoint", type=Path)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, help="also write the table here")
    args = ap.parse_args(argv)
    torch.set_num_threads(2)
    model = build_model(args.preset, args.seed, args.checkpoint)
    cfg = model.cfg
    fpt, n, lat = cfg.frames_per_token, clip_tokens(cfg), cfg.latent_dim
    rng = np.random.default_rng(1)
    actor = synthetic_actor(cfg.clip_frames, cfg.frame_dim, seed=5)  # a full clip: no padding
    xi = rng.standard_normal((n, lat)).astype(np.float32)
    eps = rng.standard_normal(lat).astype(np.float32)
    condition = rng.standard_normal(cfg.cond_dim).astype(np.float32)
    clip = clip_reference(model, actor, xi, eps, condition)
    scale = float(np.abs(clip["frames"][: n * fpt]).mean())
    rows = []
    print(f"{args.preset}: {n} tokens, mean |reactor feature| of the clip loop {scale:.3f}")
    print("| encoder context / lookahead (frames) | decoder context / lookahead (tokens) | latency (frames) "
          "| tokens compared | max-abs | mean per token | max-abs latents |")
    print("|---|---|---|---|---|---|---|")
    for w in SWEEP:
        t0 = time.time()
        stream = stream_reference(model, actor, xi, np.repeat(eps[None], n, 0),
                                  StreamOptions(condition=condition, capacity=n + 1), w)
        m = stream["frames"].shape[0] // fpt  # tokens the stream decoded (its lookahead waits)
        err = np.abs(stream["frames"] - clip["frames"][: m * fpt]).reshape(m, fpt, -1)
        lat_err = np.abs(stream["reactor_latents"] - clip["reactor_latents"][: stream["reactor_latents"].shape[0]])
        row = {
            "context_frames": w.context_frames, "lookahead_frames": w.lookahead_frames,
            "context_tokens": w.context_tokens, "lookahead_tokens": w.lookahead_tokens,
            "latency_frames": fpt - 1 + w.lookahead_frames + fpt * w.lookahead_tokens,
            "tokens": m, "max_abs": float(err.max()), "mean_per_token": float(err.mean(axis=(1, 2)).mean()),
            "max_abs_latents": float(lat_err.max()), "seconds": time.time() - t0,
        }
        rows.append(row)
        print(f"| {w.context_frames} / {w.lookahead_frames} | {w.context_tokens} / {w.lookahead_tokens} "
              f"| {row['latency_frames']} | {m} | {row['max_abs']:.3g} | {row['mean_per_token']:.3g} "
              f"| {row['max_abs_latents']:.3g} |", flush=True)
    # The part no window removes: the clip loop itself with the causal context of stream mode.
    causal = clip_reference(model, actor, xi, eps, condition, causal_context=True)
    err = np.abs(causal["frames"] - clip["frames"])[: n * fpt].reshape(n, fpt, -1)
    lat_err = np.abs(causal["reactor_latents"] - clip["reactor_latents"])
    rows.append({"context_only": True, "tokens": n, "max_abs": float(err.max()),
                 "mean_per_token": float(err.mean(axis=(1, 2)).mean()), "max_abs_latents": float(lat_err.max())})
    print(f"| whole clip (clip-mode VAE) | whole clip | - | {n} | {rows[-1]['max_abs']:.3g} "
          f"| {rows[-1]['mean_per_token']:.3g} | {rows[-1]['max_abs_latents']:.3g} |  (causal context alone)")
    if args.json:
        args.json.write_text(json.dumps({"preset": args.preset, "checkpoint": str(args.checkpoint),
                                         "clip_feature_scale": scale, "rows": rows}, indent=2) + "\n")
