"""DeepMimic's humanoid clips: t2m-22 joint positions (z-up metres, 30 fps) from the pybullet wheel.

    python3 onnx/cli.py motion deepmimic [--wheel pybullet-3.2.7-....whl] [--out-dir DIR]

The PyPI wheel `pybullet==3.2.7` (zlib licence) ships DeepMimic's motion clips
(`pybullet_data/data/motions/humanoid3d_*.txt`, 15 of them: walk, run, punch, kick, ...) and the
humanoid they drive (`pybullet_data/humanoid/humanoid.urdf`, loaded by
`pybullet_envs/deep_mimic` with `globalScaling=0.25`). Without `--wheel` the wheel is fetched
with `pip download --no-deps --only-binary :all:` for one fixed platform (the motion files are
the same in every wheel). The clips and the URDF are checked against their SHA-256.

A clip is JSON: `"Loop"` (`"wrap"`: DeepMimic plays it as a cycle; `"none"`) and `"Frames"`, 44
numbers a frame: the frame's duration in seconds (0 on the last), the root position (3), then
rotations in DeepMimic's joint order: root, chest, neck,
right hip, right knee, right ankle, right shoulder, right elbow, left hip, left knee, left ankle,
left shoulder, left elbow; a quaternion (w, x, y, z) each, one angle in radians about the joint's
z axis for knees and elbows (the layout `humanoid_pose_interpolator.py` in the wheel reads; the
URDF's joints come in the same order, and the clips' `RightJoints`/`LeftJoints` lists 3..8 and
9..14 agree). Rotations are local to the parent body, the root's is in the world.

Axes: DeepMimic's world and bodies are y up, x forward, z the body's right (the URDF's right hip
is at +z, the foot boxes reach toward +x), metres once the URDF's offsets are scaled by 0.25 (the
pelvis stands 0.85-0.89 m high, the top of the head about 1.6 m). Forward kinematics on the
URDF's joint offsets gives the 15 DeepMimic joints (it agrees with pybullet's own, the URDF
loaded at that scale, to 2e-6 m); the t2m-22 joints are taken from them
(`T2M22_FROM_DEEPMIMIC`), each a fixed point of one body so the t2m-22 bones stay rigid:

- pelvis, hips, knees, ankles, spine2 (the chest joint), neck, shoulders, elbows and wrists are
  DeepMimic's joints of those places;
- spine1 is halfway from the root joint to the chest joint (on the root body); spine3 a quarter
  of the way from the chest joint to the neck joint (on the chest body), which puts the three
  spine joints at 0.26, 0.51 and 0.63 of the pelvis-neck distance (SMPL's: 0.21, 0.48, 0.59);
- the collars are halfway between the neck joint and each shoulder, 0.04 m lower (on the chest
  body; SMPL's collar is about 0.045 m below its shoulder);
- the head is the centre of DeepMimic's head sphere, 0.175 m above the neck joint on the neck
  body (the URDF's neck collision sphere, scaled);
- `left_foot`/`right_foot` (the ball of the foot) are 0.125 m ahead of and 0.035 m below the
  ankle on the ankle body (the URDF's foot box reaches 0.134 m ahead and 0.05 m below).

Resampling to 30 fps: frame i starts at the sum of the durations before it; at each multiple of
1/30 s up to the clip's end the root position and the knee and elbow angles are interpolated
linearly and the quaternions by slerp, then forward kinematics runs on the result. Clips are
written once each, as they are: a wrapping clip's last frame is near its first pose but not on
it (up to 0.28 m apart about the pelvis), and nothing blends the seam. The joints
go from DeepMimic's axes to InterHuman's raw ones (z up: (X, Y, Z) -> (X, -Z, Y), the inverse of
InterGen's `trans_matrix`), float32 `[T, 22, 3]`.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from troupe_onnx.motion import intergen, registry
from troupe_onnx.motion.skeleton import clip_bone_lengths, t2m22

WHEEL = "pybullet==3.2.7"
# The wheel pip fetches: one platform's, fixed so that every machine gets the same file.
WHEEL_PLATFORM = ("--platform", "manylinux2014_x86_64", "--python-version", "3.11", "--implementation", "cp")
MOTIONS = "pybullet_data/data/motions/"
PREFIX = "humanoid3d_"
URDF = "pybullet_data/humanoid/humanoid.urdf"
MEMBERS = {  # path inside the wheel -> SHA-256
    URDF: "4a449f923dcbd242c1c6a3ad15e62047c6cb2fc1d275bf31a339bf60d27a6894",
    MOTIONS + "humanoid3d_backflip.txt": "ffc5e117f69364e239eeedc86d6a30ab854500a375a1c137a405f1b7652905e6",
    MOTIONS + "humanoid3d_cartwheel.txt": "17453459a40ec4ea08346072748ae3c7c384b49e619753e9779637fa8a9f7c49",
    MOTIONS + "humanoid3d_crawl.txt": "104a3b675131a43e7a214e24c0ed631c6a0d814b85c8b66b71ce63b23a5731ae",
    MOTIONS + "humanoid3d_dance_a.txt": "15ef3731f594edc9ed078170f1075815cc164acaca9e35a46db12a31ac64b717",
    MOTIONS + "humanoid3d_dance_b.txt": "b5a9d7a3f2304f6242776d7ff6d19d1f6bcb98d78d68622761c3843b614a92b5",
    MOTIONS + "humanoid3d_getup_facedown.txt": "1bd1a96e9175f65eb66e10f225473b4467bd70c68e283f4006b2ab090e337c0b",
    MOTIONS + "humanoid3d_getup_faceup.txt": "5936c32d51dad9b0cd5e61df681079d160436cdce845c312f200d7a347c4040d",
    MOTIONS + "humanoid3d_jump.txt": "a433557e94b193d8a95530572a0e32f387eb6d9996987b4216efb65444c3c641",
    MOTIONS + "humanoid3d_kick.txt": "177cfb399466309ba7f4a8a987c3b6f6edde1cbe8b2d476e53dc6061ec5d4bac",
    MOTIONS + "humanoid3d_punch.txt": "1ab4b654cecdb4ff3b2a4bf4086e50397bef28435bb59ab3aedd6a6bdc926fde",
    MOTIONS + "humanoid3d_roll.txt": "50d75c2243b2859f8dcae4ad8fa14b59054dd9ee529b4fb52ec14470cd982c55",
    MOTIONS + "humanoid3d_run.txt": "2cbe488023b243e5769299158ce7c78875ec4b701a2ffe6c0beeaf83d16ca87b",
    MOTIONS + "humanoid3d_spin.txt": "9614f10b92e7a8b123990ad5bcfafc65aa4d8fa8ac7f10ade3c3591122d34425",
    MOTIONS + "humanoid3d_spinkick.txt": "60ec9c200d96e0cd71693061f24db0bd8da9eb295daf487f6f60f8dfb324075a",
    MOTIONS + "humanoid3d_walk.txt": "32d082c3599bc40aac50b1afa196ff1e2cf3842bb40f0541ab088845f6328a41",
}
URDF_SCALE = 0.25  # pybullet_envs/deep_mimic loads the URDF with globalScaling=0.25
FPS = 30
UPRIGHT = ("walk", "run", "punch", "kick", "dance_a", "dance_b", "spinkick", "jump")  # head always above the pelvis
LOCOMOTION = ("walk", "run")  # the root travels the way the body faces

# DeepMimic's joints: name -> (parent, kind); the frame's channels come in this order after the root position.
JOINTS = {
    "root": (None, "quat"),
    "chest": ("root", "quat"),
    "neck": ("chest", "quat"),
    "right_hip": ("root", "quat"),
    "right_knee": ("right_hip", "angle"),
    "right_ankle": ("right_knee", "quat"),
    "right_shoulder": ("chest", "quat"),
    "right_elbow": ("right_shoulder", "angle"),
    "right_wrist": ("right_elbow", None),
    "left_hip": ("root", "quat"),
    "left_knee": ("left_hip", "angle"),
    "left_ankle": ("left_knee", "quat"),
    "left_shoulder": ("chest", "quat"),
    "left_elbow": ("left_shoulder", "angle"),
    "left_wrist": ("left_elbow", None),
}
FRAME_WIDTH = 1 + 3 + sum({"quat": 4, "angle": 1, None: 0}[kind] for _, kind in JOINTS.values())  # 44

# t2m-22 joint -> (DeepMimic body it is fixed to, the point in that body's frame as
# ("joint", name): where that joint is, or ("at", xyz): an offset from the body's own joint, metres,
# or ("mix", a, b, t, drop): a + t (b - a) - drop y, a and b joints whose offsets are in this body).
T2M22_FROM_DEEPMIMIC = {
    "pelvis": ("joint", "root"),
    "left_hip": ("joint", "left_hip"),
    "right_hip": ("joint", "right_hip"),
    "spine1": ("mix", "root", "root", "chest", 0.5, 0.0),
    "left_knee": ("joint", "left_knee"),
    "right_knee": ("joint", "right_knee"),
    "spine2": ("joint", "chest"),
    "left_ankle": ("joint", "left_ankle"),
    "right_ankle": ("joint", "right_ankle"),
    "spine3": ("mix", "chest", "chest", "neck", 0.25, 0.0),
    "left_foot": ("at", "left_ankle", (0.125, -0.035, 0.0)),
    "right_foot": ("at", "right_ankle", (0.125, -0.035, 0.0)),
    "neck": ("joint", "neck"),
    "left_collar": ("mix", "chest", "neck", "left_shoulder", 0.5, 0.04),
    "right_collar": ("mix", "chest", "neck", "right_shoulder", 0.5, 0.04),
    "head": ("at", "neck", (0.0, 0.175, 0.0)),
    "left_shoulder": ("joint", "left_shoulder"),
    "right_shoulder": ("joint", "right_shoulder"),
    "left_elbow": ("joint", "left_elbow"),
    "right_elbow": ("joint", "right_elbow"),
    "left_wrist": ("joint", "left_wrist"),
    "right_wrist": ("joint", "right_wrist"),
}

# DeepMimic is y up; InterHuman's raw data z up.
Y_UP_TO_Z_UP = intergen.Y_UP_TO_Z_UP


def fetch_wheel(workdir: Path) -> Path:
    return registry.pip_download(WHEEL, workdir, "pybullet-3.2.7-*.whl", "--only-binary", ":all:", *WHEEL_PLATFORM)


def read_members(wheel: Path) -> dict[str, bytes]:
    """The URDF and the humanoid3d clips of the wheel, checked against their SHA-256."""
    return registry.checked_zip_members(wheel, MEMBERS, lambda n: n.startswith(MOTIONS + PREFIX))


def joint_offsets(urdf: bytes) -> dict[str, np.ndarray]:
    """Each DeepMimic joint's offset from its parent joint in the parent body's frame, metres."""
    root = ET.fromstring(urdf.rstrip(b"\0"))  # the file ends in a NUL byte
    offsets = {"root": np.zeros(3)}
    for joint in root.iter("joint"):
        name, parent = joint.get("name"), joint.find("parent").get("link")
        if name == "root":
            continue
        origin = joint.find("origin")
        assert origin.get("rpy").split() == ["0", "0", "0"], f"{name}: rotated joint frame"
        assert JOINTS[name][0] == parent, f"{name}: parent {parent} in the URDF, {JOINTS[name][0]} expected"
        if JOINTS[name][1] == "angle":
            axis = [float(v) for v in joint.find("axis").get("xyz").split()]
            assert axis == [0.0, 0.0, 1.0], f"{name}: axis {axis}, expected z"
        offsets[name] = np.array([float(v) for v in origin.get("xyz").split()]) * URDF_SCALE
    assert set(offsets) == set(JOINTS), f"URDF joints {sorted(offsets)} are not DeepMimic's"
    return offsets


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices [..., 3, 3] of quaternions (w, x, y, z) [..., 4] (normalised here)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def _z_rotation(angle: np.ndarray) -> np.ndarray:
    c, s, zero, one = np.cos(angle), np.sin(angle), np.zeros_like(angle), np.ones_like(angle)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], -2)


def _slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    q0 = q0 / np.linalg.norm(q0, axis=-1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)  # the short way round
    dot = np.clip(np.abs(dot), -1.0, 1.0)
    theta = np.arccos(dot)
    sin = np.sin(theta)
    small = sin < 1e-6
    w0 = np.where(small, 1 - t, np.sin((1 - t) * theta) / np.where(small, 1.0, sin))
    w1 = np.where(small, t, np.sin(t * theta) / np.where(small, 1.0, sin))
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def split_frames(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(durations [F], root positions [F, 3], channels: joint -> [F, 4] quaternions or [F] angles)."""
    assert frames.ndim == 2 and frames.shape[1] == FRAME_WIDTH, f"frames {frames.shape}: {FRAME_WIDTH} numbers each"
    channels, at = {}, 4
    for name, (_, kind) in JOINTS.items():
        if kind == "quat":
            channels[name], at = frames[:, at : at + 4], at + 4
        elif kind == "angle":
            channels[name], at = frames[:, at], at + 1
    assert at == FRAME_WIDTH
    return frames[:, 0], frames[:, 1:4], channels


def resample(frames: np.ndarray, fps: int = FPS) -> np.ndarray:
    """The clip's frames `[F, 44]` at `fps` (durations set to 1/fps): slerp and linear interpolation."""
    durations, root, channels = split_frames(frames)
    starts = np.concatenate([[0.0], np.cumsum(durations[:-1])])
    assert np.all(np.diff(starts) > 0), "a frame before the last lasts no time"
    end = starts[-1]
    times = np.minimum(np.arange(int(np.floor(end * fps + 1e-2)) + 1) / fps, end)
    seg = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(starts) - 2)
    t = ((times - starts[seg]) / (starts[seg + 1] - starts[seg]))[:, None]
    out = [np.full((len(times), 1), 1.0 / fps), root[seg] + t * (root[seg + 1] - root[seg])]
    for name, (_, kind) in JOINTS.items():
        if kind == "quat":
            out.append(_slerp(channels[name][seg], channels[name][seg + 1], t))
        elif kind == "angle":
            a = channels[name]
            out.append((a[seg] + t[:, 0] * (a[seg + 1] - a[seg]))[:, None])
    return np.concatenate(out, axis=1)


def forward_kinematics(frames: np.ndarray, offsets: dict[str, np.ndarray]):
    """(joint positions: name -> [F, 3], body rotations: name -> [F, 3, 3]) in DeepMimic's world."""
    _, root, channels = split_frames(frames)
    pos, rot = {}, {}
    for name, (parent, kind) in JOINTS.items():
        if kind == "quat":
            local = _quat_to_matrix(channels[name])
        elif kind == "angle":
            local = _z_rotation(channels[name])
        else:
            local = np.broadcast_to(np.eye(3), (len(root), 3, 3))
        if parent is None:
            pos[name], rot[name] = root, local
        else:
            pos[name] = pos[parent] + rot[parent] @ offsets[name]
            rot[name] = rot[parent] @ local
    return pos, rot


def t2m22_positions(frames: np.ndarray, offsets: dict[str, np.ndarray]) -> np.ndarray:
    """t2m-22 joints `[F, 22, 3]` in DeepMimic's axes (y up), metres."""
    pos, rot = forward_kinematics(frames, offsets)
    names = t2m22().names
    out = np.zeros((len(frames), len(names), 3))
    for j, name in enumerate(names):
        how = T2M22_FROM_DEEPMIMIC[name]
        if how[0] == "joint":
            out[:, j] = pos[how[1]]
        elif how[0] == "at":
            out[:, j] = pos[how[1]] + rot[how[1]] @ np.asarray(how[2])
        else:
            _, body, a, b, frac, drop = how
            point = lambda joint: np.zeros(3) if joint == body else offsets[joint]  # noqa: E731
            local = point(a) + frac * (point(b) - point(a)) - np.array([0.0, drop, 0.0])
            out[:, j] = pos[body] + rot[body] @ local
    return out


def load_clip(data: bytes) -> tuple[np.ndarray, str]:
    """A clip file's frames `[F, 44]` and its `Loop` mode."""
    doc = json.loads(data)
    return np.asarray(doc["Frames"], dtype=np.float64), doc.get("Loop", "none")


def original_fps(frames: np.ndarray) -> float:
    return float(1.0 / np.median(frames[:-1, 0]))


def clips(wheel: Path) -> dict[str, np.ndarray]:
    """Every humanoid3d clip of the wheel: name (`walk`, `run`, ...) -> float32 `[T, 22, 3]`,
    t2m-22 joints, metres, z up, 30 fps."""
    members = read_members(Path(wheel))
    offsets = joint_offsets(members[URDF])
    out = {}
    for member, data in members.items():
        if not member.startswith(MOTIONS + PREFIX):
            continue
        frames, _ = load_clip(data)
        y_up = t2m22_positions(resample(frames), offsets)
        out[Path(member).stem[len(PREFIX) :]] = (y_up @ Y_UP_TO_Z_UP.T).astype(np.float32)
    return dict(sorted(out.items()))


def check(positions: np.ndarray, upright: bool = True, locomotion: bool = False, fps: int = FPS) -> list[str]:
    """The checks a clip `[T, 22, 3]` (z-up metres) must pass; returns what they measured.
    `upright`: the head stays above the pelvis throughout (not for rolls, getups, crawling);
    `locomotion`: the root travels the way the body faces (walking, running)."""
    names = t2m22().names
    ix = names.index
    z_up, lengths = clip_bone_lengths(positions)
    spread = np.abs(lengths - lengths[:1]).max()
    assert spread < 1e-3, f"bone lengths vary by {spread * 1e3:.2f} mm over the frames: not rigid"
    head_above = z_up[:, ix("head"), 2] - z_up[:, ix("pelvis"), 2]
    if upright:
        assert head_above.min() > 0.1, f"head only {head_above.min():.3f} m above the pelvis: not upright"
    # Handedness in the body's own frame, every frame: left x up is forward (+X x +Y = +Z in
    # InterGen's canonical frame), the way the toes point.
    left = z_up[:, ix("left_hip")] - z_up[:, ix("right_hip")]
    up = z_up[:, ix("spine3")] - z_up[:, ix("pelvis")]
    toes = (z_up[:, ix("left_foot")] - z_up[:, ix("left_ankle")]) + (z_up[:, ix("right_foot")] - z_up[:, ix("right_ankle")])
    handed = np.mean(np.sum(np.cross(left, up) * toes, axis=-1) > 0)
    # A mirrored body fails it in most frames; lying, rolling and getting up flex the feet far enough
    # against the trunk to fail it in some.
    least = 0.9 if upright else 0.6
    assert handed > least, f"left x up points the toes' way in only {handed:.0%} of frames: mirrored"
    shoulders = np.mean(np.sum((z_up[:, ix("left_shoulder")] - z_up[:, ix("right_shoulder")]) * left, axis=-1) > 0)
    assert shoulders == 1.0, "the left shoulder is not always on the left hip's side"
    canonical, _, _, _ = intergen.canonicalise(z_up)
    lh, rh = canonical[0, ix("left_hip")], canonical[0, ix("right_hip")]
    assert lh[0] > 0 > rh[0], f"after canonicalisation left hip {lh}, right hip {rh}: left should be +x"
    lf, la = canonical[0, ix("left_foot")], canonical[0, ix("left_ankle")]  # reported: a stride's back foot may point back
    # Left and right limbs in the body's own frame, all frames.
    across = canonical[:, ix("left_hip")] - canonical[:, ix("right_hip")]
    side = lambda a, b: np.sum((canonical[:, ix(a)] - canonical[:, ix(b)]) * across, axis=-1)  # noqa: E731
    limbs = {j: np.mean(side(f"left_{j}", f"right_{j}") > 0) for j in ("wrist", "elbow", "knee", "foot")}
    facing = np.cross(across, [0.0, 1.0, 0.0])  # up x (right - left)
    lag = max(1, round(0.1 * fps))
    step = canonical[lag:, 0] - canonical[:-lag, 0]  # root over 0.1 s
    moving = np.linalg.norm(step[:, [0, 2]], axis=-1) > 0.05
    ahead = np.mean(np.sum(step[moving] * facing[:-lag][moving], axis=-1) > 0) if moving.any() else float("nan")
    if locomotion:
        assert moving.mean() > 0.9 and ahead > 0.9, f"root moves ahead in {ahead:.0%} of {moving.sum()} moving frames"
    return [
        f"bone lengths constant within {spread * 1e6:.1f} µm over {len(z_up)} frames",
        f"head above pelvis by {head_above.min():+.3f} .. {head_above.max():+.3f} m",
        f"left x up points the way the toes do in {handed:.0%} of frames; "
        f"canonical frame 0: left hip x = {lh[0]:+.3f} m, right hip x = {rh[0]:+.3f} m, "
        f"left foot {lf[2] - la[2]:+.3f} m ahead of its ankle",
        "left limbs on the body's left: " + ", ".join(f"{j} {v:.0%}" for j, v in limbs.items())
        + f"; the root moves the way the body faces in {ahead:.0%} of the {moving.sum()} frames it moves",
    ]


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py motion deepmimic`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--wheel", type=Path, help="pybullet-3.2.7-*.whl (default: pip download it)")
    ap.add_argument("--out-dir", type=Path, help="write <name>.npy here (default: check only)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        wheel = args.wheel or fetch_wheel(Path(tmp))
        members = read_members(wheel)
        found = clips(wheel)
    for name, positions in found.items():
        frames, loop = load_clip(members[MOTIONS + PREFIX + name + ".txt"])
        print(
            f"{name}: {len(frames)} frames at {original_fps(frames):.1f} fps (loop {loop}) -> "
            f"{len(positions)} at {FPS} fps, {(len(positions) - 1) / FPS:.2f} s"
        )
        for line in check(positions, upright=name in UPRIGHT, locomotion=name in LOCOMOTION):
            print("  " + line)
        if args.out_dir:
            args.out_dir.mkdir(parents=True, exist_ok=True)
            np.save(args.out_dir / f"{name}.npy", positions)
    if args.out_dir:
        print(f"wrote {len(found)} clips to {args.out_dir}: t2m-22 joints, metres, z up, {FPS} fps")
