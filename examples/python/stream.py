#!/usr/bin/env python3
"""The streaming demo through the Python package: feed an actor's joint positions tick by tick,
get the reactor's joint positions back, write them to .npy with a picture beside it (an HTML
player and a GIF of both people), print per-step latency and the real-time factor.

    pip install ./bindings/python      # or: PYTHONPATH=bindings/python TROUPE_LIBRARY_PATH=target/release
    python examples/python/stream.py [--bundle DIR] [--rule mirror|follow|keep-away]
                                     [--joints FILE.npy|FILE.bvh] [--units m] [--up z]
                                     [--fps 120] [--frames N] [--tick N] [--out FILE.npy]

The default model is troupe's trained demo (onnx/bundles/armflow-demo, docs/DEMO.md) with its
first rule (mirror); the default actor is 8 s of real motion capture it never saw
(tests/data/mocap/cmu-playground-120fps.npy: t2m-22 joints, metres, z up, 120 fps). On that clip
the demo prints how far the reactor is from the rule's partner.
"""

import argparse
import time
from pathlib import Path

import numpy as np

import troupe
from troupe import motion, viewer

REPO = Path(__file__).resolve().parents[2]
DEFAULT_CLIP = REPO / "tests" / "data" / "mocap" / "cmu-playground-120fps.npy"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", default=str(REPO / "onnx" / "bundles" / "armflow-demo"))
    ap.add_argument("--rule", help="a named condition of the bundle (default: its first, if any)")
    ap.add_argument("--joints", default=str(DEFAULT_CLIP), help="float32 [T, 22, 3] .npy or a .bvh file")
    ap.add_argument("--units", default="m", choices=["m", "cm", "mm", "in"], help="units of a .npy")
    ap.add_argument("--up", default="z", choices=["y", "z"], help="up axis of a .npy")
    ap.add_argument("--fps", type=float, default=120.0, help="frame rate of a .npy")
    ap.add_argument("--frames", type=int, default=0, help="at most this many actor frames (0: all)")
    ap.add_argument("--tick", type=int, default=1)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", default="reactor_py.npy")
    args = ap.parse_args()

    if args.joints.endswith(".bvh"):
        actor, fmt = motion.read_bvh(args.joints)
    else:
        actor, fmt = np.load(args.joints), motion.JointsFormat(args.units, args.up, fps=args.fps)
    if args.frames:
        actor = actor[: args.frames]
    with troupe.Model(args.bundle) as model, model.session(seed=args.seed) as session:
        rule = args.rule or next(iter(model.condition_labels), None)
        if rule:
            session.set_condition(rule)
        session.set_joints_format(fmt)
        reactor, token_ms = [], []
        start = time.perf_counter()
        for i in range(0, len(actor), args.tick):
            t0 = time.perf_counter()
            poses = session.step_joints(actor[i : i + args.tick])
            if len(poses.positions):
                token_ms.append((time.perf_counter() - t0) * 1e3)
                reactor.append(poses.positions)
        total = time.perf_counter() - start
        model_fps = model.fps
    reactor = np.concatenate(reactor) if reactor else np.zeros((0, 22, 3), np.float32)
    out = Path(args.out)
    np.save(out, reactor)
    print(f"troupe {troupe.version()}: {len(actor)} actor frames ({fmt.fps:g} fps) in ticks of {args.tick}, "
          f"{len(reactor)} reactor frames -> {out}")
    truth_path = DEFAULT_CLIP.with_name(f"cmu-playground.{rule}.npy")
    if rule and Path(args.joints) == DEFAULT_CLIP and truth_path.exists() and len(reactor):
        truth = np.load(truth_path)[: len(reactor)]
        error = 100 * np.linalg.norm(reactor[: len(truth)] - truth, axis=-1).mean()
        print(f"the {rule} rule's partner vs the reactor: {error:.1f} cm mean per-joint error")
    if len(reactor):
        # The picture plays both people at the bundle's rate.
        stride = max(1, round(fmt.fps / model_fps))
        shown = actor[::stride][: len(reactor)]
        view = motion.JointsFormat(fmt.units, fmt.up, fmt.handedness, fps=model_fps)
        viewer.write({"actor": shown, "reactor": reactor[: len(shown)]}, html=out.with_suffix(".html"),
                     gif=out.with_suffix(".gif"), fmt=view, title="troupe: Python streaming demo")
        print(f"pictures: {out.with_suffix('.html')} (open it in a browser) and {out.with_suffix('.gif')}")
    ms = np.sort(token_ms)
    if len(ms):
        print(f"step latency (calls that produced a token, {len(ms)}): p50 {np.percentile(ms, 50):.3f} ms  "
              f"p99 {np.percentile(ms, 99):.3f} ms  max {ms[-1]:.3f} ms")
    print(f"real-time factor {len(actor) / fmt.fps / total:.1f}x")


if __name__ == "__main__":
    main()
