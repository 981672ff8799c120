"""The CMU skeleton of an ASF file as a troupe rig document, and the joint map naming its bones,
both as one JSON object {"rig": ..., "joint_map": ...} on stdout.

    PYTHONPATH=onnx python cmu_rig.py FILE.asf

Each bone is a joint where the bone starts (its parent's end; the root's children start at the
root), with the bone's own end as the end site of a bone without children. Rest pose: the ASF's
(every AMC value zero), Y up, in metres by CMU's convention (a unit is 1 / length inches).
"""

import json
import sys

import numpy as np

from troupe_onnx.motion.acclaim import read_asf

asf = read_asf(sys.argv[1])
scale = asf.cmu_metres_per_unit
joints = [{"name": "root", "parent": None, "offset": [float(v) * scale for v in asf.root_position]}]
for name in asf.order():
    bone = asf.bones[name]
    parent = bone.parent
    if parent == "root":
        offset = np.zeros(3)
    else:
        p = asf.bones[parent]
        offset = p.direction * p.length * scale
    joint = {"name": name, "parent": parent, "offset": [float(v) for v in offset]}
    if not bone.children:
        joint["end_site"] = [float(v) for v in bone.direction * bone.length * scale]
    joints.append(joint)

# Which bone starts where each t2m-22 joint is (the provenance of tests/data/mocap says which
# bone ends each joint is; a bone starts where its parent ends). CMU has no collar joint: the
# clavicles start at the top of the thorax, so the collars name no bone and are not driven.
joint_map = {
    "skeleton": "t2m22",
    "joints": {
        "pelvis": ["root"], "left_hip": ["lfemur"], "right_hip": ["rfemur"],
        "spine1": ["upperback"], "left_knee": ["ltibia"], "right_knee": ["rtibia"],
        "spine2": ["thorax"], "left_ankle": ["lfoot"], "right_ankle": ["rfoot"],
        "spine3": ["lowerneck"], "left_foot": ["ltoes"], "right_foot": ["rtoes"],
        "neck": ["upperneck"], "left_collar": ["(none)"], "right_collar": ["(none)"],
        "head": ["head"], "left_shoulder": ["lhumerus"], "right_shoulder": ["rhumerus"],
        "left_elbow": ["lradius"], "right_elbow": ["rradius"], "left_wrist": ["lwrist"],
        "right_wrist": ["rwrist"],
    },
}
print(json.dumps({"rig": {"name": "cmu-asf", "units": "m", "up": "y", "joints": joints}, "joint_map": joint_map}))
