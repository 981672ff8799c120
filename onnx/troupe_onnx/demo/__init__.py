"""The trained demo model: real mocap, rule-defined partners, ARMFlow trained from scratch.

`sources.py` fetches the motion capture, `rules.py` defines the partners, `dataset.py` turns them
into training windows, `train.py` trains the VAE and then ARMFlow, `evaluate.py` streams held-out
clips through troupe and measures the reactor against the rule, `diagnose.py` measures a
checkpoint's next token given the true past. `DATA.md` records the data.
"""

# `onnx/cli.py demo COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "train": ("train", "train the demo ARMFlow (VAE, then flow) on real mocap with rule partners (torch)"),
    "export": ("export", "the trained checkpoint as the armflow-demo bundle, with goldens (torch)"),
    "partners": ("partners", "the rules' partners of the default actor clip, for the demo and tests (numpy)"),
    "evaluate": ("evaluate", "stream held-out mocap through troupe; error against the rules and baselines (numpy)"),
    "diagnose": ("diagnose", "a checkpoint's next-token error given the true past, per rule (torch)"),
}
