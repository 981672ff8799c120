"""The t2m-22 skeleton as data, read from the runtime's own document.

`src/motion/skeletons/t2m22.json` is the one place its names, parents, rest offsets and branch
frames are written down (the Rust runtime embeds the same file); this module only reads it.
Axes are troupe's canonical ones: metres, +Y up, the rest pose facing +Z, +X the body's left.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[3]
T2M22_JSON = REPO / "src" / "motion" / "skeletons" / "t2m22.json"


@dataclass(frozen=True)
class BranchFrame:
    """How a joint with several children is oriented: x from the right child to the left one,
    y toward the up child (made perpendicular to x)."""

    left: int
    right: int
    up: int


@dataclass(frozen=True, eq=False)
class Skeleton:
    name: str
    names: tuple[str, ...]
    parents: tuple[int, ...]  # -1 for the root; parents come before their children
    offsets: np.ndarray = field(repr=False)  # [J, 3] float64: rest offset from the parent (the root's: its rest position)
    branch_frames: dict[int, BranchFrame] = field(repr=False, default_factory=dict)

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def children(self, joint: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == joint]

    def with_offsets(self, offsets: np.ndarray) -> "Skeleton":
        offsets = np.asarray(offsets, dtype=np.float64)
        assert offsets.shape == self.offsets.shape, f"{offsets.shape}: one offset per joint"
        return Skeleton(self.name, self.names, self.parents, offsets.copy(), dict(self.branch_frames))

    def rest_positions(self) -> np.ndarray:
        out = np.zeros_like(self.offsets)
        for j, p in enumerate(self.parents):
            out[j] = self.offsets[j] + (out[p] if p >= 0 else 0.0)
        return out


def parse(text: str, source: str = "<skeleton>") -> Skeleton:
    """A skeleton from its JSON document, checked as the runtime checks it."""

    def bad(message: str):
        return ValueError(f"{source}: {message}")

    doc = json.loads(text)
    joints = doc.get("joints") or []
    if not joints:
        raise bad("no joints")
    names: list[str] = []
    parents: list[int] = []
    offsets = []
    for j, joint in enumerate(joints):
        name, parent, offset = joint["name"], joint["parent"], joint["offset"]
        if name in names:
            raise bad(f"joint {j}: the name {name!r} is used twice")
        if parent is None:
            if j != 0:
                raise bad(f"joint {j} ({name}): only joint 0 is a root")
            parents.append(-1)
        else:
            if parent not in names:
                raise bad(f"joint {j} ({name}): parent {parent!r} is not a joint before it")
            parents.append(names.index(parent))
        if len(offset) != 3 or not np.all(np.isfinite(offset)):
            raise bad(f"joint {j} ({name}): offset {offset} is not three finite numbers")
        names.append(name)
        offsets.append([float(v) for v in offset])
    if parents[0] != -1:
        raise bad("joint 0 must be the root")
    branch_frames = {}
    for b in doc.get("branch_frames", []):
        j = names.index(b["joint"])
        frame = BranchFrame(names.index(b["across"][0]), names.index(b["across"][1]), names.index(b["up"]))
        for c in (frame.left, frame.right, frame.up):
            if parents[c] != j:
                raise bad(f"branch frame of {names[j]}: {names[c]} is not its child")
        branch_frames[j] = frame
    for j in range(len(names)):
        n_children = parents.count(j)
        if n_children > 1 and j not in branch_frames:
            raise bad(f"{names[j]} has {n_children} children and needs a branch frame")
    return Skeleton(doc["name"], tuple(names), tuple(parents), np.array(offsets, dtype=np.float64), branch_frames)


def load(path: Path = T2M22_JSON) -> Skeleton:
    return parse(Path(path).read_text(), str(path))


@lru_cache(maxsize=1)
def _t2m22() -> Skeleton:
    return load(T2M22_JSON)


def t2m22() -> Skeleton:
    """The built-in t2m-22 skeleton (the neutral body's rest offsets); a fresh copy each call."""
    s = _t2m22()
    return s.with_offsets(s.offsets)


def clip_bone_lengths(positions) -> tuple[np.ndarray, np.ndarray]:
    """A t2m-22 clip `[T, 22, 3]` as float64, checked for shape, and its bone lengths `[T, 21]`
    (joint j's distance from its parent, j = 1..21): what the capture readers' checks measure."""
    clip = np.asarray(positions, dtype=np.float64)
    assert clip.ndim == 3 and clip.shape[1:] == (22, 3), f"positions {clip.shape}: [T, 22, 3] expected"
    parents = t2m22().parents
    return clip, np.linalg.norm(clip[:, 1:] - clip[:, list(parents[1:])], axis=-1)
