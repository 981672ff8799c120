"""The rules' partners of the demo's default actor clip: what the demo and the tests measure against.

    python3 onnx/cli.py demo partners      # writes tests/data/mocap/cmu-playground.<rule>.npy

The actor is the committed CMU clip (`tests/data/mocap/cmu-playground-120fps.npy`, metres, z up,
120 fps). troupe streams it at the model's 30 fps (every 4th frame: the resampler's instants fall
on them), so the partners are the rules applied to those frames, written back in the clip's own
world (z up, its floor), float32 `[240, 22, 3]` at 30 fps. Numpy only.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from troupe_onnx.demo import rules, sources
from troupe_onnx.motion import intergen
from troupe_onnx.motion.skeleton import REPO

CLIP = REPO / "tests" / "data" / "mocap" / "cmu-playground-120fps.npy"
STRIDE = 4  # 120 fps -> 30


def partners(clip: np.ndarray) -> dict[str, np.ndarray]:
    """rule -> partner [T, 22, 3] in the clip's z-up world, at 30 fps."""
    z_up = np.asarray(clip, dtype=np.float64)[::STRIDE]
    y_up = sources.y_up(z_up)
    floor = z_up[..., 2].min()  # y_up's y is z_up's z, less its minimum
    out = {}
    for rule in rules.RULES:
        p = rules.partner(y_up, rule, sources.FPS)
        p[..., 1] += floor
        out[rule] = np.einsum("mn,tjn->tjm", intergen.Y_UP_TO_Z_UP, p).astype(np.float32)
    return out


def path(rule: str, directory: Path = CLIP.parent) -> Path:
    return directory / f"cmu-playground.{rule}.npy"


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py demo partners`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out-dir", type=Path, default=CLIP.parent)
    args = ap.parse_args(argv)
    for rule, p in partners(np.load(CLIP)).items():
        np.save(path(rule, args.out_dir), p)
        print(f"wrote {path(rule, args.out_dir)} {list(p.shape)}")
