"""The demo model's data side (numpy only): the partner rules, the training windows, and the
committed partners of the default clip that the demo and tests/demo.rs measure against."""

import numpy as np
import pytest

from troupe_onnx.demo import dataset, partners, rules, sources
from troupe_onnx.motion import intergen
from troupe_onnx.motion.skeleton import t2m22

NAMES = t2m22().names


@pytest.fixture(scope="module")
def actor():
    """The default clip at 30 fps, +Y up, floor at 0."""
    return sources.y_up(np.load(partners.CLIP)[:: partners.STRIDE])


def test_committed_partners_are_what_the_rules_give():
    made = partners.partners(np.load(partners.CLIP))
    for rule in rules.RULES:
        committed = np.load(partners.path(rule))
        assert committed.dtype == np.float32 and committed.shape == (240, 22, 3)
        np.testing.assert_allclose(committed, made[rule], atol=1e-6, err_msg=rule)


@pytest.mark.parametrize("rule", rules.RULES)
def test_rules_are_causal(actor, rule):
    base = rules.partner(actor, rule)
    changed = actor.copy()
    changed[120:] += np.random.default_rng(0).normal(0, 0.3, changed[120:].shape)
    other = rules.partner(changed, rule)
    np.testing.assert_array_equal(base[:120], other[:120])
    assert not np.allclose(base[120:], other[120:])


def roots(p):
    return p[:, 0, [0, 2]]


def test_mirror_reflects_the_delayed_actor_through_a_plane_in_front(actor):
    lag = round(rules.PARAMETERS["mirror"].delay_s * 30)
    out = rules.partner(actor, "mirror")
    t = 200
    past = actor[t - lag]
    f = rules.heading(past[None])[0]
    # The reflection through the plane 0.6 m in front of the delayed actor, labels swapped.
    normal = np.array([f[0], 0.0, f[1]])
    plane = past[0] * np.array([1, 0, 1]) + 0.6 * normal
    reflected = past - 2 * ((past - plane) @ normal)[:, None] * normal
    reflected = reflected[rules.mirror_permutation()]
    reflected[:, 1] -= rules.support_height(actor[: t - lag + 1], 30)[-1]
    np.testing.assert_allclose(out[t], reflected, atol=1e-9)
    assert out[t, NAMES.index("left_hip")][0] != pytest.approx(past[NAMES.index("left_hip")][0])


def test_partners_stand_where_the_rules_say(actor):
    mirror, follow, keep = (rules.partner(actor, r) for r in rules.RULES)
    gap = lambda p, q: np.linalg.norm(roots(p) - roots(q), axis=-1)  # noqa: E731
    lag = lambda r: round(rules.PARAMETERS[r].delay_s * 30)  # noqa: E731
    delayed = lambda r: rules.delayed(actor, lag(r))  # noqa: E731
    np.testing.assert_allclose(gap(mirror, delayed("mirror")), 1.2, atol=1e-9)
    np.testing.assert_allclose(gap(follow, delayed("follow")), 1.5, atol=1e-9)
    # keep-away: 2 m from the actor's current root except while it catches up at its top speed
    assert np.median(gap(keep, actor)) == pytest.approx(2.0, abs=1e-6)
    assert gap(keep, actor).min() > 1.0
    step = np.linalg.norm(np.diff(roots(keep), axis=0), axis=-1)
    assert step.max() <= rules.KEEP_AWAY_MAX_SPEED / 30 + 1e-9
    # mirror and keep-away face the actor; follow faces the way the actor did
    for p in (mirror, keep):
        to_actor = roots(actor) - roots(p)
        to_actor /= np.linalg.norm(to_actor, axis=-1, keepdims=True)
        assert np.mean(np.sum(rules.heading(p) * to_actor, axis=-1) > 0.5) > 0.9
    np.testing.assert_allclose(rules.heading(follow), rules.heading(delayed("follow")), atol=1e-9)


def test_partners_stay_on_the_floor_when_the_actor_stands_on_a_box(actor):
    raised = actor.copy()
    raised[100:, :, 1] += 0.5  # the actor steps onto a 0.5 m box at frame 100
    for rule in rules.RULES:
        low = rules.partner(raised, rule)[130:, :, 1].min(axis=1)
        assert low.max() < 0.15 and low.min() > -0.05, rule


def test_features_of_canonical_positions_are_intergens(actor):
    z_up = np.load(partners.CLIP)[:: partners.STRIDE]
    want, _, _ = intergen.process_motion(z_up)
    canonical, _, _, _ = intergen.canonicalise(z_up)
    np.testing.assert_allclose(dataset.features(canonical), want, atol=1e-5)


def test_a_stream_start_window_is_placed_as_troupe_places_a_stream(actor):
    pair = dataset.Pair("cmu/test", 0, dataset.features(actor), dataset.features(rules.partner(actor, "mirror")))
    rng = np.random.default_rng(3)
    a, b, prefix, position = dataset.draw_window(pair, 64, rng, stream_start=True)
    assert prefix == 0 and position == 0 and a.shape == (64, 262)
    p = a[0, :66].reshape(22, 3)
    assert np.hypot(p[0, 0], p[0, 2]) < 1e-5  # root over the origin
    across = p[NAMES.index("right_hip")] - p[NAMES.index("left_hip")]
    assert across[0] < 0 and abs(across[2]) < 1e-5  # hips across X: facing +Z, left at +X
    # the partner moved with the actor: their distance is unchanged by the placement
    d_window = np.linalg.norm(a[:, :3] - b[:, :3], axis=-1)
    starts = [s for s in range(len(pair.actor) - 63) if np.allclose(pair.actor[s, 132:258], a[0, 132:258])]
    assert starts, "the window's rotations are the pair's"
    s = starts[0]
    d_pair = np.linalg.norm(pair.actor[s : s + 64, :3] - pair.partner[s : s + 64, :3], axis=-1)
    np.testing.assert_allclose(d_window, d_pair, atol=1e-5)


def test_mid_stream_windows_carry_history_and_a_later_position(actor):
    pair = dataset.Pair("cmu/test", 1, dataset.features(actor), dataset.features(rules.partner(actor, "follow")))
    a, b, prefix, position = dataset.draw_window(pair, 64, np.random.default_rng(4), stream_start=False)
    assert prefix == dataset.PREFIX_FRAMES and a.shape == (prefix + 64, 262) and b.shape == a.shape
    assert 1 <= position < dataset.MAX_POSITION
    root = a[prefix, [0, 2]]
    assert np.all(np.abs(root) <= dataset.MAX_OFFSET_M + 1e-5)
