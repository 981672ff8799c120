"""The demo trainer's torch side (needs torch; run by `cargo test --test export_reproducible`
where it is installed, or `python3 -m pytest onnx/tests/test_demo_training.py`): a stage stopped
at a checkpoint and started again trains exactly as one that never stopped."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from troupe_onnx.armflow.reference import Armflow  # noqa: E402
from troupe_onnx.demo import dataset, partners, sources, train  # noqa: E402


class Stop(Exception):
    pass


class StopAfter(train.Resumable):
    """Saves like `Resumable`, then stops the run after step `stop` (a machine going away)."""

    def __init__(self, path, every, log, stop):
        super().__init__(path, every, log)
        self.stop = stop

    def step_done(self, step, model, opt, rng, hist):
        super().step_done(step, model, opt, rng, hist)
        if step + 1 == self.stop:
            raise Stop


def test_a_stopped_stage_resumed_equals_one_that_never_stopped(tmp_path):
    torch.set_num_threads(1)
    actor = sources.y_up(np.load(partners.CLIP)[:: partners.STRIDE])
    pairs = dataset.build_pairs([sources.Clip("cmu", "demo", actor, "train")], speeds=(1.0,), mirror=(False,))
    recipe = json.loads(json.dumps(train.RECIPES["v1"]))
    recipe["vae"] |= {"steps": 6, "batch": 4, "frames": 16}
    recipe["flow"] |= {"steps": 6, "batch": 2, "tokens": 4}
    logs = []

    def fresh(seed: int):
        torch.manual_seed(seed)
        return Armflow(train.demo_config(recipe)), np.random.default_rng(seed)

    for stage, run in (("vae", train.train_vae), ("flow", train.train_flow)):
        model, rng = fresh(1)
        whole = run(model, pairs, recipe, rng, logs.append)
        want = {k: v.clone() for k, v in model.state_dict().items()}

        path = tmp_path / f"{stage}.resume.pt"
        model, rng = fresh(1)
        with pytest.raises(Stop):
            run(model, pairs, recipe, rng, logs.append, StopAfter(path, 2, logs.append, stop=4))
        model, rng = fresh(99)  # a new process: other weights, other generators until resumed
        resumed = run(model, pairs, recipe, rng, logs.append, train.Resumable(path, 2, logs.append))
        assert any("resumed from" in line and "at step 4" in line for line in logs)
        for name, value in model.state_dict().items():
            assert torch.equal(value, want[name]), f"{stage}: {name} differs after resuming"
        assert resumed == whole
