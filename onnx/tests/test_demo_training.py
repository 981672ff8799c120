"""The demo trainer's torch side (needs torch; run by `cargo test --test export_reproducible`
where it is installed, or `python3 -m pytest onnx/tests/test_demo_training.py`): a stage stopped
at a checkpoint and started again trains exactly as one that never stopped; recipe v3's
per-token conditions (the partner's placement fed back) in one causal pass are what a stream of
cached steps computes; a model widened for them starts as the one it came from."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from troupe_onnx.armflow.reference import Armflow  # noqa: E402
from troupe_onnx.demo import dataset, feedback, partners, rules, sources, train  # noqa: E402


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


def tiny(recipe_name: str) -> dict:
    """A recipe's model at v1's size (fast), with the recipe's conditioning."""
    recipe = json.loads(json.dumps(train.RECIPES[recipe_name]))
    recipe["model"] = train.RECIPES["v1"]["model"] | {"feedback": recipe["model"].get("feedback", False)}
    return recipe


@pytest.fixture(scope="module")
def actor():
    return sources.y_up(np.load(partners.CLIP)[:: partners.STRIDE])


@pytest.mark.parametrize("recipe_name", ["v1", "v3"])
def test_a_stopped_stage_resumed_equals_one_that_never_stopped(tmp_path, actor, recipe_name):
    torch.set_num_threads(1)
    pairs = dataset.build_pairs([sources.Clip("cmu", "demo", actor, "train")], speeds=(1.0,), mirror=(False,))
    recipe = tiny(recipe_name)
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


def test_feedback_is_the_partners_placement_relative_to_the_actor(actor):
    partner = rules.partner(actor, "keep-away", sources.FPS)
    got = feedback.of(torch.from_numpy(partner), torch.from_numpy(actor)).numpy()
    assert got.shape == (len(actor), feedback.DIMS)
    np.testing.assert_array_equal(got[:, 0], 1.0)
    np.testing.assert_allclose(got[:, 1:3], partner[:, 0, [0, 2]] - actor[:, 0, [0, 2]], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(got[:, 1:3], axis=-1), 2.0, atol=1e-6)  # the leash
    np.testing.assert_allclose(got[:, 3:], rules.heading(partner), atol=1e-9)  # the rules' facing


def test_token_conditions_feed_each_token_the_frame_before_it():
    frames = torch.randn(2, 12, 22, 3, dtype=torch.float64)
    actor = torch.randn(2, 12, 22, 3, dtype=torch.float64)
    onehot = torch.tensor([[1.0, 0, 0], [0, 0, 1.0]], dtype=torch.float64)
    conds = feedback.token_conditions(onehot, frames, actor, 4)
    assert conds.shape == (2, 3, 3 + feedback.DIMS)
    torch.testing.assert_close(conds[..., :3], onehot[:, None].expand(2, 3, 3))
    assert torch.equal(conds[:, 0, 3:], torch.zeros(2, feedback.DIMS, dtype=torch.float64))  # no frame yet
    for k in (1, 2):
        torch.testing.assert_close(conds[:, k, 3:], feedback.of(frames[:, 4 * k - 1], actor[:, 4 * k - 1]))


def test_per_token_conditions_in_one_causal_pass_are_a_stream_of_cached_steps():
    torch.manual_seed(0)
    cfg = train.demo_config(tiny("v3"))
    model = Armflow(cfg).eval()
    for p in model.parameters():  # trained-looking weights: the condition's columns matter
        p.data.normal_(0.0, 0.05)
    b, n, d = 2, 6, cfg.latent_dim
    za, zb = torch.randn(b, n, d), torch.randn(b, n, d)
    conds = torch.randn(b, n, cfg.cond_dim)
    arnet = model.armflow.arnet
    with torch.no_grad():
        whole = train.causal_context(model, za, zb, torch.zeros(b, dtype=torch.long), arnet.modulation(conds))
        h = cfg.heads
        past = [(torch.zeros(b, h, 0, cfg.head_dim), torch.zeros(b, h, 0, cfg.head_dim))] * cfg.layers
        for j in range(n):
            token = model.armflow.start_token.expand(b, 1, -1) if j == 0 else torch.cat([za[:, j - 1 : j], zb[:, j - 1 : j]], -1)
            c, new = arnet.step(token, torch.full((b, 1), j), arnet.modulation(conds[:, j]), past)
            past = [tuple(torch.cat([o, x], 2) for o, x in zip(kv, nkv)) for kv, nkv in zip(past, new)]
            torch.testing.assert_close(c.reshape(b, -1), whole[:, j], atol=1e-5, rtol=1e-5)
        # one condition for every token is the stream-wide modulation
        same = conds[:, :1].expand(b, n, -1)
        torch.testing.assert_close(
            train.causal_context(model, za, zb, torch.zeros(b, dtype=torch.long), arnet.modulation(same)),
            train.causal_context(model, za, zb, torch.zeros(b, dtype=torch.long), arnet.modulation(conds[:, 0])),
        )


def test_a_model_widened_for_feedback_starts_as_the_one_it_came_from():
    torch.manual_seed(0)
    narrow = Armflow(train.demo_config(tiny("v2"))).eval()
    for p in narrow.parameters():
        p.data.normal_(0.0, 0.05)
    wide = Armflow(train.demo_config(tiny("v3"))).eval()
    wide.load_state_dict(train.widened(narrow.state_dict(), wide.state_dict()))
    onehot = torch.eye(3)
    fed = torch.cat([onehot, torch.randn(3, feedback.DIMS)], -1)
    with torch.no_grad():
        torch.testing.assert_close(wide.armflow.arnet.modulation(fed), narrow.armflow.arnet.modulation(onehot))
