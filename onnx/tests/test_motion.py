"""The motion tooling (`troupe_onnx.motion`; numpy only): the committed CMU excerpt and its golden
features, InterGen's canonical frame, inverse and forward kinematics, and the ASF/AMC reader."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from troupe_onnx.motion import acclaim, ik, intergen
from troupe_onnx.motion.cmu_excerpt import T2M22_FROM_CMU
from troupe_onnx.motion.features_cmd import features_of
from troupe_onnx.motion.skeleton import REPO, T2M22_JSON, parse, t2m22

MOCAP = REPO / "tests" / "data" / "mocap"
EXCERPT = MOCAP / "cmu-playground-120fps.npy"
GOLDEN = MOCAP / "cmu-playground.features.npy"
STRIDE = 4  # 120 fps -> 30 fps


@pytest.fixture(scope="module")
def excerpt() -> np.ndarray:
    return np.load(EXCERPT)


# --- the committed files ---------------------------------------------------------------------


def test_the_golden_features_regenerate_from_the_excerpt(excerpt):
    assert excerpt.shape == (960, 22, 3) and excerpt.dtype == np.float32
    golden = np.load(GOLDEN)
    assert golden.shape == (239, 262) and golden.dtype == np.float32
    ours = features_of(excerpt, STRIDE)
    assert np.abs(ours - golden).max() <= 1e-6


def test_the_features_command_writes_the_golden(tmp_path):
    out = tmp_path / "f.npy"
    cmd = [sys.executable, str(REPO / "onnx" / "cli.py"), "motion", "features", str(EXCERPT), "--stride", "4", "--out", str(out)]
    run = subprocess.run(cmd, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert np.array_equal(np.load(out), np.load(GOLDEN))


def test_the_excerpt_is_an_upright_unmirrored_person(excerpt):
    names = t2m22().names
    assert set(T2M22_FROM_CMU) == set(names)
    canonical, _, _, _ = intergen.canonicalise(excerpt)
    head, pelvis = canonical[:, names.index("head"), 1], canonical[:, names.index("pelvis"), 1]
    assert (head - pelvis).min() > 0.3
    across = canonical[:, names.index("left_hip")] - canonical[:, names.index("right_hip")]
    for part in ("hip", "knee", "foot", "shoulder", "elbow", "wrist"):
        side = canonical[:, names.index(f"left_{part}")] - canonical[:, names.index(f"right_{part}")]
        assert np.all(np.sum(side * across, axis=-1) > 0), f"left_{part} is not on the body's left"
    assert canonical[0, names.index("left_hip"), 0] > 0 > canonical[0, names.index("right_hip"), 0]


# --- InterGen's canonical frame --------------------------------------------------------------


def test_the_canonical_frame_is_intergens(excerpt):
    clip = excerpt[::STRIDE]
    canonical, quat, xz, floor = intergen.canonicalise(clip)
    assert canonical[..., 1].min() == 0.0  # the lowest joint of the whole clip on the floor
    assert np.abs(canonical[0, 0, [0, 2]]).max() < 1e-12  # frame 0's root at x = z = 0
    r_hip, l_hip = intergen.FACE_JOINT_INDX[:2]
    across = canonical[0, r_hip] - canonical[0, l_hip]
    forward = np.cross([0.0, 1.0, 0.0], across / np.linalg.norm(across))
    assert np.allclose(forward / np.linalg.norm(forward), [0, 0, 1], atol=1e-12)  # facing +Z
    assert abs(quat[0, 1]) < 1e-12 and abs(quat[0, 3]) < 1e-12  # a turn about y only
    # A rigid motion: distances between joints are kept.
    z_up = clip.astype(np.float64)
    d0 = np.linalg.norm(z_up[:, :, None] - z_up[:, None], axis=-1)
    d1 = np.linalg.norm(canonical[:, :, None] - canonical[:, None], axis=-1)
    assert np.abs(d0 - d1).max() < 1e-12
    # The features hold frames 0..T-2 of it, velocities to the next frame, and binary contacts.
    features, _, _ = intergen.process_motion(clip)
    assert np.allclose(features[:, :66], canonical[:-1].reshape(len(clip) - 1, 66), atol=1e-6)
    assert np.allclose(features[:, 66:132], (canonical[1:] - canonical[:-1]).reshape(len(clip) - 1, 66), atol=1e-6)
    assert set(np.unique(features[:, 258:])) <= {0.0, 1.0}
    assert features[:, 258:].mean() > 0.5  # mostly standing on the ground between jumps


def test_the_z_up_axes_are_intergens_trans_matrix():
    positions = np.zeros((2, 22, 3))
    positions[:, :, 2] = np.arange(22) * 0.05  # a column of joints rising along +z
    positions[:, 1, 0], positions[:, 2, 0] = 0.1, -0.1  # left hip +x, right hip -x
    positions[:, 1, 2] = positions[:, 2, 2] = 0.0
    canonical, _, _, floor = intergen.canonicalise(positions)
    assert floor == 0.0
    assert canonical[0, 21, 1] == pytest.approx(1.05)  # z up became y up


def test_six_d_is_the_first_two_columns_row_by_row():
    r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z
    assert ik.to_6d(r).tolist() == [0.0, -1.0, 1.0, 0.0, 0.0, 0.0]


def test_bad_positions_are_refused():
    with pytest.raises(ValueError, match=r"\[frames, 22, 3\]"):
        intergen.process_motion(np.zeros((5, 24, 3)))
    with pytest.raises(ValueError, match="at least 2"):
        intergen.process_motion(np.zeros((1, 22, 3)))
    clip = np.random.default_rng(0).normal(size=(3, 22, 3))
    clip[1, 4, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        intergen.process_motion(clip)


# --- inverse and forward kinematics ----------------------------------------------------------


def _rotation(axis, angle):
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_the_skeleton_is_the_runtimes_document():
    s = t2m22()
    assert s.name == "t2m22" and len(s) == 22
    assert s.names[0] == "pelvis" and s.parents[0] == -1
    assert set(s.branch_frames) == {0, 9}  # pelvis and spine3
    rest = s.rest_positions()
    assert rest[1, 0] > 0 > rest[2, 0]  # left hip at +x
    assert abs(rest[:, 1].min() - 0.02) < 1e-12
    with pytest.raises(ValueError, match="needs a branch frame"):
        parse(T2M22_JSON.read_text().replace('"branch_frames"', '"unused"'), "x")


def test_ik_of_the_rest_pose_is_no_rotation_and_fk_of_ik_is_exact_on_a_rigid_body():
    s = t2m22()
    local = ik.inverse_kinematics(s, s.rest_positions()[None])
    assert np.abs(local - np.eye(3)).max() < 1e-12
    rng = np.random.default_rng(3)
    frames = 20
    posed = np.array([[_rotation(rng.normal(size=3), rng.uniform(-1.2, 1.2)) for _ in range(22)] for _ in range(frames)])
    positions = ik.forward_kinematics(s, rng.normal(size=(frames, 3)), posed)
    again = ik.forward_kinematics(s, positions[:, 0], ik.inverse_kinematics(s, positions))
    assert np.abs(again - positions).max() < 1e-9
    # Another body's proportions: IK on the neutral skeleton, FK on the fitted one.
    other = s.with_offsets(s.offsets * np.linspace(0.9, 1.2, 22)[:, None] + [0.0, 0.0, 0.01])
    positions = ik.forward_kinematics(other, rng.normal(size=(frames, 3)), posed)
    fitted = ik.fit_skeleton(s, positions)
    again = ik.forward_kinematics(fitted, positions[:, 0], ik.inverse_kinematics(s, positions))
    assert np.abs(again - positions).max() < 1e-9


# The IK -> FK residual on the CMU excerpt, per joint, max in mm, measured (tests/motion.rs
# measures the same with troupe's IK): 0 at the pelvis; 31.2 on the hips and legs and 13.7 on
# spine1..3 (the pelvis branch: CMU's lowerback bends between the root, which carries the hips,
# and spine1, so the hips-and-spine1 triangle is not rigid); 52.3 on neck and head and 18.7 on
# the collars and arms (the spine3 branch: the clavicles and lowerneck move against the thorax).
# Single-child bones are rigid, so each chain carries its branch's error unchanged. Bounds a
# little above the measurement.
RESIDUAL_BOUND_MM = {"pelvis": 1e-6, "legs": 33.0, "spine": 15.0, "neck": 55.0, "arms": 20.0}
GROUP = ["pelvis", "legs", "legs", "spine", "legs", "legs", "spine", "legs", "legs", "spine", "legs", "legs",
         "neck", "arms", "arms", "neck", "arms", "arms", "arms", "arms", "arms", "arms"]  # fmt: skip


def test_ik_then_fk_on_the_cmu_excerpt_with_a_fitted_skeleton(excerpt):
    s = t2m22()
    canonical, _, _, _ = intergen.canonicalise(excerpt)
    fitted = ik.fit_skeleton(s, canonical)
    again = ik.forward_kinematics(fitted, canonical[:, 0], ik.inverse_kinematics(s, canonical))
    residual = np.linalg.norm(again - canonical, axis=-1) * 1e3
    report = [f"{n}: max {residual[:, j].max():.2f} mean {residual[:, j].mean():.2f} mm" for j, n in enumerate(s.names)]
    print("\n".join(report))
    for j, name in enumerate(s.names):
        assert residual[:, j].max() <= RESIDUAL_BOUND_MM[GROUP[j]], report[j]
    # Bone lengths of single-child bones are rigid in CMU's skeleton, so the fit is exact there.
    for j, p in enumerate(s.parents):
        if p >= 0 and p not in s.branch_frames:
            lengths = np.linalg.norm(canonical[:, j] - canonical[:, p], axis=-1)
            assert np.ptp(lengths) < 1e-5, s.names[j]


# --- ASF / AMC -------------------------------------------------------------------------------

ASF = """\
# a test skeleton
:version 1.10
:name tiny
:units
  mass 1.0
  length 0.5
  angle deg
:documentation
  three bones
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name a
     direction 0 1 0
     length 2
     axis 0 0 0 XYZ
    dof rx ry rz
    limits (-180.0 180.0)
           (-180.0 180.0)
           (-180.0 180.0)
  end
  begin
     id 2
     name b
     direction 1 0 0
     length 1
     axis 0 0 90 XYZ
    dof rx
    limits (-180.0 180.0)
  end
  begin
     id 3
     name c
     direction 0 -1 0
     length 1
     axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root a c
    a b
  end
"""

AMC = """\
# frames
:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 90 0
a 0 0 90
b 90
2
root 0 0 0 0 0 0
a 0 0 0
b 0
"""

# By hand. Frame 1: the root turns 90 degrees about y, R0 = Ry(90) (x -> -z, z -> x).
#   c: (1,2,3) + Ry(90) (0,-1,0) = (1,1,3).
#   a: M = Rz(90) (y -> -x); R_a = Ry(90) Rz(90); (0,1,0) -> (-1,0,0) -> (0,0,1); end (1,2,3) + 2 (0,0,1).
#   b: C = Rz(90), C Rx(90) C^-1 = 90 degrees about C x = y: Ry(90); R_b = Ry(90) Rz(90) Ry(90);
#      (1,0,0) -> (0,0,-1) -> (0,0,-1) -> (-1,0,0); end (1,2,5) + (-1,0,0).
# Frame 2: the rest pose at the origin: a up to (0,2,0), b along +x to (1,2,0), c down to (0,-1,0).
EXPECTED = {
    "a": [[1, 2, 5], [0, 2, 0]],
    "b": [[0, 2, 5], [1, 2, 0]],
    "c": [[1, 1, 3], [0, -1, 0]],
}


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_hand_written_asf_amc_reads_back_to_hand_computed_positions(tmp_path):
    asf = acclaim.read_asf(_write(tmp_path, "t.asf", ASF))
    assert asf.name == "tiny" and asf.length_unit == 0.5 and asf.order() == ["a", "b", "c"]
    assert asf.bones["a"].limits == [(-180.0, 180.0)] * 3 and asf.bones["c"].dof == ()
    assert asf.cmu_metres_per_unit == pytest.approx(0.0254 / 0.5)
    amc = acclaim.read_amc(_write(tmp_path, "t.amc", AMC), asf)
    assert amc.frames.tolist() == [1, 2]
    pose = acclaim.forward_kinematics(asf, amc)
    assert np.allclose(pose.root, [[1, 2, 3], [0, 0, 0]])
    for bone, ends in EXPECTED.items():
        assert np.allclose(pose.end(bone), ends, atol=1e-12), bone
    assert np.allclose(pose.start("b"), pose.end("a"))
    # The same motion in radians gives the same positions.
    radians = AMC.replace(":DEGREES", ":RADIANS").replace(" 90", f" {np.pi / 2!r}")
    again = acclaim.forward_kinematics(asf, acclaim.read_amc(_write(tmp_path, "r.amc", radians), asf))
    assert np.allclose(again.ends, pose.ends, atol=1e-12)
    # A pre-set root position offsets all the motion.
    shifted = acclaim.read_asf(_write(tmp_path, "s.asf", ASF.replace("position 0 0 0", "position 10 0 0")))
    moved = acclaim.forward_kinematics(shifted, acclaim.read_amc(tmp_path / "t.amc", shifted))
    assert np.allclose(moved.ends - pose.ends, [10, 0, 0])


def _line_of(text: str, needle: str) -> int:
    """The number of the line equal to `needle`, else of the first line containing it."""
    lines = text.splitlines()
    if needle in lines:
        return lines.index(needle) + 1
    return next(n for n, line in enumerate(lines, start=1) if needle in line)


@pytest.mark.parametrize(
    "old, new, needle, words",
    [
        ("direction 1 0 0", "direction 1 0", "direction 1 0", ["bone b", "3 number"]),
        ("length 2", "length two", "length two", ["bone a", "not numbers"]),
        ("dof rx\n", "dof rx tx\n", "dof rx tx", ["bone b", "tx not supported"]),
        ("    a b\n", "    a b d\n", "    a b d", ["bone d", "unknown bone"]),
        ("axis 0 0 90 XYZ", "axis 0 0 90 XYQ", "axis 0 0 90 XYQ", ["bone b", "axis"]),
        ("order TX TY TZ RX RY RZ", "order TX TY TZ RX RY RQ", "order TX", ["bone root", "root order"]),
        # A `limits` line without its pair: the error is at the `end` that follows it.
        ("    limits (-180.0 180.0)\n  end\n  begin\n     id 3", "    limits\n  end\n  begin\n     id 3",
         "    limits", ["bone b", "1 limit pair(s) missing"]),
    ],
)
def test_malformed_asf_names_file_line_and_bone(tmp_path, old, new, needle, words):
    assert old in ASF
    text = ASF.replace(old, new, 1)
    path = _write(tmp_path, "bad.asf", text)
    with pytest.raises(acclaim.AcclaimError) as err:
        acclaim.read_asf(path)
    message = str(err.value)
    line = _line_of(text, needle) + (1 if needle == "    limits" else 0)
    assert f"{path}:{line}:" in message, message
    for w in words:
        assert w in message, message


def test_a_bone_missing_from_the_hierarchy_is_named(tmp_path):
    path = _write(tmp_path, "bad.asf", ASF.replace("    root a c\n", "    root a\n"))
    with pytest.raises(acclaim.AcclaimError, match=r"bad\.asf:\d+: bone c: has no parent"):
        acclaim.read_asf(path)


@pytest.mark.parametrize(
    "old, new, needle, words",
    [
        ("a 0 0 90\n", "a 0 0\n", "a 0 0", ["bone a", "3 value(s) expected, got 2"]),
        ("b 90\n", "b ninety\n", "b ninety", ["bone b", "not numbers"]),
        ("b 90\n", "b 90\nc 1\n", "c 1", ["bone c", "without dof"]),
        ("b 90\n", "b 90\nz 1\n", "z 1", ["bone z", "not a bone"]),
        ("b 90\n", "b 90\nb 90\n", "b 90", ["bone b", "twice"]),
        ("b 0\n", "", "2", ["bone b", "frame 2 has no values for b"]),
        ("2\n", "1\n", "1", ["frame 1 after frame 1"]),
    ],
)
def test_malformed_amc_names_file_line_and_bone(tmp_path, old, new, needle, words):
    asf = acclaim.read_asf(_write(tmp_path, "t.asf", ASF))
    assert old in AMC
    text = AMC.replace(old, new, 1) if old != "2\n" else AMC.replace("\n2\n", "\n1\n")
    path = _write(tmp_path, "bad.amc", text)
    with pytest.raises(acclaim.AcclaimError) as err:
        acclaim.read_amc(path, asf)
    message = str(err.value)
    lines = text.splitlines()
    # The line the error is about: the last one equal to the needle (a repeat, or frame 2's number).
    line = max(n for n, l in enumerate(lines, start=1) if l == needle)
    assert f"{path}:{line}:" in message, message
    for w in words:
        assert w in message, message


def test_the_cli_lists_the_motion_commands():
    run = subprocess.run([sys.executable, str(REPO / "onnx" / "cli.py")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "motion cmu-excerpt" in run.stdout and "motion features" in run.stdout
