"""The models and the clip that come with troupe: the trained demo model and the motion-capture
clip its demo streams, so that a wheel streams motion with nothing else present.

    import troupe
    from troupe import bundles, motion
    with troupe.Model(bundles.demo()) as model, model.session(condition="mirror") as session:
        session.set_joints_format(motion.JointsFormat(units="m", up="z", fps=120))
        partner = session.step_joints(bundles.demo_clip()).positions   # [T, 22, 3]

In a wheel they lie inside the package (`troupe/data/`); used from a checkout of the repository,
they are the repository's own (`onnx/bundles/armflow-demo`, `tests/data/mocap/`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["demo", "demo_clip", "path"]

_HERE = Path(__file__).resolve().parent
_REPO = _HERE.parents[2] if len(_HERE.parents) > 2 else _HERE
_CLIP = "cmu-playground-120fps.npy"


def _found(packaged: Path, in_repo: Path, what: str) -> Path:
    for p in (packaged, in_repo):
        if p.exists():
            return p
    raise FileNotFoundError(f"{what} is neither in the package ({packaged}) nor in a checkout ({in_repo})")


def path(name: str) -> Path:
    """The folder of a bundle that comes with troupe (today: "armflow-demo")."""
    if not isinstance(name, str) or "/" in name or "\\" in name or name.startswith("."):
        raise ValueError(f"a bundle name is a plain folder name, got {name!r}")
    return _found(_HERE / "data" / "bundles" / name, _REPO / "onnx" / "bundles" / name, f"bundle {name!r}")


def demo() -> Path:
    """The trained demo model (ARMFlow, 2.1 M parameters): a partner that answers an actor under
    the rules `mirror`, `follow` and `keep-away` (its condition labels)."""
    return path("armflow-demo")


def demo_clip() -> np.ndarray:
    """8 s of real motion capture (CMU Graphics Lab, "playground"): float32 [960, 22, 3] t2m-22
    joint positions in metres, z up, 120 fps. The data used here was obtained from
    mocap.cs.cmu.edu; the database was created with funding from NSF EIA-0196217."""
    return np.load(_found(_HERE / "data" / _CLIP, _REPO / "tests" / "data" / "mocap" / _CLIP, "the demo clip"))
