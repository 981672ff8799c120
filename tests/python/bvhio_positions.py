"""World joint positions of a BVH file as the independent `bvhio` package computes them.

    python3 tests/python/bvhio_positions.py FILE.bvh OUT.npy [MAX_FRAMES]

Writes float64 [frames, joints, 3] in the file's units (joints in file order) and prints the
joint names as JSON. Used by tests/bvh.rs to check troupe's BVH reader and writer.
"""

import json
import sys

import bvhio
import numpy as np


def main() -> None:
    path, out = sys.argv[1], sys.argv[2]
    limit = int(sys.argv[3]) if len(sys.argv) > 3 else None
    root = bvhio.readAsHierarchy(path)
    layout = root.layout()
    frames = len(root.Keyframes)
    if limit is not None:
        frames = min(frames, limit)
    positions = np.zeros((frames, len(layout), 3))
    for f in range(frames):
        root.loadPose(f)
        for joint, index, _ in layout:
            p = joint.PositionWorld
            positions[f, index] = (p.x, p.y, p.z)
    np.save(out, positions)
    print(json.dumps([joint.Name for joint, _, _ in layout]))


if __name__ == "__main__":
    main()
