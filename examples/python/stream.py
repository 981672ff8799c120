#!/usr/bin/env python3
"""The streaming demo through the Python package: feed an actor tick by tick, write the reactor
motion to .npy, print per-step latency and the real-time factor.

    pip install ./bindings/python      # or: PYTHONPATH=bindings/python TROUPE_LIBRARY_PATH=target/release
    python examples/python/stream.py [--bundle DIR] [--actor FILE.npy] [--frames N] [--tick N] [--out FILE.npy]
"""

import argparse
import time

import numpy as np

import troupe


def synthetic_actor(frames: int, dim: int) -> np.ndarray:
    t = np.arange(frames)[:, None] / 30.0
    d = np.arange(dim)[None, :]
    return (0.5 * np.sin(2 * np.pi * (0.2 + 0.05 * (d % 37)) * t + d)).astype(np.float32)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", default="onnx/bundles/armflow-tiny")
    ap.add_argument("--actor", help="float32 [T, frame_dim] .npy (default: synthetic)")
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--tick", type=int, default=1)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", default="reactor_py.npy")
    args = ap.parse_args()

    with troupe.Model(args.bundle) as model, model.session(seed=args.seed) as session:
        fps = model.fps
        actor = np.load(args.actor) if args.actor else synthetic_actor(args.frames, model.frame_dim)
        out = np.empty((model.max_output_frames(args.tick), model.frame_dim), np.float32)
        reactor, token_ms = [], []
        start = time.perf_counter()
        for i in range(0, len(actor), args.tick):
            t0 = time.perf_counter()
            frames = session.step(actor[i : i + args.tick], out=out)
            if len(frames):
                token_ms.append((time.perf_counter() - t0) * 1e3)
                reactor.append(frames.copy())
        total = time.perf_counter() - start
    reactor = np.concatenate(reactor) if reactor else np.zeros((0, model.frame_dim), np.float32)
    np.save(args.out, reactor)
    ms = np.sort(token_ms)
    print(f"troupe {troupe.version()}: {len(actor)} actor frames in ticks of {args.tick}, "
          f"{len(reactor)} reactor frames -> {args.out}")
    if len(ms):
        print(f"step latency (calls that produced a token, {len(ms)}): p50 {np.percentile(ms, 50):.3f} ms  "
              f"p99 {np.percentile(ms, 99):.3f} ms  max {ms[-1]:.3f} ms")
    print(f"real-time factor {len(actor) / fps / total:.1f}x")


if __name__ == "__main__":
    main()
