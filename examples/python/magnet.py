#!/usr/bin/env python3
"""MAGNet from Python: run one of a `magnet` bundle's sampling configurations on a clip of troupe
frames and report the time (the Python binding over libtroupe).

    TROUPE_LIBRARY_PATH=target/release/libtroupe.so PYTHONPATH=bindings/python \\
        python3 examples/python/magnet.py --bundle onnx/bundles/magnet-tiny --config dd100 --samples 1
"""

import argparse
import time
from pathlib import Path

import numpy as np

import troupe


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, default=Path(__file__).resolve().parents[2] / "onnx/bundles/magnet-tiny")
    ap.add_argument("--config", default="dd100")
    ap.add_argument("--frames", type=Path, help="float32 [frames, people, 145] (default: the bundle's golden clip)")
    ap.add_argument("--samples", type=int)
    ap.add_argument("--steps", type=int)
    ap.add_argument("--no-x0-guidance", action="store_true")
    ap.add_argument("--out", type=Path, default=Path("magnet_py.npy"))
    args = ap.parse_args()
    model = troupe.Model(args.bundle)
    print(f"{args.bundle}: {model.magnet.people} people, configurations {', '.join(model.magnet.configs)}")
    frames = np.load(args.frames or args.bundle / "golden" / "frames.npy")
    start = time.perf_counter()
    out = model.magnet.generate(args.config, frames, samples=args.samples, steps=args.steps,
                                x0_guidance=not args.no_x0_guidance)
    seconds = time.perf_counter() - start
    print(f"{args.config} on {len(frames)} frames: {out.shape} in {seconds:.2f} s; finite: {bool(np.isfinite(out).all())}")
    np.save(args.out, out)


if __name__ == "__main__":
    main()
