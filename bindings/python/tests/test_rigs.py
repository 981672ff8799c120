"""troupe.motion's rigs through the real shared library: a rig from BVH and from JSON, the CMU
excerpt retargeted onto it a clip and a frame at a time, glTF and BVH files on it, and every bad
input raising the library's message."""

import json
from pathlib import Path

import numpy as np
import pytest

import troupe
from troupe import motion

REPO = Path(__file__).resolve().parents[3]
CMU = REPO / "tests" / "data" / "mocap"
FMT = motion.JointsFormat(units="m", up="z", fps=30)


@pytest.fixture(scope="module")
def clip():
    return np.load(CMU / "cmu-playground-120fps.npy")[::4][:90]  # [90, 22, 3], metres, z up, 30 fps


def own_rig_json() -> str:
    """troupe's own body as a rig document in centimetres, Z up."""
    s = motion.skeleton()
    joints = []
    for j, name in enumerate(s.names):
        x, y, z = (float(v) for v in s.rest_offsets[j])
        joints.append({"name": name, "parent": s.names[s.parents[j]] if s.parents[j] >= 0 else None,
                       "offset": [100 * x, -100 * z, 100 * y]})
    return json.dumps({"name": "own", "units": "cm", "up": "z", "joints": joints})


def test_retargeting_onto_troupes_own_body_keeps_the_root(clip):
    rig = motion.Rig.from_json(own_rig_json())
    assert rig.joint_names == motion.skeleton().names
    rotations, roots, root_joint = motion.retarget(rig, clip, FMT)
    assert rotations.shape == (90, 22, 4) and roots.shape == (90, 3) and root_joint == 0
    assert np.allclose(np.linalg.norm(rotations, axis=-1), 1, atol=1e-5)
    # Centimetres, Z up, as the rig is: the root travels as the clip's does, scaled by the ratio
    # of the legs (the CMU actor's to troupe's neutral body's). It is placed by the hip centre,
    # which CMU's skeleton has 10 cm below its pelvis and troupe's body 8 cm: leaning into its
    # jumps, the two pelvises part by up to their sum.
    moved, source = (roots - roots[0]) / 100, clip[:, 0] - clip[0, 0]
    scale = float((moved * source).sum() / (source * source).sum())
    assert 0.8 < scale < 1.2
    assert np.abs(moved - scale * source).max() < 0.2
    assert np.abs(moved[-1] - scale * source[-1]).max() < np.abs(source[-1]).max()
    with motion.Retargeter(rig, FMT) as stream:
        pose = stream.push(clip[0])
        assert pose.rotations.shape == (22, 4) and pose.root_joint == 0
        assert np.abs(pose.root_translation / 100 - clip[0, 0]).max() < 0.2
        bad = clip[1].copy()
        bad[3, 1] = np.nan
        with pytest.raises(troupe.TroupeError, match="finite"):
            stream.push(bad)
        with pytest.raises(troupe.TroupeError, match="66 floats"):
            stream.push(clip[1][:21])
        stream.reset()
        again = stream.push(clip[0])
        assert np.array_equal(again.rotations, pose.rotations)


def test_a_bvh_rig_and_the_files_written_on_it(tmp_path, clip):
    # A rig no one tuned for: the BVH troupe writes of the clip, read back as a rig.
    source = tmp_path / "source.bvh"
    motion.write_bvh(source, {"actor": clip}, FMT)
    rig = motion.Rig.from_bvh(source)
    assert rig.joint_names[0] == "pelvis"
    take = motion.read_bvh_take(source)
    assert take.positions.shape == (90, 22, 3) and take.inferred == []
    glb = tmp_path / "pair.glb"
    motion.write_gltf(glb, {"actor": clip, "partner": clip + np.float32([1.5, 0, 0])}, FMT, rig=rig)
    data = glb.read_bytes()
    assert data[:4] == b"glTF" and int.from_bytes(data[8:12], "little") == len(data)
    assert b'"actor_pelvis"' in data and b'"partner_pelvis"' in data
    motion.write_gltf(tmp_path / "own.glb", clip, FMT, bodies=False)
    # The file's skin as a rig: the same joints.
    back = motion.Rig.from_gltf(tmp_path / "own.glb")
    assert back.joint_names == motion.skeleton().names
    with pytest.raises(troupe.TroupeError, match="skin 3"):
        motion.Rig.from_gltf(tmp_path / "own.glb", skin=3)
    out = tmp_path / "rig.bvh"
    motion.write_rig_bvh(out, rig, clip, FMT)
    positions, fmt = motion.read_bvh(out)
    assert positions.shape == (90, 22, 3) and fmt.units == "cm"
    # A partner shorter than its actor (the stream's latency): each keeps its own frames, nothing
    # trimmed (glTF holds the shorter one's last pose); JSON, one length, writes those both have.
    motion.write_gltf(tmp_path / "x.glb", {"a": clip, "b": clip[:80]}, FMT)
    data = (tmp_path / "x.glb").read_bytes()
    doc = json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])
    times = sorted(a["count"] for a in doc["accessors"] if a.get("max") and len(a["max"]) == 1)
    assert times == [80, 90], times
    counts = {s["input"] for s in doc["animations"][0]["samplers"]}
    assert len(counts) == 2
    with pytest.warns(UserWarning, match=r"over the 80 frames they all have \(the last frames of a 90 left out\)"):
        motion.write_json(tmp_path / "x.json", {"a": clip, "b": clip[:80]}, FMT)


def test_a_joint_map_is_json_text_a_dict_or_a_file(tmp_path, clip):
    source = tmp_path / "source.bvh"
    motion.write_bvh(source, {"actor": clip}, FMT)
    names = motion.skeleton().names
    own = {"skeleton": "t2m22", "joints": {n: [n] for n in names}}
    path = tmp_path / "map.json"
    path.write_text(json.dumps(own))
    builtin = motion.read_bvh_take(source)
    for given in (own, json.dumps(own), path, str(path)):
        take = motion.read_bvh_take(source, joint_map=given)
        assert np.array_equal(take.positions, builtin.positions), type(given)
    # An empty list says the rig has no such joint: it is placed from its neighbours.
    no_toes = {"skeleton": "t2m22", "joints": {**own["joints"], "left_foot": []}}
    take = motion.read_bvh_take(source, joint_map=no_toes)
    assert [line for line in take.inferred if line.startswith("left_foot")], take.inferred
    # Which rig joint each t2m-22 joint is read from; None for the one placed from others.
    assert builtin.mapping == {n: n for n in names}
    assert take.mapping == {n: (None if n == "left_foot" else n) for n in names}
    with pytest.raises(FileNotFoundError, match="neither joint-map JSON text nor a file"):
        motion.read_bvh_take(source, joint_map=str(tmp_path / "missing.json"))
    with pytest.raises(TypeError, match="joint_map"):
        motion.read_bvh_take(source, joint_map=3)  # type: ignore[arg-type]
    with pytest.raises(troupe.TroupeError, match="no entry for t2m-22 joint"):
        motion.read_bvh_take(source, joint_map={"skeleton": "t2m22", "joints": {"pelvis": ["pelvis"]}})


def test_the_retargeter_shows_which_rig_joint_each_joint_drives():
    rig = motion.Rig.from_json(own_rig_json())
    with motion.Retargeter(rig, FMT) as stream:
        assert stream.mapping == {name: name for name in motion.skeleton().names}
    # The same body with numbers for names: recognised by its shape, joint for joint.
    numbered = json.loads(own_rig_json())
    rename = {j["name"]: f"bone {k}" for k, j in enumerate(numbered["joints"])}
    for j in numbered["joints"]:
        j["name"], j["parent"] = rename[j["name"]], rename.get(j["parent"])
    with motion.Retargeter(motion.Rig.from_json(json.dumps(numbered)), FMT) as stream:
        assert stream.mapping == rename


def test_bad_rigs_are_refused_with_the_reason(tmp_path):
    with pytest.raises(troupe.TroupeError, match="0 joints"):
        motion.Rig.from_json('{"name": "x", "joints": []}')
    with pytest.raises(troupe.TroupeError, match="not a rig document"):
        motion.Rig.from_json("[]")
    with pytest.raises(troupe.TroupeError, match="IO"):
        motion.Rig.from_bvh(tmp_path / "missing.bvh")
    legs = json.dumps({"name": "legs", "joints": [{"name": "Hips", "parent": None, "offset": [0, 1, 0]}]})
    rig = motion.Rig.from_json(legs)
    with pytest.raises(troupe.TroupeError, match="left_hip"):
        motion.Retargeter(rig)
    with pytest.raises(ValueError, match="rest_frame"):
        motion.Rig.from_bvh(tmp_path / "missing.bvh", rest_frame=-1)
    rig.close()
    with pytest.raises(ValueError, match="closed"):
        rig.joint_names


def test_fbx_files_are_read_like_bvh_as_their_author_meant(tmp_path):
    # ASCII FBX in centimetres, Z up (tests/data/PROVENANCE.md): read Y up in metres, or converted
    # to the unit asked for; Blender's binary FBX: its bind pose is the rest pose.
    ascii_fbx = REPO / "tests" / "data" / "ascii_body.fbx"
    take = motion.read_bvh_take(ascii_fbx)
    assert take.positions.shape == (31, 22, 3)
    assert take.format.units == "m" and take.format.fps == 30.0
    assert take.mapping["pelvis"] == "Hips" and take.inferred == []
    np.testing.assert_allclose(take.positions[-1, 0], [0.0, 0.95, 0.5], atol=1e-5)
    cm, fmt = motion.read_bvh(ascii_fbx, units="cm")
    assert fmt.units == "cm"
    np.testing.assert_allclose(cm[-1, 0], [0.0, 95.0, 50.0], atol=1e-3)
    rig = motion.Rig.from_fbx(REPO / "tests" / "data" / "blender_mixamo.fbx")
    assert rig.joint_names[0] == "mixamorig:Hips"
    assert motion.Retargeter(rig).mapping["left_elbow"] == "mixamorig:LeftForeArm"
    broken = tmp_path / "broken.fbx"
    broken.write_bytes((REPO / "tests" / "data" / "blender_mixamo.fbx").read_bytes()[:5000])
    with pytest.raises(troupe.InvalidArgument, match="broken.fbx: not a readable FBX file"):
        motion.Rig.from_fbx(broken)


def test_a_clip_written_as_fbx_on_a_rig_reads_back_on_that_rig(tmp_path, clip):
    rig = motion.Rig.from_fbx(REPO / "tests" / "data" / "blender_mixamo.fbx")
    out = tmp_path / "reactor.fbx"
    motion.write_rig_fbx(out, rig, clip[:40], motion.JointsFormat("m", "z", fps=30.0))
    back = motion.Rig.from_fbx(out)
    assert back.joint_names == rig.joint_names
    take = motion.read_bvh_take(out)
    assert take.positions.shape == (40, 22, 3) and take.inferred == []
    # The retargeted clip keeps the source's height profile: the head stays above the hips.
    assert (take.positions[:, 15, 1] > take.positions[:, 0, 1]).all()
    with pytest.raises(troupe.InvalidArgument, match="NaN|finite"):
        bad = np.array(clip[:5], np.float32)
        bad[2, 3, 1] = np.nan
        motion.write_rig_fbx(tmp_path / "bad.fbx", rig, bad, motion.JointsFormat("m", "z", fps=30.0))
    assert not (tmp_path / "bad.fbx").exists()
