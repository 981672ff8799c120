"""The demo trainer's torch side (needs torch; run by `cargo test --test export_reproducible`
where it is installed, or `python3 -m pytest onnx/tests/test_demo_training.py`): a stage stopped
at a checkpoint and started again trains exactly as one that never stopped; recipe v3's
per-token conditions (the partner's placement fed back) in one causal pass are what a stream of
cached steps computes; a model widened for them starts as the one it came from; the reference's
stream loop (the goldens') feeds back what training feeds back, and a bundle of such a model
states its feedback in the manifest."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from troupe_onnx.armflow import feedback  # noqa: E402
from troupe_onnx.armflow.reference import Armflow, StreamOptions, VaeWindows, clip_reference, stream_reference  # noqa: E402
from troupe_onnx.demo import dataset, partners, rules, sources, train  # noqa: E402


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


def feedback_model(seed: int = 0) -> Armflow:
    """Recipe v3's conditioning at v1's size, with trained-looking weights (every condition column,
    the fed-back ones included, matters)."""
    torch.manual_seed(seed)
    cfg = train.demo_config(tiny("v3"))
    cfg.latent_scale = 0.7
    model = Armflow(cfg).eval()
    for p in model.parameters():
        p.data.normal_(0.0, 0.05)
    return model


def test_the_stream_loop_feeds_back_what_training_feeds_back(actor):
    """`stream_reference` with feedback against the training's one causal pass over its own
    outputs: the reactor latents decoded in one pass give the frames; `token_conditions` of those
    frames and the input actor frames give each token's condition (token j: frame 4j - 1); the
    causal context under those conditions and one MeanFlow step from the noise give the contexts
    and the reactor latents the loop produced."""
    model = feedback_model()
    cfg, core, fpt = model.cfg, model.armflow, model.cfg.frames_per_token
    assert (cfg.cond_dim, cfg.caller_cond_dim, cfg.null_condition) == (8, 3, (1.0, 0.0, 0.0))
    f = dataset.features(actor)
    f = dataset.rigid(f, *dataset.placement_at(f[0]))
    n = 12
    frames_in = np.ascontiguousarray(f[: n * fpt + 2], np.float32)
    rng = np.random.default_rng(0)
    xi, eps = (rng.standard_normal((n, cfg.latent_dim)).astype(np.float32) for _ in range(2))
    onehot = rules.condition("keep-away")
    out = stream_reference(model, frames_in, xi, eps, StreamOptions(condition=onehot))
    a, b = torch.from_numpy(out["actor_latents"]), torch.from_numpy(out["reactor_latents"])
    with torch.no_grad():
        decoded = model.vae.decoder(b[None] / torch.tensor(cfg.latent_scale))[0]
        torch.testing.assert_close(torch.from_numpy(out["frames"]), decoded, atol=1e-5, rtol=1e-5)
        joints = lambda x: x[: n * fpt, :66].reshape(1, n * fpt, 22, 3).double()  # noqa: E731
        conds = feedback.token_conditions(torch.from_numpy(onehot)[None].double(), joints(decoded),
                                          joints(torch.from_numpy(frames_in)), fpt).float()
        assert out["feedback"].shape == (n, feedback.DIMS)
        np.testing.assert_array_equal(out["feedback"][0], 0.0)  # token 0: no frame yet
        np.testing.assert_array_equal(out["feedback"][1:, 0], 1.0)
        torch.testing.assert_close(torch.from_numpy(out["feedback"]), conds[0, :, 3:], atol=1e-5, rtol=1e-5)
        for j in (1, n - 1):  # the last frame of the token before, both people's
            last = j * fpt - 1
            want = feedback.of(decoded[last, :66].reshape(22, 3).double(),
                               torch.from_numpy(frames_in[last, :66]).reshape(22, 3).double())
            torch.testing.assert_close(torch.from_numpy(out["feedback"][j]), want.float(), atol=1e-5, rtol=1e-5)
        zero = torch.zeros(1, dtype=torch.long)
        contexts = train.causal_context(model, a[None], b[None], zero, core.arnet.modulation(conds))[0]
        torch.testing.assert_close(torch.from_numpy(out["contexts"]), contexts, atol=1e-5, rtol=1e-5)
        step = core.velocity(a, torch.from_numpy(eps), contexts, torch.zeros(n), torch.ones(n))
        torch.testing.assert_close(b, torch.from_numpy(eps) - step, atol=1e-5, rtol=1e-5)
        # Not vacuous: without the feedback the contexts would differ.
        blind = torch.cat([conds[..., :3], torch.zeros_like(conds[..., 3:])], dim=-1)
        unfed = train.causal_context(model, a[None], b[None], zero, core.arnet.modulation(blind))[0]
        assert (unfed[1:] - contexts[1:]).abs().max() > 1e-3
    # What the feedback loop cannot run: a decoder lookahead, the clip loop.
    with pytest.raises(ValueError, match="lookahead"):
        stream_reference(model, frames_in, xi, eps, StreamOptions(), VaeWindows(64, 0, 17, 1))
    with pytest.raises(ValueError, match="feedback"):
        clip_reference(model, frames_in, xi, eps[0], onehot)


def test_a_feedback_bundle_states_its_feedback_in_the_manifest(tmp_path):
    """The manifest's `condition` of a v3 bundle: the caller's 3 floats (labels, null) and the
    5 fed back; the conditioning graph reads all 8. The goldens carry each token's feedback.
    A bundle without feedback keeps its condition section as it was."""
    pytest.importorskip("onnx")
    from troupe_onnx.armflow import export as armflow_export
    from troupe_onnx.demo import export as demo_export

    model = feedback_model()
    record = {"recipe_name": "v3", "recipe": tiny("v3"), "latent_scale": model.cfg.latent_scale}
    ckpt = tmp_path / "armflow.pt"
    train.save(model, ckpt, record)
    out = tmp_path / "bundle"
    demo_export.export(ckpt, out, golden=True)
    manifest = json.loads((out / "troupe.json").read_text())
    labels = [{"name": r, "vector": rules.condition(r).tolist(), "about": demo_export.ABOUT[r]} for r in rules.RULES]
    assert manifest["condition"] == {
        "dim": 3, "feedback": {"kind": "partner_placement", "dim": 5}, "null": [1.0, 0.0, 0.0],
        "null_source": "label:mirror", "labels": labels,
    }
    assert manifest["graphs"]["conditioning"]["inputs"] == [{"name": "condition", "dtype": "float32", "shape": [1, 8]}]
    assert manifest["vae"]["decoder"]["lookahead_tokens"] == 0
    assert manifest["producer"]["training"] == record
    golden = out / "golden"
    assert np.load(golden / "default_condition.npy").shape == (3,)
    fed = np.load(golden / "default_feedback.npy")
    assert fed.shape == (armflow_export.GOLDEN_TOKENS, feedback.DIMS)
    np.testing.assert_array_equal(fed[0], 0.0)
    np.testing.assert_array_equal(fed[1:, 0], 1.0)
    plain = Armflow(train.demo_config(tiny("v2")))
    assert armflow_export.condition_manifest(plain) == {"dim": 3, "null": [1.0, 0.0, 0.0], "null_source": "vector"}


def test_feedback_reads_t2m22s_hips_and_shoulders():
    from troupe_onnx.armflow import feedback as fb
    from troupe_onnx.motion.skeleton import t2m22

    names = t2m22().names
    assert [fb._L_HIP, fb._R_HIP, fb._L_SHOULDER, fb._R_SHOULDER] == [
        names.index(n) for n in ("left_hip", "right_hip", "left_shoulder", "right_shoulder")
    ]


def test_diagnose_measures_a_checkpoint_against_its_vae(tmp_path, actor):
    from troupe_onnx.demo import diagnose

    torch.manual_seed(0)
    recipe = tiny("v3")
    cfg = train.demo_config(recipe)
    cfg.latent_scale = 0.8
    model = Armflow(cfg)
    path = tmp_path / "armflow.pt"
    train.save(model, path, {"recipe": recipe, "latent_scale": 0.8})
    loaded = diagnose.load(path)
    assert loaded.cfg.condition_feedback == "partner_placement"
    frames = diagnose.TOKENS * cfg.frames_per_token + 1
    window = actor[:frames]
    # The true partner tokens, as diagnose encodes them (placed as a stream starts).
    fa = dataset.features(window)
    fb = dataset.features(rules.partner(window, "keep-away", sources.FPS))
    placed = torch.from_numpy(dataset.rigid(fb, *dataset.placement_at(fa[0]))[None])
    with torch.no_grad():
        truth = loaded.vae.encoder(placed)[0][0] * cfg.latent_scale
    # A flow that lands on the true tokens has no error; one beside them has.
    loaded.armflow.velocity = lambda a, z, c, r, t: z - truth
    forced, vae = diagnose.window_errors(loaded, window, "keep-away")
    assert forced == 0.0 and np.isfinite(vae) and vae > 0.0
    loaded.armflow.velocity = lambda a, z, c, r, t: z - truth - 0.5
    assert diagnose.window_errors(loaded, window, "keep-away")[0] > 0.0
