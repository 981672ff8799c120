"""InterGen's motion processing (`tr3e/InterGen`, `utils/utils.py::process_motion_np`) in numpy.

An independent transcription of the published code, step for step, with HumanML3D's quaternion
helpers (w, x, y, z); the reference that troupe's `encode_clip` (`src/motion/`) is tested
against. Input: joint positions of the t2m-22 skeleton as InterHuman's raw files hold them,
metres with +Z up. Output: `T - 1` frames of the 262-d `interhuman262` layout:

| columns | content |
|---|---|
| `[0:66]` | positions of frames `0 .. T-2` in the canonical frame |
| `[66:132]` | velocities `p[t+1] - p[t]` |
| `[132:258]` | 6-D local rotations of joints 1..21 |
| `[258:262]` | contacts: left ankle, left foot, right ankle, right foot |

The one departure from InterGen: its rotation columns are SMPL fits read from the dataset; here
they come from inverse kinematics on the positions (`troupe_onnx.motion.ik`), which is what
troupe computes for callers who have positions only. InterGen loads its data as float32; this
computes in float64 from the float32 input (as the runtime does) and rounds the features once.
"""

from __future__ import annotations

import numpy as np

from troupe_onnx.motion import ik
from troupe_onnx.motion.skeleton import Skeleton, t2m22

# InterGen's constants (utils/utils.py).
TRANS_MATRIX = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # raw z-up -> y-up
Y_UP_TO_Z_UP = np.linalg.inv(TRANS_MATRIX)  # y-up (CMU, DeepMimic, troupe) -> InterHuman's raw z-up
FACE_JOINT_INDX = (2, 1, 17, 16)  # r_hip, l_hip, sdr_r, sdr_l
FID_L, FID_R = (7, 10), (8, 11)
FEET_THRE = 0.001
HEIGHT_FACTOR = np.array([0.12, 0.05])
N_JOINTS = 22
FEATURE_DIM = 262
SLICES = {"positions": slice(0, 66), "velocities": slice(66, 132), "rotations": slice(132, 258), "contacts": slice(258, 262)}


def qbetween_np(v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """HumanML3D's `qbetween_np`: the quaternion of the shortest arc from v0 to v1."""
    v = np.cross(v0, v1)
    w = np.sqrt((v0**2).sum(axis=-1, keepdims=True) * (v1**2).sum(axis=-1, keepdims=True)) + (v0 * v1).sum(
        axis=-1, keepdims=True
    )
    q = np.concatenate([w, v], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def qrot_np(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """HumanML3D's `qrot`: v rotated by the unit quaternion q (shapes [..., 4] and [..., 3])."""
    qvec = q[..., 1:]
    uv = np.cross(qvec, v)
    uuv = np.cross(qvec, uv)
    return v + 2 * (q[..., :1] * uv + uuv)


def canonicalise(positions_zup: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """InterGen's canonical frame: (positions [T, 22, 3] y-up, root_quat_init [1, 4],
    root_pose_init_xz [1, 3], floor_height)."""
    positions = np.einsum("mn,tjn->tjm", TRANS_MATRIX, np.asarray(positions_zup, dtype=np.float64))
    # Put on floor.
    floor_height = positions.min(axis=0).min(axis=0)[1]
    positions[:, :, 1] -= floor_height
    # XZ at origin.
    root_pos_init = positions[0]
    root_pose_init_xz = root_pos_init[0] * np.array([1.0, 0.0, 1.0])
    positions = positions - root_pose_init_xz
    # All initially face Z+.
    r_hip, l_hip, _, _ = FACE_JOINT_INDX
    across = root_pos_init[r_hip] - root_pos_init[l_hip]
    across = across / np.sqrt((across**2).sum(axis=-1))[..., np.newaxis]
    forward_init = np.cross(np.array([[0.0, 1.0, 0.0]]), across, axis=-1)
    forward_init = forward_init / np.sqrt((forward_init**2).sum(axis=-1))[..., np.newaxis]
    target = np.array([[0.0, 0.0, 1.0]])
    root_quat_init = qbetween_np(forward_init, target)
    root_quat_init_for = np.ones(positions.shape[:-1] + (4,)) * root_quat_init
    positions = qrot_np(root_quat_init_for, positions)
    return positions, root_quat_init, root_pose_init_xz[None], float(floor_height)


def foot_detect(positions: np.ndarray, thres: float = FEET_THRE) -> tuple[np.ndarray, np.ndarray]:
    """InterGen's foot contacts of canonical positions: ([T-1, 2], [T-1, 2]) float32."""
    velfactor = np.array([thres, thres])

    def side(fid):
        fid = list(fid)
        x = (positions[1:, fid, 0] - positions[:-1, fid, 0]) ** 2
        y = (positions[1:, fid, 1] - positions[:-1, fid, 1]) ** 2
        z = (positions[1:, fid, 2] - positions[:-1, fid, 2]) ** 2
        height = positions[:-1, fid, 1]
        return (((x + y + z) < velfactor) & (height < HEIGHT_FACTOR)).astype(np.float32)

    return side(FID_L), side(FID_R)


def rotation_features(positions: np.ndarray, skeleton: Skeleton | None = None) -> np.ndarray:
    """The 6-D local rotations of joints 1..21 by inverse kinematics: [T, 126]."""
    local = ik.inverse_kinematics(skeleton or t2m22(), positions)
    return ik.to_6d(local[:, 1:]).reshape(len(positions), -1)


def process_motion(positions_zup_m: np.ndarray, skeleton: Skeleton | None = None):
    """InterGen's `process_motion_np` on joint positions `[T, 22, 3]` (metres, z up):
    (features [T-1, 262] float32, root_quat_init [1, 4], root_pose_init_xz [1, 3])."""
    positions_zup_m = np.asarray(positions_zup_m)
    if positions_zup_m.ndim != 3 or positions_zup_m.shape[1:] != (N_JOINTS, 3):
        raise ValueError(f"joint positions must be [frames, 22, 3], got {positions_zup_m.shape}")
    if len(positions_zup_m) < 2:
        raise ValueError(f"{len(positions_zup_m)} frame(s): features need at least 2")
    if not np.all(np.isfinite(positions_zup_m)):
        raise ValueError("joint positions are not all finite")
    positions, root_quat_init, root_pose_init_xz, _ = canonicalise(positions_zup_m)
    feet_l, feet_r = foot_detect(positions)
    rot_data = rotation_features(positions, skeleton)
    joint_positions = positions.reshape(len(positions), -1)
    joint_vels = (positions[1:] - positions[:-1]).reshape(len(positions) - 1, -1)
    data = joint_positions[:-1]
    data = np.concatenate([data, joint_vels], axis=-1)
    data = np.concatenate([data, rot_data[:-1]], axis=-1)
    data = np.concatenate([data, feet_l, feet_r], axis=-1)
    return data.astype(np.float32), root_quat_init, root_pose_init_xz
