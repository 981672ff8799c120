"""MAGNet's sampling reference without torch (`troupe_onnx.magnet`: schedule, matrices, DDIM,
guidance, tasks, transforms), checked against the numbers `docs/spec/magnet.md` states: the
schedule's test vector (§3.1), the level tables (§3.2), the released matrices' shapes (§4.5),
every task's network calls per run (§9) with a deterministic stub network, and the invariants
each task promises (given people stay given, clean tokens stay clean).

Run by `cargo test --test magnet_reference` (numpy only; CI runs it).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from troupe_onnx.magnet import tasks as T
from troupe_onnx.magnet.configs import RELEASED
from troupe_onnx.magnet.draws import RecordingDraws, SeededDraws
from troupe_onnx.magnet.guidance import GuidanceConfig, check_mode, mode_input, transform_smoothing_gradient
from troupe_onnx.magnet.matrices import ar_matrix, index_matrix, level_matrix, prune
from troupe_onnx.magnet.schedule import CLEAN, PURE_NOISE, Schedule, ddim_step, level_table, q_sample
from troupe_onnx.magnet.transforms import (
    compose, from_9d, inverse, quaternion_from_rotation, rotation_from_6d, rotation_to_6d, to_9d,
)

SCHED = Schedule.cosine()
LATENT = 8  # the stub's latent width: tokens are LATENT + 36 P wide


# --------------------------------------------------------------------------------------------
# Schedule and DDIM (§3)
# --------------------------------------------------------------------------------------------


def test_schedule_matches_the_test_vector():
    vector = {  # i: (abar, sqrt abar, sqrt(1 - abar)), §3.1
        0: (0.999958694, 0.999979377, 0.00642528012),
        19: (0.998252511, 0.999125838, 0.0418032706),
        99: (0.972092748, 0.985947609, 0.167054668),
        499: (0.493843585, 0.702740073, 0.711446702),
        979: (0.000971193018, 0.03116397, 0.999514282),
        998: (2.42876695e-06, 0.00155845017, 0.999998808),
    }
    for i, want in vector.items():
        got = (SCHED.abar[i], SCHED.sqrt_abar[i], SCHED.sqrt_one_minus_abar[i])
        np.testing.assert_allclose(got, want, rtol=2e-7, err_msg=f"row {i}")
    assert SCHED.abar[999] == 0.0 and SCHED.sqrt_abar[999] == 0.0 and SCHED.sqrt_one_minus_abar[999] == 1.0


def test_level_tables():
    assert list(level_table(50)) == [-1 + 20 * m for m in range(51)]
    assert list(level_table(30)) == [
        -1, 32, 65, 99, 132, 165, 199, 232, 265, 299, 332, 365, 399, 432, 465, 499, 532, 565, 599, 632, 665,
        699, 732, 765, 799, 832, 865, 899, 932, 965, 999,
    ]


def test_ddim_to_clean_returns_x0_and_keeps_unchanged_tokens():
    rng = np.random.default_rng(0)
    x, x0, z = (rng.standard_normal((2, 3, 2, 5)).astype(np.float32) for _ in range(3))
    k = np.array([[999, 999], [19, 39], [-1, 500]])
    k_next = np.array([[999, 979], [-1, 19], [-1, 480]])
    out = ddim_step(SCHED, x, x0, k, k_next, 1.0, z)
    np.testing.assert_array_equal(out[:, 0, 0], x[:, 0, 0])  # 999 -> 999 waits
    np.testing.assert_array_equal(out[:, 2, 0], x[:, 2, 0])  # clean stays
    np.testing.assert_allclose(out[:, 1, 0], x0[:, 1, 0], atol=1e-6)  # 19 -> -1 lands on x0
    # eta = 0: sqrt(a') x0 + sqrt(1 - a') eps, no noise
    det = ddim_step(SCHED, x, x0, k, k_next, 0.0, z)
    a = SCHED.abar[500 - 20]
    eps = (x[:, 2, 1] - SCHED.sqrt_abar[500] * x0[:, 2, 1]) / SCHED.sqrt_one_minus_abar[500]
    np.testing.assert_allclose(det[:, 2, 1], np.sqrt(a) * x0[:, 2, 1] + np.sqrt(1 - a) * eps, rtol=1e-5, atol=1e-6)


def test_q_sample_reads_row_999_for_clean_levels():
    x0 = np.ones((1, 2, 1, 3), np.float32)
    n = np.full((1, 2, 1, 3), 2.0, np.float32)
    out = q_sample(SCHED, x0, np.array([[CLEAN], [0]]), n)
    np.testing.assert_array_equal(out[0, 0], n[0, 0])  # sqrt(abar_999) = 0, sqrt(1 - abar_999) = 1


# --------------------------------------------------------------------------------------------
# Scheduling matrices (§4)
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name,kind,persons,group,context,rows,unpruned,stride,ar_rows", [
    ("dd100 joint", "causal_uncertainty", 2, 32, 8, 51, 51, 4, 51),
    ("partner prediction", "causal_uncertainty", 2, 2, 8, 58, 66, None, None),
    ("partner inpainting", "full_sequence", 2, 2, 8, 51, 51, None, None),
    ("turn taking", "causal_uncertainty", 2, 4, 8, 54, 58, 2, 51),
    ("trio", "causal_uncertainty", 3, 12, 8, 52, 54, 4, 51),
    ("pp2joint phase 2", "causal_uncertainty", 2, 2, 8, 58, 66, 2, 52),
])
def test_released_matrices_have_the_stated_shapes(name, kind, persons, group, context, rows, unpruned, stride, ar_rows):
    full = level_matrix(kind, 50, 16, persons, group, context, do_prune=False)
    m = level_matrix(kind, 50, 16, persons, group, context)
    assert (full.shape[0], m.shape[0]) == (unpruned, rows), name
    assert (m[:, : context * persons] == CLEAN).all()
    assert (m[-1] == CLEAN).all() and (m[0, context * persons:] == PURE_NOISE).all()
    if stride:
        a = ar_matrix(m, stride * persons)
        assert a.shape[0] == ar_rows, name
        assert (a[:, : -stride * persons] == CLEAN).all() and (a[-1] == CLEAN).all()


def test_pyramid_staggers_groups_by_one_step():
    idx = index_matrix("causal_uncertainty", 5, 6, 2)
    assert idx.shape == (8, 6)
    assert list(idx[0]) == [5] * 6
    assert list(idx[3]) == [2, 2, 3, 3, 4, 4]
    assert list(idx[-1]) == [0] * 6


def test_autoregressive_schedule_extremes():
    simultaneous = index_matrix("autoregressive", 4, 6, 2, offset_proportion=0.0)
    assert simultaneous.shape[0] == 5 and (simultaneous == simultaneous[:, :1]).all()
    sequential = index_matrix("autoregressive", 4, 6, 2, offset_proportion=1.0)
    assert sequential.shape[0] == 4 + 2 * 4 + 1
    assert list(sequential[4]) == [0, 0, 4, 4, 4, 4]


def test_prune_keeps_the_last_of_the_equal_leading_rows():
    m = np.array([[5, 5], [5, 5], [5, 4], [4, 3]])
    assert prune(m).tolist() == [[5, 5], [5, 4], [4, 3]]
    assert prune(np.array([[1, 1], [1, 1]])).shape == (2, 2)


# --------------------------------------------------------------------------------------------
# Tasks (§5) with a deterministic stub network (the spec's: x0 = 0.5 tanh(x) + 0.001 k)
# --------------------------------------------------------------------------------------------


class Stub:
    def __init__(self):
        self.calls = 0

    def __call__(self, x, k):
        self.calls += 1
        levels = np.broadcast_to(k[None, ..., None], x.shape).astype(np.float32)
        return (0.5 * np.tanh(x) + 0.001 * levels).astype(np.float32)


def identity_stats():
    z, o = np.zeros(9, np.float32), np.ones(9, np.float32)
    return T.TransformStats(z, o, z, o)


def clip_tokens(t, persons, seed=0):
    """Tokens whose transform slots hold plausible (normalised = raw) transforms."""
    rng = np.random.default_rng(seed)
    d = LATENT + 36 * persons
    x = rng.standard_normal((t, persons, d)).astype(np.float32)
    eye = np.array([1, 0, 0, 0, 1, 0, 0.1, 0, 0.2], np.float32)
    x[..., LATENT:] = np.tile(eye, (d - LATENT) // 9) + 0.01 * x[..., LATENT:]
    return x


class FastDraws:
    """numpy's generator: the sampler's draws in the same order, faster than troupe's portable
    one where only their count and shapes matter."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)

    def normal(self, shape):
        return self.rng.standard_normal(shape, dtype=np.float32)


def make_run(sampling, persons, stub, seed=1, portable=False):
    draws = RecordingDraws(SeededDraws(seed) if portable else FastDraws(seed))
    sampling = replace(sampling, guidance=replace(sampling.guidance, smoothing=None, foot_skating=None))
    run = T.Run(sampling, SCHED, stub, draws, identity_stats(), 16, persons, LATENT, np.zeros((persons, 10), np.float32))
    return run, draws


CALLS = {  # released config -> (network calls for the config's length, §5.12 / §9)
    "dd100": 500, "dd100_partner_prediction": 342, "dd100_turn_taking": 1806, "dd100_motion_control": 342,
    "dd100_partner_inpainting": 200, "dd100_inbetweening": 65, "dd100_pp2joint": 684 + 2199, "dd100_sync": 2709,
    "meta_trio": 801,
}


def run_released(name, stub, samples=1):
    cfg = replace(RELEASED[name], samples=samples)
    persons = 3 if name == "meta_trio" else 2
    run, draws = make_run(cfg, persons, stub)
    tc = cfg.context_tokens
    if cfg.task in ("joint", "agentic_turn_taking", "agentic_sync"):
        fn = {"joint": T.joint, "agentic_turn_taking": T.agentic_turn_taking, "agentic_sync": T.agentic_sync}[cfg.task]
        return fn(run, clip_tokens(tc, persons), np.ones((tc, persons), bool)), draws
    if cfg.task == "inbetweening":
        key_mask = np.zeros(16, bool)
        key_mask[[0, 15]] = True
        return T.inbetweening(run, clip_tokens(16, persons), key_mask), draws
    t_gt = {"dd100_partner_inpainting": 37, "dd100_pp2joint": 100}.get(name, 50)
    gt = clip_tokens(t_gt, persons)
    if cfg.task == "pp2joint":
        return T.pp2joint(run, gt, cfg.seq_len), draws
    fn = {"partner_prediction": T.partner_prediction, "motion_control_live": T.motion_control_live,
          "partner_inpainting": T.partner_inpainting}[cfg.task]
    return fn(run, gt), draws


@pytest.mark.parametrize("name", sorted(CALLS))
def test_released_configs_make_the_stated_number_of_network_calls(name):
    stub = Stub()
    out, draws = run_released(name, stub)
    assert stub.calls == CALLS[name]
    # one DDIM draw per call, plus the initial noise (two worlds: two; partner prediction: noise_a
    # first; pp2joint: both phases' initial noise)
    extra = {"agentic_turn_taking": 2, "agentic_sync": 2, "partner_prediction": 2, "pp2joint": 3}.get(RELEASED[name].task, 1)
    assert draws.count == stub.calls + extra
    assert np.isfinite(out).all()


def test_output_lengths():
    assert run_released("dd100", Stub())[0].shape[1] == 52  # 200 frames -> 52 tokens, not truncated
    assert run_released("meta_trio", Stub())[0].shape[1:3] == (76, 3)
    assert run_released("dd100_partner_inpainting", Stub())[0].shape[1] == 37
    assert run_released("dd100_pp2joint", Stub())[0].shape[1] == 100 - 8 + 100


def test_partner_prediction_returns_the_given_person_exactly():
    stub = Stub()
    cfg = replace(RELEASED["dd100_partner_prediction"], steps=6, samples=2)
    run, _ = make_run(cfg, 2, stub)
    gt = clip_tokens(30, 2, seed=4)
    out = T.partner_prediction(run, gt)
    np.testing.assert_array_equal(out[:, :, 0], np.broadcast_to(gt[:, 0], out[:, :, 0].shape))
    np.testing.assert_array_equal(out[:, :8, 1], np.broadcast_to(gt[:8, 1], out[:, :8, 1].shape))
    assert not np.allclose(out[:, 8:, 1], gt[8:, 1])


def test_joint_keeps_its_context_but_smooths_and_cleans_it():
    stub = Stub()
    cfg = replace(RELEASED["dd100"], steps=5, samples=2, seq_len=64, temporal_smoothing=None, update_history_transforms=False)
    run, _ = make_run(cfg, 2, stub)
    ctx = clip_tokens(8, 2, seed=5)
    out = T.joint(run, ctx, np.ones((8, 2), bool))
    np.testing.assert_array_equal(out[0, :8], ctx)


def test_motion_control_live_keeps_the_user_given_until_the_last_chunk():
    stub = Stub()
    cfg = replace(RELEASED["dd100_motion_control"], steps=5, temporal_smoothing=None, update_history_transforms=False)
    run, _ = make_run(cfg, 2, stub)
    gt = clip_tokens(30, 2, seed=6)
    out = T.motion_control_live(run, gt)
    np.testing.assert_array_equal(out[0, :, 0], gt[:, 0])


def test_inbetweening_keeps_its_key_tokens():
    stub = Stub()
    cfg = replace(RELEASED["dd100_inbetweening"], steps=5, temporal_smoothing=None)
    run, _ = make_run(cfg, 2, stub)
    keys = clip_tokens(16, 2, seed=7)
    mask = np.zeros(16, bool)
    mask[[0, 15]] = True
    out = T.inbetweening(run, keys, mask)
    np.testing.assert_array_equal(out[0, [0, 15]], keys[[0, 15]])


def test_seeded_runs_repeat_and_depend_on_the_seed():
    cfg = replace(RELEASED["dd100"], steps=3, samples=1, seq_len=64)
    outs = []
    for seed in (1, 1, 2):
        run, _ = make_run(cfg, 2, Stub(), seed=seed, portable=True)
        outs.append(T.joint(run, clip_tokens(8, 2), np.ones((8, 2), bool)))
    np.testing.assert_array_equal(outs[0], outs[1])
    assert not np.array_equal(outs[0], outs[2])


def test_postprocess_zeroes_heights_and_orthonormalises():
    stub = Stub()
    cfg = replace(RELEASED["meta_trio"], steps=3, samples=1, seq_len=64)
    run, _ = make_run(cfg, 3, stub)
    out = T.joint(run, clip_tokens(8, 3), np.ones((8, 3), bool))
    tr = out[..., LATENT:].reshape(out.shape[:3] + (-1, 9))
    # Heights are zeroed before `temporal` mode rebuilds frame 0 of each partner slot (slots
    # 4 and 8 of the 12 transforms) from chained transitions, which may tilt.
    rebuilt = [4, 8]
    np.testing.assert_allclose(np.delete(tr, rebuilt, axis=3)[..., 7], 0.0, atol=1e-6)
    r = rotation_from_6d(tr[..., :6])
    np.testing.assert_allclose(rotation_to_6d(r), tr[..., :6], atol=1e-5)


# --------------------------------------------------------------------------------------------
# Guidance (§6), numpy side
# --------------------------------------------------------------------------------------------


def test_transform_smoothing_gradient_is_the_losses_gradient():
    rng = np.random.default_rng(3)
    x0 = rng.standard_normal((2, 6, 2, LATENT + 72)).astype(np.float64)

    def loss(v):
        y = v[..., LATENT:]
        lap = y[:, :-2] - 2 * y[:, 1:-1] + y[:, 2:]
        return (lap**2).mean()

    grad = transform_smoothing_gradient(x0.astype(np.float32), LATENT)
    eps = 1e-6
    for idx in [(0, 0, 0, LATENT), (1, 3, 1, LATENT + 40), (0, 5, 0, LATENT + 71)]:
        plus, minus = x0.copy(), x0.copy()
        plus[idx] += eps
        minus[idx] -= eps
        assert abs((loss(plus) - loss(minus)) / (2 * eps) - grad[idx]) < 1e-6
    assert (grad[..., :LATENT] == 0).all()


def test_mask_modes():
    cfg = GuidanceConfig()
    x = np.ones((1, 16, 2, 4), np.float32)
    k = np.full((16, 2), 999)
    k[:8] = CLEAN
    draws = SeededDraws(0)
    full = mode_input("full", x, k, 16, draws, SCHED, cfg)
    assert not np.allclose(full[:, :8], 1.0) and np.array_equal(full[:, 8:], x[:, 8:])
    partial = mode_input("partial", x, k, 16, SeededDraws(0), SCHED, cfg)
    np.testing.assert_allclose(partial[:, :8], 0.5 * full[:, :8] + 0.5, rtol=1e-6)
    person = mode_input("person1", x, k, 16, SeededDraws(0), SCHED, cfg)
    assert np.array_equal(person[:, :, 0], x[:, :, 0]) and not np.allclose(person[:, :, 1], 1.0)
    others = mode_input("~person1", x, k, 16, SeededDraws(0), SCHED, cfg)
    assert np.array_equal(others[:, :, 1], x[:, :, 1])
    assert mode_input("clean", x, k, 16, draws, SCHED, cfg) is x
    with pytest.raises(ValueError):
        check_mode("person2", 2)


# --------------------------------------------------------------------------------------------
# Transforms (§0, §7.2)
# --------------------------------------------------------------------------------------------


def test_transforms_round_trip():
    rng = np.random.default_rng(8)
    t9 = rng.standard_normal((5, 9)).astype(np.float32)
    m = from_9d(t9)
    r = m[:, :3, :3]
    np.testing.assert_allclose(r @ np.swapaxes(r, 1, 2), np.broadcast_to(np.eye(3), r.shape), atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-5)
    np.testing.assert_allclose(from_9d(to_9d(m)), m, atol=1e-5)
    np.testing.assert_allclose(compose(inverse(m), m), np.broadcast_to(np.eye(4), m.shape), atol=1e-5)


def test_quaternions_of_known_rotations():
    half = np.sqrt(0.5)
    rz90 = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], np.float32)
    rx180 = np.diag([1, -1, -1]).astype(np.float32)
    np.testing.assert_allclose(quaternion_from_rotation(np.eye(3, dtype=np.float32)), [1, 0, 0, 0], atol=1e-7)
    np.testing.assert_allclose(quaternion_from_rotation(rz90), [half, 0, 0, half], atol=1e-6)
    q = quaternion_from_rotation(rx180)
    np.testing.assert_allclose(np.abs(q), [0, 1, 0, 0], atol=1e-6)


# --------------------------------------------------------------------------------------------
# troupe's frames -> MAGNet's features (§1.2)
# --------------------------------------------------------------------------------------------


def test_features_derived_from_frames_are_consistent():
    from troupe_onnx.magnet.motion import FRAME_DIM, canonical_frames, clip_from_frames

    rng = np.random.default_rng(11)
    f, p = 6, 3
    frames = np.zeros((f, p, FRAME_DIM), np.float32)
    frames[..., :136] = rng.standard_normal((f, p, 136))
    frames[..., 136:145] = rng.standard_normal((f, p, 9))
    clip = clip_from_frames(frames)
    world = from_9d(clip.world_canonical)
    # canonical frames: yaw only, on the floor, facing the root's x axis projected on the floor
    np.testing.assert_allclose(world[..., 1, :3], np.broadcast_to([0, 1, 0], world[..., 1, :3].shape), atol=1e-6)
    np.testing.assert_allclose(world[..., 1, 3], 0.0, atol=1e-6)
    root = from_9d(clip.world_root)
    ex = root[..., :3, 0]
    flat = ex * np.array([1, 0, 1])
    np.testing.assert_allclose(world[..., :3, 0], flat / np.linalg.norm(flat, axis=-1, keepdims=True), atol=1e-5)
    # chaining the transitions from frame 0 rebuilds every canonical frame
    chained = world[0]
    for t in range(1, f):
        chained = compose(chained, from_9d(clip.tm1_t[t]))
        np.testing.assert_allclose(chained, world[t], atol=1e-4)
    np.testing.assert_allclose(clip.tm1_t[0], np.broadcast_to([1, 0, 0, 0, 1, 0, 0, 0, 0], (p, 9)), atol=1e-6)
    # a partner's canonical frame seen from one's own; the root seen from one's canonical frame
    np.testing.assert_allclose(compose(world[:, 0], from_9d(clip.partner[:, 0, 1])), world[:, 2], atol=1e-4)
    np.testing.assert_allclose(compose(world[:, 2], from_9d(clip.partner[:, 2, 0])), world[:, 0], atol=1e-4)
    np.testing.assert_allclose(compose(world, from_9d(clip.canonical_root)), root, atol=1e-4)
    np.testing.assert_array_equal(clip.betas, frames[0, :, :10])
    assert canonical_frames(clip.world_root).shape == (f, p, 4, 4)
