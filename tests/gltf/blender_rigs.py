"""Characters as Blender writes them: armatures in the naming conventions people use, exported
with Blender's own BVH and FBX exporters (run by tests/rigs.rs with the `bpy` of target/blender).

    python3 tests/gltf/blender_rigs.py OUT_DIR

Writes OUT_DIR/<convention>.bvh and OUT_DIR/<convention>.fbx for each convention below and
OUT_DIR/rigs.json: for each character, the bone every t2m-22 joint should map to (the test
compares troupe's mapping with it) and, for the FBX file, where Blender puts every bone's head
in each frame of a short animation (metres, Blender's Z up), which troupe's FBX reader must
reproduce. Every
character is the same body (1.75 m, standing, facing -Y, Blender's Z up); what differs is how
it is named and posed at rest and the exporter's scale:

- `rigify`: Rigify's deform bones (`DEF-spine.003`, `DEF-upper_arm.L`, twist bones `.001`);
- `mixamo`: Mixamo's `mixamorig:` names;
- `unreal`: Unreal's mannequin (`pelvis`, `spine_01`, `clavicle_l`, `ball_l`, a `root` bone on
  the floor), exported in centimetres;
- `a_pose`: Mixamo's names, the arms 45 degrees down at rest;
- `blender_default`: the names Blender gives bones extruded one after the other (`Bone`,
  `Bone.001`, ...), which say nothing.

Blender's BVH exporter writes armature space as it is, Z up: every BVH file here stands along
Z. The FBX files are written as Blender's exporter is used for engines (Y up, metres), but for
`unreal`, written Z up in centimetres, as Unreal's own files are.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import bpy

# The body: t2m-22 joint, parent, head position (metres, Z up, facing -Y, its left at +X).
BODY = [
    ("pelvis", None, (0.0, 0.0, 0.95)),
    ("spine1", "pelvis", (0.0, 0.0, 1.06)),
    ("spine2", "spine1", (0.0, 0.01, 1.19)),
    ("spine3", "spine2", (0.0, 0.01, 1.33)),
    ("neck", "spine3", (0.0, 0.0, 1.50)),
    ("head", "neck", (0.0, -0.01, 1.60)),
    ("left_collar", "spine3", (0.03, 0.0, 1.45)),
    ("left_shoulder", "left_collar", (0.17, 0.02, 1.45)),
    ("left_elbow", "left_shoulder", (0.45, 0.03, 1.45)),
    ("left_wrist", "left_elbow", (0.70, 0.02, 1.45)),
    ("left_hip", "pelvis", (0.10, 0.0, 0.91)),
    ("left_knee", "left_hip", (0.10, -0.01, 0.50)),
    ("left_ankle", "left_knee", (0.10, 0.02, 0.08)),
    ("left_foot", "left_ankle", (0.10, -0.11, 0.02)),
]
for name, parent, (x, y, z) in list(BODY):
    if name.startswith("left_"):
        BODY.append((name.replace("left_", "right_"), (parent or "").replace("left_", "right_") or None, (-x, y, z)))

# Where each leaf bone's tail points (its end site): a hand, a toe, the top of the head.
TAILS = {"head": (0.0, -0.01, 1.75), "left_foot": (0.10, -0.17, 0.02)}

SIDES = {"L": ("left", "Left", "l"), "R": ("right", "Right", "r")}


def named(convention: str) -> dict[str, str]:
    """Each body joint's bone name in `convention`."""
    names = {}
    for side, (body, mixamo, _) in SIDES.items():
        low = SIDES[side][2]
        rigify = {"collar": "shoulder", "shoulder": "upper_arm", "elbow": "forearm", "wrist": "hand",
                  "hip": "thigh", "knee": "shin", "ankle": "foot", "foot": "toe"}
        mix = {"collar": "Shoulder", "shoulder": "Arm", "elbow": "ForeArm", "wrist": "Hand",
               "hip": "UpLeg", "knee": "Leg", "ankle": "Foot", "foot": "ToeBase"}
        unreal = {"collar": "clavicle", "shoulder": "upperarm", "elbow": "lowerarm", "wrist": "hand",
                  "hip": "thigh", "knee": "calf", "ankle": "foot", "foot": "ball"}
        for part in rigify:
            joint = f"{body}_{part}"
            names[joint] = {
                "rigify": f"DEF-{rigify[part]}.{side}",
                "mixamo": f"mixamorig:{mixamo}{mix[part]}",
                "a_pose": f"mixamorig:{mixamo}{mix[part]}",
                "unreal": f"{unreal[part]}_{low}",
            }.get(convention, "")
    centre = {
        "rigify": ["DEF-spine", "DEF-spine.001", "DEF-spine.002", "DEF-spine.003", "DEF-spine.004",
                   "DEF-spine.006"],
        "mixamo": ["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2",
                   "mixamorig:Neck", "mixamorig:Head"],
        "unreal": ["pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head"],
    }
    centre["a_pose"] = centre["mixamo"]
    for joint, name in zip(["pelvis", "spine1", "spine2", "spine3", "neck", "head"], centre.get(convention, [])):
        names[joint] = name
    if convention == "blender_default":
        # Extruded in the order a person builds a body: up the spine, then each limb.
        for k, (joint, _, _) in enumerate(BODY):
            names[joint] = "Bone" if k == 0 else f"Bone.{k:03d}"
    return names


def build(convention: str) -> tuple[bpy.types.Object, dict[str, str]]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    names = named(convention)
    data = bpy.data.armatures.new(convention)
    rig = bpy.data.objects.new(convention, data)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    heads = {joint: head for joint, _, head in BODY}
    if convention == "a_pose":
        # Each arm turned 45 degrees down about the forward axis, at the shoulder.
        c = s = math.sqrt(0.5)
        for side, sign in (("left", 1.0), ("right", -1.0)):
            sx, _, sz = heads[f"{side}_shoulder"]
            for part in ("elbow", "wrist"):
                x, y, z = heads[f"{side}_{part}"]
                dx, dz = x - sx, z - sz
                heads[f"{side}_{part}"] = (sx + c * dx + sign * s * dz, y, sz - sign * s * dx + c * dz)
    # The child each bone points at (the spine's, where the hips and chest branch).
    aims = {"pelvis": "spine1", "spine3": "neck"}
    children: dict[str, list[str]] = {}
    for joint, parent, _ in BODY:
        if parent:
            children.setdefault(parent, []).append(joint)
    bones = {}
    for joint, parent, _ in BODY:
        bone = data.edit_bones.new(names[joint])
        bone.head = heads[joint]
        kids = children.get(joint, [])
        if kids:
            bone.tail = heads[aims.get(joint, kids[0])]
        elif joint.endswith("_wrist"):  # the hand continues the forearm
            ex, ey, ez = heads[joint.replace("wrist", "elbow")]
            x, y, z = heads[joint]
            bone.tail = (x + (x - ex) * 0.4, y + (y - ey) * 0.4, z + (z - ez) * 0.4)
        else:
            tail = TAILS[joint.replace("right_", "left_")]
            bone.tail = (-tail[0], tail[1], tail[2]) if joint.startswith("right_") else tail
        bone.use_connect = False
        if parent:
            bone.parent = bones[parent]
        bones[joint] = bone
    if convention == "rigify":
        # Rigify's deform limbs are split in two: the second half, `.001`, is a twist bone.
        for joint in ("left_shoulder", "left_elbow", "left_hip", "left_knee",
                      "right_shoulder", "right_elbow", "right_hip", "right_knee"):
            upper = bones[joint]
            kids = [b for b in upper.children]
            twist = data.edit_bones.new(upper.name + ".001")
            middle = (upper.head + upper.tail) / 2
            twist.head, twist.tail = middle, upper.tail.copy()
            upper.tail = middle
            twist.parent = upper
            for kid in kids:
                kid.parent = twist
    if convention == "unreal":
        # Unreal's skeletons hang from a `root` bone on the floor.
        root = data.edit_bones.new("root")
        root.head, root.tail = (0.0, 0.0, 0.0), (0.0, 0.0, 0.3)
        bones["pelvis"].parent = root
    bpy.ops.object.mode_set(mode="OBJECT")
    return rig, names


def animate(rig: bpy.types.Object, names: dict[str, str]) -> list[dict[str, list[float]]]:
    """Four frames of motion: the root walks forward and turns, the spine twists, an elbow and a
    knee bend. Returns each frame's bone heads in world space (metres, Z up)."""
    keys = {"pelvis": (0.0, 0.0, 0.3), "spine2": (0.0, 0.4, 0.0), "left_elbow": (0.9, 0.0, 0.0),
            "right_knee": (0.7, 0.0, 0.0)}
    for frame in range(1, 5):
        share = (frame - 1) / 3
        for joint, (x, y, z) in keys.items():
            bone = rig.pose.bones[names[joint]]
            bone.rotation_mode = "XYZ"
            bone.rotation_euler = (x * share, y * share, z * share)
            bone.keyframe_insert("rotation_euler", frame=frame)
        root = rig.pose.bones[names["pelvis"]]
        root.location = (0.0, 0.05 * (frame - 1) / bpy.context.scene.unit_settings.scale_length, 0.0)
        root.keyframe_insert("location", frame=frame)
    metres = bpy.context.scene.unit_settings.scale_length
    heads = []
    for frame in range(1, 5):
        bpy.context.scene.frame_set(frame)
        heads.append({b.name: [v * metres for v in rig.matrix_world @ b.head] for b in rig.pose.bones})
    return heads


def skin(rig: bpy.types.Object, names: dict[str, str]) -> None:
    """A box around the hips, bound to the hips bone (so the exporter writes a bind pose), selected
    with the armature."""
    mesh = bpy.data.meshes.new("body")
    s = 0.1
    corners = [(x, y, 0.95 + z) for x in (-s, s) for y in (-s, s) for z in (-s, s)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(corners, [], faces)
    body = bpy.data.objects.new("body", mesh)
    bpy.context.scene.collection.objects.link(body)
    group = body.vertex_groups.new(name=names["pelvis"])
    group.add(list(range(8)), 1.0, "REPLACE")
    body.parent = rig
    body.modifiers.new("armature", "ARMATURE").object = rig
    body.select_set(True)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    expected = {}
    for convention, scale in (("rigify", 1.0), ("mixamo", 1.0), ("unreal", 100.0), ("a_pose", 1.0),
                              ("blender_default", 1.0)):
        rig, names = build(convention)
        bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 3
        bpy.ops.object.select_all(action="DESELECT")
        rig.select_set(True)
        path = out / f"{convention}.bvh"
        bpy.ops.export_anim.bvh(filepath=str(path), global_scale=scale, frame_start=1, frame_end=3)
        if convention == "unreal":
            # Z up in centimetres: the scene's unit is a centimetre, the body 175 of them tall.
            bpy.context.scene.unit_settings.scale_length = 0.01
            rig.scale = (100.0, 100.0, 100.0)
            bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
        heads = animate(rig, names)
        bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 4
        if convention == "mixamo":
            # A skinned body, as Mixamo's characters have: the file then holds a bind pose,
            # which is the rest pose, whatever frame the exporter stands on.
            skin(rig, names)
        else:
            # No bind pose: the bones' transforms at export are the rest pose (frame 1's).
            bpy.context.scene.frame_set(1)
        fbx = out / f"{convention}.fbx"
        types = {"ARMATURE", "MESH"}
        if convention == "unreal":
            bpy.ops.export_scene.fbx(filepath=str(fbx), use_selection=True, object_types=types,
                                     axis_up="Z", axis_forward="-Y", apply_unit_scale=True,
                                     apply_scale_options="FBX_SCALE_NONE", global_scale=1.0, bake_anim=True)
        else:
            bpy.ops.export_scene.fbx(filepath=str(fbx), use_selection=True, object_types=types,
                                     bake_anim=True)
        # From the toes (2 cm up) or Unreal's root bone (on the floor) to the top of the head.
        height = 1.75 if convention == "unreal" else 1.73
        expected[convention] = {"file": path.name, "units": "cm" if scale == 100.0 else "m", "height": height,
                                "bones": {joint: names[joint] for joint, _, _ in BODY},
                                "fbx": fbx.name, "fbx_heads": heads}
    (out / "rigs.json").write_text(json.dumps(expected, indent=1))
    print(f"wrote {len(expected)} characters to {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
