"""An ASCII FBX 7.4 file of a standing body, written the way Autodesk's tools write ASCII FBX:
Z up, centimetres (`UnitScaleFactor` 1), 30 fps, each bone a `LimbNode` model with its rest
translation, and an animation stack whose one curve moves the hips 50 cm forward (along -Y, the
figure's front) over one second; the stack states only its end, so its span is its keys'.

    python3 tests/gltf/ascii_fbx.py tests/data/ascii_body.fbx

Plain Python, no dependencies: the committed file is its output (tests/rigs.rs reads it; Blender
cannot write ASCII FBX). The body is tests/gltf/blender_rigs.py's, with Mixamo's names.
"""

from __future__ import annotations

import sys
from pathlib import Path

# FBX time: 46186158000 ticks per second.
SECOND = 46186158000

BODY = [
    ("Hips", None, (0.0, 0.0, 0.95)),
    ("Spine", "Hips", (0.0, 0.0, 1.06)),
    ("Spine1", "Spine", (0.0, 0.01, 1.19)),
    ("Spine2", "Spine1", (0.0, 0.01, 1.33)),
    ("Neck", "Spine2", (0.0, 0.0, 1.50)),
    ("Head", "Neck", (0.0, -0.01, 1.60)),
    ("HeadTop_End", "Head", (0.0, -0.01, 1.75)),
    ("LeftShoulder", "Spine2", (0.03, 0.0, 1.45)),
    ("LeftArm", "LeftShoulder", (0.17, 0.02, 1.45)),
    ("LeftForeArm", "LeftArm", (0.45, 0.03, 1.45)),
    ("LeftHand", "LeftForeArm", (0.70, 0.02, 1.45)),
    ("LeftUpLeg", "Hips", (0.10, 0.0, 0.91)),
    ("LeftLeg", "LeftUpLeg", (0.10, -0.01, 0.50)),
    ("LeftFoot", "LeftLeg", (0.10, 0.02, 0.08)),
    ("LeftToeBase", "LeftFoot", (0.10, -0.11, 0.02)),
    ("LeftToe_End", "LeftToeBase", (0.10, -0.17, 0.02)),
]
for _name, _parent, (_x, _y, _z) in list(BODY):
    if _name.startswith("Left"):
        BODY.append((_name.replace("Left", "Right"), (_parent or "").replace("Left", "Right") or None,
                     (-_x, _y, _z)))


def main(out: Path) -> None:
    heads = {name: head for name, _, head in BODY}
    lines = [
        "; FBX 7.4.0 project file",
        "; Written by troupe's tests/gltf/ascii_fbx.py",
        "",
        "FBXHeaderExtension:  {",
        "\tFBXHeaderVersion: 1003",
        "\tFBXVersion: 7400",
        "}",
        "GlobalSettings:  {",
        "\tVersion: 1000",
        "\tProperties70:  {",
        '\t\tP: "UpAxis", "int", "Integer", "",2',
        '\t\tP: "UpAxisSign", "int", "Integer", "",1',
        '\t\tP: "FrontAxis", "int", "Integer", "",1',
        '\t\tP: "FrontAxisSign", "int", "Integer", "",-1',
        '\t\tP: "CoordAxis", "int", "Integer", "",0',
        '\t\tP: "CoordAxisSign", "int", "Integer", "",1',
        '\t\tP: "UnitScaleFactor", "double", "Number", "",1',
        '\t\tP: "TimeMode", "enum", "", "",6',
        "\t}",
        "}",
        "Objects:  {",
    ]
    connections = []
    ids = {}
    for k, (name, parent, head) in enumerate(BODY):
        model, attribute = 1000 + 2 * k, 1001 + 2 * k
        ids[name] = model
        base = heads[parent] if parent else (0.0, 0.0, 0.0)
        t = [round((h - b) * 100.0, 4) for h, b in zip(head, base)]
        lines += [
            f'\tNodeAttribute: {attribute}, "NodeAttribute::{name}", "LimbNode" {{',
            '\t\tTypeFlags: "Skeleton"',
            "\t}",
            f'\tModel: {model}, "Model::{name}", "LimbNode" {{',
            "\t\tVersion: 232",
            "\t\tProperties70:  {",
            f'\t\t\tP: "Lcl Translation", "Lcl Translation", "", "A",{t[0]},{t[1]},{t[2]}',
            "\t\t}",
            "\t}",
        ]
        connections.append(f'\tC: "OO",{attribute},{model}')
        connections.append(f'\tC: "OO",{model},{ids[parent] if parent else 0}')
    hips = [round(v * 100.0, 4) for v in heads["Hips"]]
    lines += [
        '\tAnimationStack: 9000, "AnimStack::walk", "" {',
        "\t\tProperties70:  {",
        f'\t\t\tP: "LocalStop", "KTime", "Time", "",{SECOND}',
        f'\t\t\tP: "ReferenceStop", "KTime", "Time", "",{SECOND}',
        "\t\t}",
        "\t}",
        '\tAnimationLayer: 9001, "AnimLayer::BaseLayer", "" {',
        "\t}",
        '\tAnimationCurveNode: 9002, "AnimCurveNode::T", "" {',
        "\t\tProperties70:  {",
        f'\t\t\tP: "d|X", "Number", "", "A",{hips[0]}',
        f'\t\t\tP: "d|Y", "Number", "", "A",{hips[1]}',
        f'\t\t\tP: "d|Z", "Number", "", "A",{hips[2]}',
        "\t\t}",
        "\t}",
        '\tAnimationCurve: 9003, "AnimCurve::", "" {',
        "\t\tDefault: 0",
        "\t\tKeyVer: 4008",
        f"\t\tKeyTime: *2 {{\n\t\t\ta: 0,{SECOND}\n\t\t}}",
        f"\t\tKeyValueFloat: *2 {{\n\t\t\ta: {hips[1]},{hips[1] - 50.0}\n\t\t}}",
        # Linear interpolation for every key (eInterpolationLinear, eTangentAuto).
        "\t\tKeyAttrFlags: *1 {\n\t\t\ta: 260\n\t\t}",
        "\t\tKeyAttrDataFloat: *4 {\n\t\t\ta: 0,0,0,0\n\t\t}",
        "\t\tKeyAttrRefCount: *1 {\n\t\t\ta: 2\n\t\t}",
        "\t}",
        "}",
    ]
    connections += [
        '\tC: "OO",9001,9000',
        '\tC: "OO",9002,9001',
        f'\tC: "OP",9002,{ids["Hips"]}, "Lcl Translation"',
        '\tC: "OP",9003,9002, "d|Y"',
    ]
    lines += ["Connections:  {", *connections, "}", ""]
    out.write_text("\n".join(lines))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
