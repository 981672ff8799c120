"""Blender (the `bpy` module, headless) imports a file troupe wrote and reports where each bone's
head (its joint) is, in glTF's axes (metres, +Y up), at the frames asked for.

    python blender_check.py gltf FILE.glb OUT.json FPS FRAME [FRAME...]
    python blender_check.py bvh FILE.bvh OUT.json FPS SCALE FRAME [FRAME...]
    python blender_check.py fbx FILE.fbx OUT.json FPS FRAME [FRAME...]
    python blender_check.py export FILE.bvh OUT.glb SCALE
    python blender_check.py render FILE.glb OUT.png FRAME

(`export`: Blender imports the BVH and exports its armature as glTF, a rig troupe did not write;
`render`: Blender's Workbench renders the imported file at a frame, 800 x 600, looking at the
bones' centre from the front.)

glTF: Blender's importer turns glTF's +Y up into its +Z up; BVH: the importer reads Y up
(`axis_up='Y'`, `axis_forward='-Z'`) and scales lengths by SCALE (file units to metres). Both
are turned back here: Blender (x, y, z) is glTF (x, z, -y). FBX: the importer's defaults, which
read the file's axes and unit from its settings (as a person importing it gets). Frames are
troupe's, from 0.
"""

import json
import sys

import bpy


def heads(frame, first):
    """Every pose bone's head in world space, glTF axes, keyed by the bone's name."""
    bpy.context.scene.frame_set(first + frame)
    out = {}
    for obj in bpy.context.scene.objects:
        if obj.type != "ARMATURE":
            continue
        for bone in obj.pose.bones:
            p = obj.matrix_world @ bone.head
            out[bone.name] = [p.x, p.z, -p.y]
    return out


def export(path, out_path, scale):
    """Blender's own glTF of a BVH file's armature (its rest pose and its motion)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_anim.bvh(filepath=path, axis_forward="-Z", axis_up="Y", global_scale=scale)
    bpy.ops.export_scene.gltf(filepath=out_path, export_format="GLB")


def render(path, out_path, frame):
    """A picture of the imported file at `frame`, as a person opening it in Blender sees it."""
    import math

    from mathutils import Vector

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 30
    bpy.ops.import_scene.gltf(filepath=path)
    scene.frame_set(frame)
    points = [o.matrix_world @ b.head for o in scene.objects if o.type == "ARMATURE" for b in o.pose.bones]
    centre = sum(points, Vector()) / len(points)
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = 800, 600
    scene.display.shading.color_type = "MATERIAL"
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    camera.location = centre + Vector((0.0, -6.0, 0.8))
    camera.rotation_euler = (math.radians(82), 0.0, 0.0)
    scene.camera = camera
    scene.render.filepath = out_path
    bpy.ops.render.render(write_still=True)


def main():
    if sys.argv[1] == "render":
        render(sys.argv[2], sys.argv[3], int(sys.argv[4]))
        return
    if sys.argv[1] == "export":
        export(sys.argv[2], sys.argv[3], float(sys.argv[4]))
        return
    kind, path, out_path, fps = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    rest = sys.argv[5:]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = fps
    if kind == "gltf":
        bpy.ops.import_scene.gltf(filepath=path)
        frames = [int(f) for f in rest]
        # The importer keys time 0 at frame 0 at the scene's frame rate.
        first = 0
    elif kind == "fbx":
        bpy.ops.import_scene.fbx(filepath=path)
        frames = [int(f) for f in rest]
        # The importer keys time 0 at frame 1 (its `anim_offset`).
        first = 1
    else:
        scale = float(rest[0])
        frames = [int(f) for f in rest[1:]]
        bpy.ops.import_anim.bvh(
            filepath=path,
            axis_forward="-Z",
            axis_up="Y",
            global_scale=scale,
            frame_start=1,
            use_fps_scale=False,
            rotate_mode="NATIVE",
        )
        first = 1
    report = {
        "blender": bpy.app.version_string,
        "armatures": sum(1 for o in scene.objects if o.type == "ARMATURE"),
        # (The glTF importer adds an "Icosphere" of its own to draw bones with.)
        "meshes": sum(1 for o in scene.objects if o.type == "MESH" and o.name != "Icosphere"),
        "objects": sorted(f"{o.type} {o.name}" for o in scene.objects),
        "frames": {str(f): heads(f, first) for f in frames},
    }
    with open(out_path, "w") as f:
        json.dump(report, f)


main()
