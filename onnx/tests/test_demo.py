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


def test_committed_walk_and_its_partner_are_what_the_script_gives():
    walk = partners.walk(np.load(partners.CLIP))
    committed = np.load(partners.CLIP.parent / "cmu-playground-walk.npy")
    assert committed.dtype == np.float32 and committed.shape == (984, 22, 3)
    np.testing.assert_array_equal(committed, walk)
    np.testing.assert_allclose(np.load(partners.CLIP.parent / "cmu-playground-walk.mirror.npy"),
                               partners.partners(walk, stride=1)["mirror"], atol=1e-6)
    floor = walk[:, 0, :2]
    assert np.linalg.norm(floor - floor[0], axis=-1).max() > 10.0  # it walks far from its start


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
    # the partner is the rule started afresh at the window's first frame, moved with the actor:
    # their distance is unchanged by the placement
    d_window = np.linalg.norm(a[:, :3] - b[:, :3], axis=-1)
    starts = [s for s in range(len(pair.actor) - 63) if np.allclose(pair.actor[s, 132:258], a[0, 132:258])]
    assert starts, "the window's rotations are the pair's"
    s = starts[0]
    fresh = rules.partner(actor[s : s + 65], "mirror")
    d_fresh = np.linalg.norm(actor[s : s + 64, 0] - fresh[:64, 0], axis=-1)
    np.testing.assert_allclose(d_window, d_fresh, atol=1e-5)


def test_a_stream_start_window_starts_keep_away_on_its_leash_in_front(actor):
    # Mid-clip, the clip-long partner stands wherever the leash has taken it; a stream that
    # starts there starts its partner 2 m in front of the actor, as evaluation and the runtime do.
    pair = dataset.Pair("cmu/test", 2, dataset.features(actor), dataset.features(rules.partner(actor, "keep-away")))
    rng = np.random.default_rng(5)
    for _ in range(4):
        a, b, _, _ = dataset.draw_window(pair, 32, rng, stream_start=True)
        offset = b[0, [0, 2]] - a[0, [0, 2]]
        assert abs(np.hypot(*offset) - 2.0) < 1e-4
        assert offset[1] > 1.8, offset  # in front: the placed actor faces +Z


def test_mid_stream_windows_carry_history_and_a_later_position(actor):
    pair = dataset.Pair("cmu/test", 1, dataset.features(actor), dataset.features(rules.partner(actor, "follow")))
    a, b, prefix, position = dataset.draw_window(pair, 64, np.random.default_rng(4), stream_start=False)
    assert prefix == dataset.PREFIX_FRAMES and a.shape == (prefix + 64, 262) and b.shape == a.shape
    assert 1 <= position < dataset.MAX_POSITION
    root = a[prefix, [0, 2]]
    assert np.all(np.abs(root) <= dataset.MAX_OFFSET_M + 1e-5)


def test_an_actor_with_pauses_holds_still_and_keeps_all_its_motion(actor):
    rng = np.random.default_rng(3)
    paused = dataset.with_pauses(actor, rng)
    assert len(paused) > len(actor)
    still = np.all(np.abs(np.diff(paused, axis=0)) == 0.0, axis=(1, 2))
    assert still.sum() >= sources.FPS // 2  # at least one hold of 0.5 s
    moving = paused[np.concatenate([[True], ~still])]
    # Every frame of the clip is there, in order (holds only repeat frames).
    assert len(moving) >= len(actor) - 1 and np.allclose(moving[-1], actor[-1])


def test_chained_clips_continue_where_and_how_the_last_one_ended(actor):
    rng = np.random.default_rng(4)
    a, b = actor[:100], actor[150:]
    long = dataset.chained([a, b], rng, blend=8)
    assert len(long) == len(a) + 8 + len(b)
    np.testing.assert_array_equal(long[:100], a)
    # No jump anywhere: the largest root step is the clips' own.
    steps = np.linalg.norm(np.diff(long[:, 0], axis=0), axis=-1)
    assert steps.max() <= 1.5 * max(np.linalg.norm(np.diff(actor[:, 0], axis=0), axis=-1).max(), 0.05)
    # The second clip is the same motion, turned and moved rigidly, on the floor.
    second = long[108:]
    np.testing.assert_allclose(np.linalg.norm(second[:, 4] - second[:, 7], axis=-1),
                               np.linalg.norm(b[:, 4] - b[:, 7], axis=-1), atol=1e-9)
    np.testing.assert_allclose(second[..., 1], b[..., 1], atol=1e-9)


def test_more_augmentation_means_more_pairs_each_under_every_rule(actor):
    clip = sources.Clip("cmu", "demo", actor, "train")
    plain = dataset.build_pairs([clip], speeds=(1.0,), mirror=(False,))
    more = dataset.build_pairs([clip, clip], speeds=(0.8, 1.25), mirror=(False,), pauses=1, chains=1, seed=1)
    assert len(plain) == len(rules.RULES)
    assert len(more) == len(rules.RULES) * (2 * 2 + 2 + 1)
    assert sorted({p.rule for p in more}) == list(range(len(rules.RULES)))


def test_evaluation_measures_say_what_they_measure(actor):
    from troupe_onnx.demo import evaluate

    truth = rules.partner(actor, "mirror")
    assert evaluate.facing_error_deg(truth, truth) < 1e-6
    turned = truth.copy()
    turned[..., [0, 2]] *= -1  # turned 180 degrees about the origin's vertical
    assert evaluate.facing_error_deg(turned, truth) > 179.0
    assert evaluate.closest_m(actor, actor) == 0.0
    assert abs(evaluate.closest_m(actor, actor + np.array([0.3, 0.0, 0.4])) - 0.5) < 1e-9
    assert evaluate.jitter_cm(actor + np.array([1.0, 2.0, 3.0])) == pytest.approx(evaluate.jitter_cm(actor))
    still = np.repeat(actor[:1], 10, axis=0)
    assert evaluate.jitter_cm(still) == 0.0 and evaluate.foot_skate_cm(still) == 0.0
    assert evaluate.resample(actor, 30.0) is actor
    assert len(evaluate.resample(actor[:121], 60.0)) == 61
