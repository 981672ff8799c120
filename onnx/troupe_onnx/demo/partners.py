"""The rules' partners of the demo's default actor clip: what the demo and the tests measure against.

    python3 onnx/cli.py demo partners      # writes tests/data/mocap/cmu-playground.<rule>.npy
                                           # and cmu-playground-walk.npy, cmu-playground-walk.mirror.npy

The actor is the committed CMU clip (`tests/data/mocap/cmu-playground-120fps.npy`, metres, z up,
120 fps). troupe streams it at the model's 30 fps (every 4th frame: the resampler's instants fall
on them), so the partners are the rules applied to those frames, written back in the clip's own
world (z up, its floor), float32 `[240, 22, 3]` at 30 fps. Numpy only.

The *walk* is the same clip at 30 fps played `WALK_REPEATS` times, each time moved (not turned)
to start where the last ended, with `WALK_BLEND` frames of cross-fade: an actor that walks 11.5 m
away from where it started, far beyond the floor area the demo model was trained on, for the
recentring test (`tests/demo.rs`); its mirror partner beside it.
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
WALK_REPEATS, WALK_BLEND = 4, 8


def partners(clip: np.ndarray, stride: int = STRIDE) -> dict[str, np.ndarray]:
    """rule -> partner [T, 22, 3] in the clip's z-up world, at 30 fps (`clip` at 30 * stride fps)."""
    z_up = np.asarray(clip, dtype=np.float64)[::stride]
    y_up = sources.y_up(z_up)
    floor = z_up[..., 2].min()  # y_up's y is z_up's z, less its minimum
    out = {}
    for rule in rules.RULES:
        p = rules.partner(y_up, rule, sources.FPS)
        p[..., 1] += floor
        out[rule] = np.einsum("mn,tjn->tjm", intergen.Y_UP_TO_Z_UP, p).astype(np.float32)
    return out


def walk(clip: np.ndarray) -> np.ndarray:
    """The walk of the module's doc from `clip` (120 fps, z up): [T, 22, 3] float32 at 30 fps."""
    z_up = np.asarray(clip, dtype=np.float64)[::STRIDE]
    floor_plane = np.array([1.0, 1.0, 0.0])  # z up: the floor is (x, y)
    out = z_up
    for _ in range(WALK_REPEATS - 1):
        nxt = z_up - z_up[:1, :1] * floor_plane + out[-1:, :1] * floor_plane
        w = np.linspace(0.0, 1.0, WALK_BLEND + 2)[1:-1, None, None]
        out = np.concatenate([out, (1 - w) * out[-1:] + w * nxt[:1], nxt])
    return out.astype(np.float32)


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
    actor = walk(np.load(CLIP))
    for name, p in (("cmu-playground-walk.npy", actor),
                    ("cmu-playground-walk.mirror.npy", partners(actor, stride=1)["mirror"])):
        np.save(args.out_dir / name, p)
        print(f"wrote {args.out_dir / name} {list(p.shape)}")
