#!/usr/bin/env python3
"""Bodies passing through each other, with and without troupe's guards (a benchmark, not a
test): intersection frequency and depth (`motion.penetration_metrics`), how far the guarded
motion moves from the unguarded, and the cost.

    cargo build --release --lib
    TROUPE_LIBRARY_PATH=target/release/libtroupe.so python3 benches/penetration.py --json docs/penetration.json

- **ARMFlow streams, the penetration guard**: the trained demo model (`onnx/bundles/armflow-demo`)
  answering the real capture `tests/data/mocap/cmu-playground.features.npy` under each of its
  rules, seed 7, with the guard off and on (its defaults, and a sweep of its two settings). The
  cost per token is the median over 5 streams of the whole clip's step time divided by its
  tokens.
- **ARFlow, physical guidance**: the committed tiny bundles (random weights: no trained ARFlow
  exists) on their golden actor (a synthetic walk), λ = 0 against the default λ = 2, seed 3; the
  cost per frame is the median over 5 generations.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bindings" / "python"))


def joints(features: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(features[:, :66].reshape(-1, 22, 3))


def mpjpe_cm(a: np.ndarray, b: np.ndarray) -> float:
    return float(100 * np.linalg.norm(joints(a) - joints(b), axis=-1).mean())


def median_time(fn, runs: int = 5) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def armflow_rows(troupe, motion) -> list[dict]:
    actor = np.load(ROOT / "tests/data/mocap/cmu-playground.features.npy").astype(np.float32)
    rows = []
    with troupe.Model(ROOT / "onnx/bundles/armflow-demo") as demo:
        for rule in ("mirror", "follow", "keep-away"):
            def run(guard):
                s = demo.session(seed=7, condition=rule)
                if guard:
                    s.set_penetration_guard(True, *guard)
                return s.step(actor)

            seconds, free = median_time(lambda: run(None))
            n = len(free)
            a = joints(actor[:n])
            base = motion.penetration_metrics(a, joints(free))
            tokens = n / 4
            rows.append({"model": "armflow-demo", "rule": rule, "guard": "off", "frames": n,
                         **{k: base[k] for k in ("frequency", "depth_sum", "max_depth")},
                         "mpjpe_to_unguarded_cm": 0.0, "ms_per_token": 1e3 * seconds / tokens})
            for guard in ((0.05, 2.0), (0.02, 1.0), (0.05, 5.0)):
                seconds, out = median_time(lambda: run(guard))
                m = motion.penetration_metrics(a, joints(out))
                rows.append({"model": "armflow-demo", "rule": rule,
                             "guard": f"d_safe {guard[0]} m, {guard[1]} m/s" + (" (default)" if guard == (0.05, 2.0) else ""),
                             "frames": n, **{k: m[k] for k in ("frequency", "depth_sum", "max_depth")},
                             "mpjpe_to_unguarded_cm": mpjpe_cm(out, free), "ms_per_token": 1e3 * seconds / tokens})
    return rows


def arflow_rows(troupe, motion) -> list[dict]:
    rows = []
    for name in ("arflow-tiny", "arflow-tiny-online"):
        bundle = ROOT / "onnx/bundles" / name
        actor = np.load(bundle / "golden/actor.npy")
        with troupe.Model(bundle) as model:
            free = None
            for guidance in (0.0, 2.0):
                seconds, out = median_time(lambda: model.arflow.generate(actor, seed=3, guidance=guidance))
                if guidance == 0.0:
                    free = out
                m = motion.penetration_metrics(joints(actor), joints(out))
                rows.append({"model": name, "guidance": guidance, "frames": len(out),
                             **{k: m[k] for k in ("frequency", "depth_sum", "max_depth")},
                             "mpjpe_to_unguided_cm": mpjpe_cm(out, free),
                             "ms_per_frame": 1e3 * seconds / len(out)})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json")
    args = ap.parse_args()
    import troupe
    from troupe import motion

    result = {"armflow_guard": armflow_rows(troupe, motion), "arflow_guidance": arflow_rows(troupe, motion)}
    for section, rows in result.items():
        print(f"\n{section}")
        for r in rows:
            print(json.dumps(r))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
