"""Motion people have, in and out: the t2m-22 skeleton, joint positions to a bundle's features and
back, streams, and BVH files. numpy in, numpy out.

    import troupe
    from troupe import motion
    model = troupe.Model("onnx/bundles/armflow-tiny")
    fmt = motion.JointsFormat(units="cm", up="z", fps=120)       # how your positions are measured
    features, placement = motion.encode(model, positions, fmt)  # positions: [T, 22, 3]
    poses = motion.decode(model, reactor_features, placement, fmt)
    poses.positions  # [T, 22, 3] in your world; .rotations [T, 22, 4] wxyz; .rotations_6d; .contacts

Rotations: joint 0's is the root's world orientation, every other joint's is local to its parent
(as SMPL, BVH and engines use them). See docs/MOTION.md.

Your character (docs/RIGS.md): a Rig from its BVH file or a rig JSON document, motion retargeted
onto it a clip or a frame at a time, and glTF (.glb) and BVH files of it:

    rig = motion.Rig.from_bvh("character.bvh")
    rotations, roots, root_joint = motion.retarget(rig, positions, fmt)  # [T, J, 4] wxyz, [T, 3]
    motion.write_gltf("scene.glb", {"actor": actor, "reactor": reactor}, fmt, rig=rig)
"""

from __future__ import annotations

import ctypes
import json
import os
import warnings
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from . import _native
from . import Model, _check, _floats, _lib, _ptr
from .errors import ShapeMismatch
from .errors import expect_type

__all__ = ["JointsFormat", "Placement", "Poses", "Skeleton", "FeatureStream", "skeleton", "encode", "decode",
           "read_bvh", "write_bvh", "write_json", "save_npz", "smplx145_positions", "penetration_metrics", "JOINTS",
           "Rig", "RigPose", "Retargeter", "BvhTake", "read_bvh_take", "retarget", "write_gltf", "write_rig_bvh", "write_rig_fbx"]

JOINTS = 22
_UNITS = {"m": 0, "cm": 1, "mm": 2, "in": 3}
_UP = {"y": 0, "z": 1}
_HANDED = {"right": 0, "left": 1}
_UNITS_AUTO = 0xFFFFFFFF


class JointsFormat:
    """How positions are measured: units ("m", "cm", "mm", "in"), up axis ("y" or "z"),
    handedness ("right" or "left") and frame rate (resampled to the bundle's)."""

    def __init__(self, units: str = "m", up: str = "y", handedness: str = "right", fps: float = 30.0):
        for value, table, what in ((units, _UNITS, "units"), (up, _UP, "up"), (handedness, _HANDED, "handedness")):
            if value not in table:
                raise ValueError(f"{what} must be one of {sorted(table)}, got {value!r}")
        if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)):
            raise TypeError(f"fps must be a number, got {type(fps).__name__}")
        self.units, self.up, self.handedness, self.fps = units, up, handedness, float(fps)

    def _c(self) -> _native.JointsFormat:
        f = _native.JointsFormat()
        _check(_lib.troupe_joints_format_init(ctypes.byref(f), ctypes.sizeof(f)))
        f.units, f.up_axis, f.handedness, f.fps = _UNITS[self.units], _UP[self.up], _HANDED[self.handedness], self.fps
        return f

    @classmethod
    def _from_c(cls, f: _native.JointsFormat) -> "JointsFormat":
        name = lambda table, code: next(k for k, v in table.items() if v == code)  # noqa: E731
        return cls(name(_UNITS, f.units), name(_UP, f.up_axis), name(_HANDED, f.handedness), f.fps)

    def __repr__(self) -> str:
        return f"JointsFormat(units={self.units!r}, up={self.up!r}, handedness={self.handedness!r}, fps={self.fps})"


class Placement:
    """Where a clip's canonical frame sits in the caller's world (InterGen's canonicalisation):
    floor height, first-frame root x and z (metres, Y up) and the heading quaternion (wxyz)."""

    def __init__(self, c: _native.Placement):
        self._c = c

    floor = property(lambda self: self._c.floor)
    origin = property(lambda self: (self._c.origin_x, self._c.origin_z))
    heading = property(lambda self: tuple(self._c.heading))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Placement) and bytes(self._c) == bytes(other._c)

    def __repr__(self) -> str:
        return f"Placement(floor={self.floor:.4f}, origin={self.origin}, heading={self.heading})"


class Poses(NamedTuple):
    """Poses in the caller's world: positions [T, 22, 3], rotations [T, 22, 4] (wxyz),
    rotations_6d [T, 22, 6], contacts [T, 4] (left ankle, left foot, right ankle, right foot)."""

    positions: np.ndarray
    rotations: np.ndarray
    rotations_6d: np.ndarray
    contacts: np.ndarray


class Skeleton(NamedTuple):
    """The t2m-22 skeleton: joint names, parents (-1 for the root) and rest offsets [22, 3] in
    metres (Y up, facing +Z, +X the body's left)."""

    names: list
    parents: np.ndarray
    rest_offsets: np.ndarray


def skeleton() -> Skeleton:
    """The t2m-22 skeleton troupe's features are defined on."""
    n = _lib.troupe_motion_joint_count()
    parents = np.empty(n, np.int32)
    offsets = np.empty((n, 3), np.float32)
    _check(_lib.troupe_motion_skeleton(parents.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), n, _ptr(offsets),
                                       offsets.size))
    return Skeleton([_lib.troupe_motion_joint_name(j).decode() for j in range(n)], parents, offsets)


def smplx145_positions(frames: ArrayLike) -> np.ndarray:
    """MAGNet's frames of one person (float32 [frames, 145], the `magnet-smplx145` layout) posed
    on the t2m-22 skeleton: joint positions [frames, 22, 3] in metres, Y up, the frames' world.
    Bone lengths are troupe's neutral body's, not the person's betas. For pictures
    (`troupe.viewer`), BVH files and JSON poses of a MAGNet output."""
    f = _floats(frames, "frames")
    if f.ndim != 2 or f.shape[1] != 145:
        raise ShapeMismatch(f"frames must be [frames, 145], got {list(f.shape)}")
    out = np.empty((f.shape[0], JOINTS, 3), np.float32)
    _check(_lib.troupe_motion_smplx145_positions(_ptr(f), f.shape[0], _ptr(out), out.size))
    return out


def penetration_metrics(first: ArrayLike, second: ArrayLike) -> dict:
    """How much two people's bodies pass through each other (docs/ARFLOW.md): t2m-22 joints
    [frames, 22, 3] each (metres, Y up, one world), each person's joints against the other's
    capsule body. Returns frames_intersecting, frequency, depth_sum (metres, the intersection
    volume's proxy) and max_depth."""
    a, b = _positions(first, "first"), _positions(second, "second")
    if a.shape != b.shape:
        raise ValueError(f"the two people have {a.shape[0]} and {b.shape[0]} frames")
    n = ctypes.c_size_t()
    freq, depth, deepest = ctypes.c_double(), ctypes.c_double(), ctypes.c_double()
    _check(_lib.troupe_motion_penetration_metrics(_ptr(a), _ptr(b), a.shape[0], ctypes.byref(n), ctypes.byref(freq),
                                           ctypes.byref(depth), ctypes.byref(deepest)))
    return {"frames": a.shape[0], "frames_intersecting": n.value, "frequency": freq.value,
            "depth_sum": depth.value, "max_depth": deepest.value}


def _joint_map(joint_map: str | os.PathLike | dict | None) -> bytes | None:
    """A joint map as the C API takes it (JSON text), from JSON text, a dict, or a JSON file's
    path; None for the built-in map."""
    if joint_map is None:
        return None
    if isinstance(joint_map, dict):
        return json.dumps(joint_map).encode()
    if isinstance(joint_map, str) and joint_map.lstrip().startswith("{"):
        return joint_map.encode()
    if isinstance(joint_map, (str, os.PathLike)):
        if not os.path.isfile(joint_map):
            raise FileNotFoundError(
                f"joint_map: {os.fspath(joint_map)!r} is neither joint-map JSON text nor a file")
        with open(joint_map, "rb") as f:
            return f.read()
    raise TypeError(f"joint_map: expected JSON text, a dict or a path, got {type(joint_map).__name__}")


def _positions(x: ArrayLike, what: str) -> np.ndarray:
    a = _floats(x, what)
    if a.ndim != 3 or a.shape[1:] != (JOINTS, 3):
        raise ShapeMismatch(f"{what} must be [frames, 22, 3], got {list(a.shape)}")
    return a


def _pose_buffers(frames: int) -> tuple[Poses, _native.PoseBuffers]:
    poses = Poses(np.empty((frames, JOINTS, 3), np.float32), np.empty((frames, JOINTS, 4), np.float32),
                  np.empty((frames, JOINTS, 6), np.float32), np.empty((frames, 4), np.float32))
    b = _native.PoseBuffers(_ptr(poses.positions), poses.positions.size, _ptr(poses.rotations), poses.rotations.size,
                            _ptr(poses.rotations_6d), poses.rotations_6d.size, _ptr(poses.contacts),
                            poses.contacts.size)
    return poses, b


def _format(fmt: JointsFormat | None, model: Model | None = None) -> _native.JointsFormat:
    """The C form of `fmt` (checked to be a JointsFormat); None: the defaults at the model's rate."""
    if fmt is None:
        fmt = JointsFormat(fps=model.fps) if model is not None else JointsFormat()
    return expect_type(fmt, JointsFormat, "fmt")._c()


def _placement(placement: Placement | None) -> Any:
    """A reference to `placement`'s C form (checked to be a Placement), or None."""
    if placement is None:
        return None
    return ctypes.byref(expect_type(placement, Placement, "placement")._c)


def encode(model: Model, positions: np.ndarray, fmt: JointsFormat | None = None,
           placement: Placement | None = None) -> tuple[np.ndarray, Placement]:
    """Features of a clip of joint positions ([T, 22, 3] as `fmt` says), resampled to the bundle's
    rate, in InterGen's canonical frame (or `placement`'s). Returns (features [T' - 1, frame_dim],
    the Placement used)."""
    expect_type(model, Model, "model")
    p = _positions(positions, "positions")
    c = _format(fmt, model)
    n = ctypes.c_size_t()
    _check(_lib.troupe_motion_encoded_frames(model._h(), ctypes.byref(c), p.shape[0], ctypes.byref(n)))
    out = np.empty((n.value, model.frame_dim), np.float32)
    used = _native.Placement()
    given = _placement(placement)
    written = ctypes.c_size_t()
    _check(_lib.troupe_motion_encode(model._h(), ctypes.byref(c), _ptr(p), p.shape[0], given, _ptr(out),
                                     out.shape[0], ctypes.byref(written), ctypes.byref(used)))
    return out[: written.value], Placement(used)


def decode(model: Model, features: np.ndarray, placement: Placement, fmt: JointsFormat | None = None) -> Poses:
    """Poses of feature frames ([T, frame_dim]) in the caller's world (`placement` from `encode`
    or a stream; `fmt`'s axes and units)."""
    expect_type(model, Model, "model")
    given = _placement(expect_type(placement, Placement, "placement"))
    c = _format(fmt, model)
    f = _floats(features, "features")
    if f.ndim != 2 or f.shape[1] != model.frame_dim:
        raise ShapeMismatch(f"features must be [frames, {model.frame_dim}], got {list(f.shape)}")
    poses, buffers = _pose_buffers(f.shape[0])
    _check(_lib.troupe_motion_decode(model._h(), ctypes.byref(c), given, _ptr(f), f.shape[0],
                                     ctypes.byref(buffers)))
    return poses


class FeatureStream:
    """Joint-position frames in, feature frames out, one frame at a time (one frame of latency:
    velocities need the next frame). One thread at a time."""

    def __init__(self, model: Model, fmt: JointsFormat | None = None, placement: Placement | None = None):
        expect_type(model, Model, "model")
        handle = _native.stream_p()
        c = _format(fmt, model)
        given = _placement(placement)
        _check(_lib.troupe_motion_stream_new(model._h(), ctypes.byref(c), given, ctypes.byref(handle)))
        self._handle, self._dim = handle, model.frame_dim

    def push(self, frame: ArrayLike) -> np.ndarray:
        """One frame of positions ([22, 3]) in; the feature frames it completes out ([k, frame_dim])."""
        f = _floats(frame, "frame", JOINTS * 3)
        cap = _lib.troupe_motion_stream_max_frames(self._handle)
        out = np.empty((cap, self._dim), np.float32)
        n = ctypes.c_size_t()
        _check(_lib.troupe_motion_stream_push(self._handle, _ptr(f), f.size, _ptr(out), cap, ctypes.byref(n)))
        return out[: n.value]

    @property
    def placement(self) -> Placement | None:
        """The canonical frame, once the first frame has fixed it."""
        c = _native.Placement()
        if _lib.troupe_motion_stream_placement(self._handle, ctypes.byref(c)) != 0:
            return None
        return Placement(c)

    def reset(self, placement: Placement | None = None) -> None:
        _check(_lib.troupe_motion_stream_reset(self._handle, _placement(placement)))

    def close(self) -> None:
        if self._handle:
            _lib.troupe_motion_stream_free(self._handle)
            self._handle = None  # type: ignore[assignment]

    __del__ = close

    def __enter__(self) -> FeatureStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class BvhTake(NamedTuple):
    """A BVH take as t2m-22 joint positions [T, 22, 3] (the file's units, Y up), its
    JointsFormat, the t2m-22 joints its rig lacks with how each was placed (one line each), and
    which rig joint each t2m-22 joint is read from (`mapping`, by name; None where placed)."""
    positions: np.ndarray
    format: JointsFormat
    inferred: list[str]
    mapping: dict[str, str | None]


def read_bvh(path: str | os.PathLike, units: str | None = None,
             joint_map: str | os.PathLike | dict | None = None) -> tuple[np.ndarray, JointsFormat]:
    """A BVH or FBX take (told apart by content) as t2m-22 joint positions: (positions [T, 22, 3]
    in the file's units, Y up (a file standing along Z, as Blender writes BVH, is turned), its
    JointsFormat). `units`: the file's ("m", "cm", ...), or None to guess from the figure's
    height (an FBX file declares its own, and is converted to `units`, metres for None); `joint_map`: a joint map (JSON text, a dict, or a JSON file's path) to use instead of
    the built-in one. Joints the rig lacks are placed from the others (`read_bvh_take` says
    which)."""
    take = read_bvh_take(path, units, joint_map)
    return take.positions, take.format


def read_bvh_take(path: str | os.PathLike, units: str | None = None,
                  joint_map: str | os.PathLike | dict | None = None) -> BvhTake:
    """`read_bvh`, also saying which t2m-22 joints the rig lacks and how they were placed."""
    handle = _native.bvh_p()
    code = _UNITS_AUTO if units is None else _UNITS[units]
    jm = _joint_map(joint_map)
    _check(_lib.troupe_bvh_read(os.fsencode(path), jm, code, ctypes.byref(handle)))
    try:
        frames = _lib.troupe_bvh_frames(handle)
        out = np.empty((frames, JOINTS, 3), np.float32)
        _check(_lib.troupe_bvh_positions(handle, _ptr(out), out.size))
        c = _native.JointsFormat()
        _check(_lib.troupe_bvh_format(handle, ctypes.byref(c), ctypes.sizeof(c)))
        said = _lib.troupe_bvh_inferred(handle).decode()
        sources = [_lib.troupe_bvh_joint_source(handle, k) for k in range(JOINTS)]
        mapping = {t2m: (name.decode() if name is not None else None) for t2m, name in zip(T2M22_JOINTS, sources)}
        return BvhTake(out, JointsFormat._from_c(c), said.splitlines(), mapping)
    finally:
        _lib.troupe_bvh_free(handle)


def write_bvh(path: str | os.PathLike, people: ArrayLike | dict[str, ArrayLike], fmt: JointsFormat | None = None, units: str = "cm",
              fit_skeleton: bool = True) -> None:
    """Writes people on the t2m-22 skeleton to a BVH file (atomically). `people`: a dict
    {name: positions [T, 22, 3]} (or one array for one person) in the world `fmt` describes (its
    fps is the file's rate). `fit_skeleton`: each person keeps their bone lengths (the file
    reproduces the positions) rather than troupe's neutral body."""
    stacked, names, c = _people(people, fmt)
    _check(_lib.troupe_bvh_write(os.fsencode(path), _ptr(stacked), stacked.shape[0], stacked.shape[1], ctypes.byref(c),
                                 names, _UNITS[units], int(fit_skeleton)))


def _people(people: ArrayLike | dict[str, ArrayLike],
            fmt: JointsFormat | None) -> tuple[np.ndarray, Any, _native.JointsFormat]:
    """The people stacked [P, T, 22, 3] for the C API's writers of one length (JSON), over the
    frames they all have: a partner streamed back lags its actor by the stream's latency, so the
    actor's last frames have no partner pose yet; they are left out, with a warning naming how
    many."""
    if not isinstance(people, dict):
        people = {"person1": people}
    arrays = [_positions(p, f"positions of {name}") for name, p in people.items()]
    frames = min(a.shape[0] for a in arrays)
    if any(a.shape[0] != frames for a in arrays):
        longer = ", ".join(f"{name} {a.shape[0]}" for name, a in zip(people, arrays) if a.shape[0] != frames)
        warnings.warn(f"people of different lengths are written over the {frames} frames they all have "
                      f"(the last frames of {longer} left out)", stacklevel=3)
        arrays = [a[:frames] for a in arrays]
    for name in people:
        if not isinstance(name, str) or "\0" in name:
            raise ValueError(f"person name {name!r} must be a str without NUL characters")
    names = (ctypes.c_char_p * len(arrays))(*[n.encode() for n in people])
    return np.ascontiguousarray(np.stack(arrays)), names, _format(fmt)


def write_json(path: str | os.PathLike, people: ArrayLike | dict[str, ArrayLike], fmt: JointsFormat | None = None) -> None:
    """Writes people's poses ({name: positions [T, 22, 3]} in the world `fmt` describes) as a
    JSON document for robots and tools: per frame, joint positions, rotations (wxyz; joint 0 the
    root's world orientation, the others local to their parent) and contacts, with the skeleton,
    units, axes and frame rate stated in it."""
    stacked, names, c = _people(people, fmt)
    _check(_lib.troupe_motion_write_json(os.fsencode(path), _ptr(stacked), stacked.shape[0], stacked.shape[1],
                                         ctypes.byref(c), names))


def save_npz(path: str | os.PathLike, poses: Poses, fmt: JointsFormat | None = None) -> None:
    """Saves poses (from `decode` or `Session.step_joints`) as an .npz for robot pipelines:
    positions [T, 22, 3], rotations_wxyz [T, 22, 4], rotations_6d, contacts, joint_names,
    parents, and the axes they are in (units, up, handedness, fps)."""
    fmt = fmt or JointsFormat()
    s = skeleton()
    np.savez(path, positions=poses.positions, rotations_wxyz=poses.rotations, rotations_6d=poses.rotations_6d,
             contacts=poses.contacts, joint_names=np.array(s.names), parents=s.parents, units=fmt.units, up=fmt.up,
             handedness=fmt.handedness, fps=np.float32(fmt.fps))


_RETARGET_NO_FOOT_LOCK = 1
_RETARGET_NO_LIMB_IK = 2
_GLTF_NO_BODIES = 4
_RIG_ZERO_POSE = 0xFFFFFFFF


def _retarget_flags(foot_lock: bool, limb_ik: bool) -> int:
    return (0 if foot_lock else _RETARGET_NO_FOOT_LOCK) | (0 if limb_ik else _RETARGET_NO_LIMB_IK)


# The t2m-22 joints, in the order positions [22, 3] list them.
T2M22_JOINTS = ("pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
                "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
                "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist")


class Rig:
    """A character rig (its joints, rest pose, units and axes) with the joint map saying which of
    its joints is which t2m-22 joint (`joint_map`: JSON text, a dict or a JSON file's path, or None
    for the built-in names: Mixamo, LAFAN1, CMU, HumanIK, SMPL, Rigify). Immutable; share it
    freely."""

    def __init__(self, handle: Any):
        self._handle = handle

    @classmethod
    def from_bvh(cls, path: str | os.PathLike, units: str | None = None, rest_frame: int | None = None,
                 joint_map: str | os.PathLike | dict | None = None) -> "Rig":
        """The rig of a BVH or FBX file (told apart by content). `units`: the file's, or None to
        guess (an FBX file declares its own and is converted to `units`, metres for None);
        `rest_frame`: the frame whose pose is the rest pose (for files whose all-zero pose lies
        down, as LAFAN1's), or None for the all-zero pose (for FBX, its bind pose where it has
        one)."""
        handle = _native.rig_p()
        code = _UNITS_AUTO if units is None else _UNITS[units]
        if rest_frame is not None and not 0 <= int(rest_frame) < _RIG_ZERO_POSE:
            raise ValueError(f"rest_frame must be a frame index, got {rest_frame!r}")
        frame = _RIG_ZERO_POSE if rest_frame is None else int(rest_frame)
        jm = _joint_map(joint_map)
        _check(_lib.troupe_rig_from_bvh(os.fsencode(path), code, frame, jm, ctypes.byref(handle)))
        return cls(handle)

    @classmethod
    def from_fbx(cls, path: str | os.PathLike, units: str | None = None, rest_frame: int | None = None,
                 joint_map: str | os.PathLike | dict | None = None) -> "Rig":
        """The rig of an FBX file (binary or ASCII): `from_bvh`, which reads either."""
        return cls.from_bvh(path, units, rest_frame, joint_map)

    @classmethod
    def from_gltf(cls, path: str | os.PathLike, skin: int = 0,
                  joint_map: str | os.PathLike | dict | None = None) -> "Rig":
        """The rig of skin `skin` in a glTF file (.glb or .gltf): its joints, their hierarchy and
        their nodes' transforms as the rest pose."""
        handle = _native.rig_p()
        if not 0 <= int(skin):
            raise ValueError(f"skin must be an index, got {skin!r}")
        jm = _joint_map(joint_map)
        _check(_lib.troupe_rig_from_gltf(os.fsencode(path), int(skin), jm, ctypes.byref(handle)))
        return cls(handle)

    @classmethod
    def from_json(cls, text: str, joint_map: str | os.PathLike | dict | None = None) -> "Rig":
        """A rig from its JSON document (docs/RIGS.md)."""
        expect_type(text, str, "text")
        handle = _native.rig_p()
        jm = _joint_map(joint_map)
        _check(_lib.troupe_rig_from_json(text.encode(), jm, ctypes.byref(handle)))
        return cls(handle)

    @property
    def joint_names(self) -> list[str]:
        """The rig's joint names, in its order."""
        n = _lib.troupe_rig_joint_count(self._live())
        return [_lib.troupe_rig_joint_name(self._handle, j).decode() for j in range(n)]

    def _live(self) -> Any:
        if not self._handle:
            raise ValueError("the rig is closed")
        return self._handle

    def close(self) -> None:
        """Frees the rig (also done when it is collected)."""
        if getattr(self, "_handle", None):
            _lib.troupe_rig_free(self._handle)
            self._handle = None  # type: ignore[assignment]

    __del__ = close


class RigPose(NamedTuple):
    """One pose of a rig: local rotations [J, 4] (wxyz, the rig's axes), the moving joint's
    local translation [3] (the rig's units and axes), and that joint's index."""
    rotations: np.ndarray
    root_translation: np.ndarray
    root_joint: int


class Retargeter:
    """One stream retargeted onto a rig a frame at a time, with no latency: positions [22, 3] in
    the world `fmt` describes in, a RigPose out. One thread at a time."""

    def __init__(self, rig: Rig, fmt: JointsFormat | None = None, foot_lock: bool = True, limb_ik: bool = True):
        expect_type(rig, Rig, "rig")
        self._handle = _native.retargeter_p()
        self._joints = _lib.troupe_rig_joint_count(rig._live())
        self._names = rig.joint_names
        c = _format(fmt)
        _check(_lib.troupe_rig_retargeter_new(rig._handle, ctypes.byref(c), _retarget_flags(foot_lock, limb_ik),
                                              ctypes.byref(self._handle)))

    def push(self, frame: ArrayLike) -> RigPose:
        """The rig's pose for the stream's next frame."""
        f = np.ascontiguousarray(_floats(frame, "frame"))
        rotations = np.empty((self._joints, 4), np.float32)
        root = np.empty(3, np.float32)
        joint = ctypes.c_size_t()
        _check(_lib.troupe_rig_retarget_push(self._live(), _ptr(f), f.size, _ptr(rotations), rotations.size,
                                             _ptr(root), ctypes.byref(joint)))
        return RigPose(rotations, root, joint.value)

    def reset(self) -> None:
        """Forgets the stream (foot pins, the previous frame)."""
        _check(_lib.troupe_rig_retarget_reset(self._live()))

    @property
    def mapping(self) -> dict[str, str | None]:
        """Which rig joint each t2m-22 joint drives, by name (None: the rig has none), as the
        joint map's names or, where they fall short, the rig's shape found it."""
        out = (ctypes.c_int64 * 22)()
        _check(_lib.troupe_rig_retargeter_mapping(self._live(), out, 22))
        return {t2m: (self._names[j] if j >= 0 else None) for t2m, j in zip(T2M22_JOINTS, out)}

    def _live(self) -> Any:
        if not self._handle:
            raise ValueError("the retargeter is closed")
        return self._handle

    def close(self) -> None:
        """Frees the retargeter (also done when it is collected)."""
        if getattr(self, "_handle", None):
            _lib.troupe_rig_retargeter_free(self._handle)
            self._handle = None  # type: ignore[assignment]

    __del__ = close

    def __enter__(self) -> "Retargeter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def retarget(rig: Rig, positions: ArrayLike, fmt: JointsFormat | None = None, foot_lock: bool = True,
             limb_ik: bool = True) -> tuple[np.ndarray, np.ndarray, int]:
    """A clip [T, 22, 3] (in the world `fmt` describes) retargeted onto `rig`: (local rotations
    [T, J, 4] wxyz in the rig's axes, the moving joint's local translations [T, 3] in the rig's
    units and axes, that joint's index). The source's proportions are measured from the clip."""
    expect_type(rig, Rig, "rig")
    p = _positions(positions, "positions")
    joints = _lib.troupe_rig_joint_count(rig._live())
    rotations = np.empty((p.shape[0], joints, 4), np.float32)
    roots = np.empty((p.shape[0], 3), np.float32)
    joint = ctypes.c_size_t()
    c = _format(fmt)
    _check(_lib.troupe_rig_retarget_clip(rig._handle, _ptr(p), p.shape[0], ctypes.byref(c),
                                         _retarget_flags(foot_lock, limb_ik), _ptr(rotations), rotations.size,
                                         _ptr(roots), roots.size, ctypes.byref(joint)))
    return rotations, roots, joint.value


def write_gltf(path: str | os.PathLike, people: ArrayLike | dict[str, ArrayLike], fmt: JointsFormat | None = None,
               rig: Rig | None = None, bodies: bool = True, foot_lock: bool = True, limb_ik: bool = True) -> None:
    """Writes people ({name: positions [T, 22, 3]} in the world `fmt` describes; its fps is the
    animation's rate) as a glTF 2.0 binary file (.glb, atomically): each retargeted onto `rig`
    (None: troupe's own body) as a skinned skeleton with, unless `bodies` is False, a capsule
    body in its own colour, and one animation. glTF axes: metres, +Y up. People may have
    different lengths: a shorter one holds its last pose to the end of the longest."""
    if rig is not None:
        expect_type(rig, Rig, "rig")
    if not isinstance(people, dict):
        people = {"person1": people}
    arrays = [_positions(p, f"positions of {name}") for name, p in people.items()]
    for name in people:
        if not isinstance(name, str) or "\0" in name:
            raise ValueError(f"person name {name!r} must be a str without NUL characters")
    clips = (_native.PersonClip * len(arrays))(
        *[_native.PersonClip(name=n.encode(), positions=_ptr(a), n_frames=a.shape[0]) for n, a in zip(people, arrays)])
    flags = _retarget_flags(foot_lock, limb_ik) | (0 if bodies else _GLTF_NO_BODIES)
    _check(_lib.troupe_gltf_write_people(os.fsencode(path), rig._live() if rig is not None else None, clips,
                                         len(arrays), ctypes.byref(_format(fmt)), flags))


def write_rig_bvh(path: str | os.PathLike, rig: Rig, positions: ArrayLike, fmt: JointsFormat | None = None,
                  units: str = "cm", foot_lock: bool = True, limb_ik: bool = True) -> None:
    """Writes one person's clip [T, 22, 3] retargeted onto `rig` as a BVH file of the rig's
    hierarchy (atomically), in `units`, Y up."""
    expect_type(rig, Rig, "rig")
    p = _positions(positions, "positions")
    c = _format(fmt)
    _check(_lib.troupe_rig_bvh_write(os.fsencode(path), rig._live(), _ptr(p), p.shape[0], ctypes.byref(c),
                                     _UNITS[units], _retarget_flags(foot_lock, limb_ik)))


def write_rig_fbx(path: str | os.PathLike, rig: Rig, positions: ArrayLike, fmt: JointsFormat | None = None,
                  units: str = "cm", foot_lock: bool = True, limb_ik: bool = True) -> None:
    """Writes one person's clip [T, 22, 3] retargeted onto `rig` as a binary FBX file of the rig's
    skeleton and one animation (atomically), in `units`, Y up: what Blender, Unity, Unreal and
    Maya import. `Rig.from_fbx` reads it back."""
    expect_type(rig, Rig, "rig")
    p = _positions(positions, "positions")
    c = _format(fmt)
    _check(_lib.troupe_rig_fbx_write(os.fsencode(path), rig._live(), _ptr(p), p.shape[0], ctypes.byref(c),
                                     _UNITS[units], _retarget_flags(foot_lock, limb_ik)))
