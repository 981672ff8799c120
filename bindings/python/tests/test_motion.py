"""troupe.motion through the real shared library: the skeleton, joint positions to features and
back on real motion capture (the committed CMU excerpt), streams, joint sessions, BVH files, and
every bad input raising the library's message."""

from pathlib import Path

import numpy as np
import pytest

import troupe
from troupe import motion

REPO = Path(__file__).resolve().parents[3]
BUNDLE = REPO / "onnx" / "bundles" / "armflow-tiny"
INTERX = REPO / "onnx" / "bundles" / "armflow-tiny-interx"
CMU = REPO / "tests" / "data" / "mocap"


@pytest.fixture(scope="module")
def model():
    with troupe.Model(BUNDLE) as m:
        yield m


@pytest.fixture(scope="module")
def clip():
    return np.load(CMU / "cmu-playground-120fps.npy")  # [960, 22, 3], metres, z up, 120 fps


CMU_FORMAT = motion.JointsFormat(units="m", up="z", fps=120)


def test_skeleton_as_data():
    s = motion.skeleton()
    assert s.names[0] == "pelvis" and s.names[21] == "right_wrist" and len(s.names) == 22
    assert s.parents[0] == -1 and s.parents[4] == 1 and s.parents[13] == 9
    assert s.rest_offsets.shape == (22, 3) and s.rest_offsets[1, 0] > 0 > s.rest_offsets[2, 0]


def test_features_equal_the_intergen_transcription(model, clip):
    features, placement = motion.encode(model, clip, CMU_FORMAT)
    golden = np.load(CMU / "cmu-playground.features.npy")
    assert features.shape == golden.shape == (239, 262)
    assert np.abs(features - golden).max() <= 1e-5
    # InterGen's floor: the lowest joint of the clip at the bundle's rate (every 4th frame).
    assert placement.floor == pytest.approx(float(np.min(clip[::4, :, 2])), abs=1e-6)


def test_round_trip_into_the_callers_world_in_centimetres(model, clip):
    cm = clip[::4] * 100.0
    fmt = motion.JointsFormat(units="cm", up="z", fps=30)
    features, placement = motion.encode(model, cm, fmt)
    poses = motion.decode(model, features, placement, fmt)
    assert poses.positions.shape == (239, 22, 3) and poses.rotations.shape == (239, 22, 4)
    assert np.abs(poses.positions - cm[:-1]).max() < 1e-3  # 1e-5 m
    assert np.allclose(np.linalg.norm(poses.rotations, axis=-1), 1.0, atol=1e-5)
    assert set(np.unique(poses.contacts)) <= {0.0, 1.0}


def test_stream_equals_batch_one_frame_late(model, clip):
    with motion.FeatureStream(model, CMU_FORMAT) as stream:
        assert stream.placement is None
        rows = [stream.push(f) for f in clip[:80]]
        assert [len(r) for r in rows[:5]] == [0, 0, 0, 0, 1]  # 120 -> 30 fps, one frame late
        streamed = np.concatenate(rows)
        batch, _ = motion.encode(model, clip[:80], CMU_FORMAT, placement=stream.placement)
        np.testing.assert_array_equal(streamed, batch)
        with pytest.raises(ValueError):
            stream.push(np.zeros(65, np.float32))
        bad = clip[80].copy()
        bad[7, 1] = np.nan
        with pytest.raises(troupe.TroupeError, match="left_ankle"):
            stream.push(bad)


def test_session_speaks_joints(model, clip):
    assert model.joints_latency_frames == model.latency_frames + 1
    with model.session(seed=4) as session:
        assert session.joints_placement is None
        session.set_joints_format(CMU_FORMAT)
        poses = session.step_joints(clip[:200])
        assert poses.positions.shape == (48, 22, 3)  # 50 frames at 30 fps -> 49 features -> 12 tokens
        assert session.joints_placement is not None
        more = session.step_joints(clip[200:204])
        assert more.positions.shape[0] in (0, 4)
        with pytest.raises(troupe.TroupeError, match="INVALID_ARG.*frame 2"):
            bad = clip[204:210].copy()
            bad[2, 0, 0] = np.inf
            session.step_joints(bad)
        with pytest.raises(ValueError):
            session.step_joints(np.zeros((3, 24, 3), np.float32))


def test_bundles_without_joint_features_refuse(clip):
    with troupe.Model(INTERX) as interx:
        with pytest.raises(troupe.TroupeError, match="interhuman262"):
            motion.encode(interx, clip, CMU_FORMAT)


def test_bvh_round_trip_and_bad_files(tmp_path, clip):
    actor = clip[::4]
    reactor = actor + np.array([1.0, 0.0, 0.0], np.float32)
    path = tmp_path / "pair.bvh"
    fmt = motion.JointsFormat(units="m", up="z", fps=30)
    def through_a_file(positions):
        motion.write_bvh(path, {"actor": positions}, fmt)
        read, read_fmt = motion.read_bvh(path)
        # The written frame time (0.03333333 s) is read as the 30 fps it means.
        assert read_fmt.units == "cm" and read_fmt.up == "y" and read_fmt.fps == 30
        # The file is y up in centimetres; the clip z up in metres: (x, y, z)_file = 100 (x, z, -y).
        return np.stack([read[..., 0], -read[..., 2], read[..., 1]], -1) / 100

    # CMU's hips and shoulders do not move rigidly with one rig joint, so a skeleton (one rotation
    # per joint) reproduces them to centimetres; a rigid take (what the file now holds) exactly.
    once = through_a_file(actor)
    assert np.abs(once - actor).max() < 0.06
    twice = through_a_file(once)
    assert np.abs(twice - once).max() < 1e-5
    motion.write_bvh(path, {"actor": actor, "reactor": reactor}, fmt)
    assert "ROOT scene" in path.read_text()
    with pytest.raises(troupe.TroupeError, match="IO"):
        motion.read_bvh(tmp_path / "missing.bvh")
    (tmp_path / "bad.bvh").write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 zero\n")
    with pytest.raises(troupe.TroupeError, match=r"bad.bvh:4:.*OFFSET of Hips"):
        motion.read_bvh(tmp_path / "bad.bvh")
    nan = actor.copy()
    nan[3, 3, 1] = np.nan
    with pytest.raises(troupe.TroupeError, match="frame 3, joint 3"):
        motion.write_bvh(tmp_path / "nan.bvh", nan, fmt)
    assert not (tmp_path / "nan.bvh").exists()
    with pytest.raises(ValueError, match="without NUL"):
        motion.write_bvh(tmp_path / "nul.bvh", {"act\0or": actor, "reactor": reactor}, fmt)
    with pytest.raises(ValueError):
        motion.JointsFormat(units="furlongs")


def test_viewer_writes_the_player_and_gif(tmp_path, clip):
    from troupe import viewer

    actor = clip[:120:4]
    reactor = actor + np.array([1.2, 0.0, 0.0], np.float32)
    fmt = motion.JointsFormat(units="m", up="z", fps=30)
    viewer.write({"actor": actor, "reactor": reactor}, html=tmp_path / "p.html", gif=tmp_path / "p.gif", fmt=fmt)
    page = (tmp_path / "p.html").read_text()
    assert "actor" in page and "reactor" in page and "<script src" not in page
    assert (tmp_path / "p.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    bad = actor.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(troupe.TroupeError, match="INVALID_ARG"):
        viewer.write({"actor": bad}, html=tmp_path / "bad.html", fmt=fmt)
    assert not (tmp_path / "bad.html").exists()


def test_poses_for_robots_as_json_and_npz(tmp_path, model, clip):
    import json

    actor = clip[:40:4]
    fmt = motion.JointsFormat(units="m", up="z", fps=30)
    motion.write_json(tmp_path / "poses.json", {"actor": actor}, fmt)
    doc = json.loads((tmp_path / "poses.json").read_text())
    assert doc["format"] == "troupe-poses" and doc["up"] == "z" and doc["units"] == "m"
    assert doc["skeleton"]["joints"][0] == "pelvis" and doc["skeleton"]["parents"][1] == 0
    person = doc["people"][0]
    assert person["name"] == "actor"
    assert np.abs(np.array(person["positions"]) - actor).max() < 1e-6
    q = np.array(person["rotations"])
    assert q.shape == (10, 22, 4) and np.allclose(np.linalg.norm(q, axis=-1), 1, atol=1e-5)
    nan = actor.copy()
    nan[2, 5, 0] = np.nan
    with pytest.raises(troupe.TroupeError, match="person 0, frame 2, joint 5"):
        motion.write_json(tmp_path / "nan.json", {"actor": nan}, fmt)
    assert not (tmp_path / "nan.json").exists()
    features, placement = motion.encode(model, actor, fmt)
    poses = motion.decode(model, features, placement, fmt)
    motion.save_npz(tmp_path / "poses.npz", poses, fmt)
    saved = np.load(tmp_path / "poses.npz")
    np.testing.assert_array_equal(saved["positions"], poses.positions)
    assert list(saved["joint_names"][:2]) == ["pelvis", "left_hip"] and str(saved["up"]) == "z"
