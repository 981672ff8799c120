"""InterGen's interhuman262 features of a clip of joint positions (the numpy transcription).

    python3 onnx/cli.py motion features POSITIONS.npy [--stride 4] --out FEATURES.npy

POSITIONS.npy: `[T, 22, 3]` t2m-22 joint positions, metres, z up (InterHuman's raw convention).
`--stride N` keeps every N-th frame from frame 0 (4: CMU's 120 fps to InterHuman's 30) before
processing. Writes `[T' - 1, 262]` float32 features (`troupe_onnx.motion.intergen`).

The committed golden is
`python3 onnx/cli.py motion features tests/data/mocap/cmu-playground-120fps.npy --stride 4
--out tests/data/mocap/cmu-playground.features.npy`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from troupe_onnx.motion import intergen


def features_of(positions: np.ndarray, stride: int = 1) -> np.ndarray:
    """Features of `[T, 22, 3]` z-up metres taken every `stride` frames."""
    features, _, _ = intergen.process_motion(np.asarray(positions)[::stride])
    return features


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py motion features`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("positions", type=Path, help="[T, 22, 3] joint positions .npy, metres, z up")
    ap.add_argument("--stride", type=int, default=1, help="keep every N-th frame from frame 0 (default 1)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    if args.stride < 1:
        sys.exit(f"--stride must be at least 1, got {args.stride}")
    positions = np.load(args.positions)
    try:
        features = features_of(positions, args.stride)
    except ValueError as e:
        sys.exit(f"{args.positions}: {e}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.save(args.out, features)
    contacts = features[:, intergen.SLICES["contacts"]].mean(axis=0)
    print(
        f"wrote {args.out}: {features.shape[0]} frames x {features.shape[1]} from {len(positions)} frames "
        f"(stride {args.stride}); contact rates (l ankle, l foot, r ankle, r foot) "
        + ", ".join(f"{c:.2f}" for c in contacts)
    )
