"""The Python bindings through the real shared library (TROUPE_LIBRARY_PATH or the installed wheel)."""

import ctypes
import io
import re
import tarfile
import threading
from pathlib import Path

import numpy as np
import pytest

import troupe
from troupe import _native

REPO = Path(__file__).resolve().parents[3]
BUNDLE = REPO / "onnx" / "bundles" / "armflow-tiny"
GOLDEN = BUNDLE / "golden"


@pytest.fixture(scope="module")
def model():
    with troupe.Model(BUNDLE) as m:
        yield m


def actor(frames=64, dim=262):
    t = np.arange(frames, dtype=np.float32)[:, None]
    d = np.arange(dim, dtype=np.float32)[None, :]
    return (0.5 * np.sin(0.1 * t * (1 + d % 5) + d)).astype(np.float32)


def stream(session, frames, tick):
    outs = [session.step(frames[i : i + tick]) for i in range(0, len(frames), tick)]
    return np.concatenate(outs)


def test_version_and_abi():
    lib = _native.load()
    assert lib.troupe_abi_version() == _native.ABI_VERSION
    assert re.fullmatch(r"\d+\.\d+\.\d+", troupe.version())
    assert troupe.__version__ == troupe.version(), (troupe.__version__, troupe.version())


def test_every_header_function_has_a_prototype():
    header = (REPO / "include" / "troupe.h").read_text()
    # The deprecated 0.1 names (docs/ABI.md) need no prototype: the package uses today's.
    deprecated = set(re.findall(r'TROUPE_DEPRECATED\("[^"]*"\)[^;(]*\b(troupe_\w+)\(', header))
    assert len(deprecated) == 20, sorted(deprecated)
    declared = set(re.findall(r"\b(troupe_\w+)\(", header)) - deprecated
    assert declared, "no functions found in the header"
    missing = declared - set(_native.PROTOTYPES)
    assert not missing, f"functions without a ctypes prototype: {sorted(missing)}"
    assert set(_native.PROTOTYPES) <= declared, "prototypes for functions not in the header"


def test_struct_sizes_match_the_library():
    lib = _native.load()
    assert ctypes.sizeof(_native.SessionOptions) == lib.troupe_session_options_size()
    assert ctypes.sizeof(_native.GroupOptions) == lib.troupe_umf_options_size()


def test_queries(model):
    assert (model.frame_dim, model.fps, model.frames_per_token) == (262, 30, 4)
    assert (model.latency_frames, model.condition_dim, model.latent_dim) == (3, 32, 16)
    assert model.max_output_frames(37) == 40


def test_frames_come_out_a_token_at_a_time(model):
    with model.session(seed=3) as s:
        sizes = [s.step(f[None]).shape[0] for f in actor(12)]
    assert sizes == [0, 0, 0, 4] * 3


def test_chunking_reset_and_determinism(model):
    x = actor(80)
    with model.session(seed=5) as s:
        one = stream(s, x, 1)
        s.reset()
        assert np.array_equal(stream(s, x, 37), one)
    with model.session(seed=5) as s:
        assert np.array_equal(stream(s, x, 4), one)
    with model.session(seed=6) as s:
        assert not np.array_equal(stream(s, x, 4), one)
    assert one.shape == (80, 262) and np.isfinite(one).all()


def test_preallocated_output(model):
    x = actor(8)
    out = np.zeros((8, 262), np.float32)
    with model.session(seed=1) as s:
        got = s.step(x, out=out)
    assert got.base is out and got.shape == (8, 262) and np.abs(out).sum() > 0


def test_golden_parity_with_injected_noise(model):
    """The PyTorch reference's golden run, reproduced through the C ABI from Python."""
    xi, eps = np.load(GOLDEN / "default_xi.npy"), np.load(GOLDEN / "default_eps.npy")
    with model.session(condition=np.load(GOLDEN / "default_condition.npy")) as s:
        for a, r in zip(xi, eps):
            s.armflow.queue_noise(a, r)
        frames = s.step(np.load(GOLDEN / "actor.npy"))
    assert np.abs(frames - np.load(GOLDEN / "default_frames.npy")).max() <= 1e-4


def test_errors_are_raised_with_the_library_message(model):
    with pytest.raises(troupe.TroupeError) as e:
        troupe.Model("/nonexistent/bundle")
    assert e.value.name == "TROUPE_ERR_IO" and "/nonexistent/bundle" in str(e.value)
    with pytest.raises(troupe.TroupeError) as e:
        model.session(steps=0)
    assert e.value.name == "TROUPE_ERR_INVALID_ARG"
    with model.session() as s:
        with pytest.raises(ValueError):
            s.step(np.zeros((4, 100), np.float32))
        with pytest.raises(troupe.TroupeError) as e:
            s.set_condition(np.zeros(5, np.float32))
        assert e.value.name == "TROUPE_ERR_SHAPE" and "expects 32" in str(e.value)
        with pytest.raises(troupe.TroupeError) as e:
            s.set_cfg_scale(float("nan"))
        assert e.value.name == "TROUPE_ERR_INVALID_ARG"


def test_each_status_code_has_its_exception_class(model):
    # Every TROUPE_ERR_* code of the header maps to its class, with the code and name C gives.
    header = (REPO / "include" / "troupe.h").read_text()
    codes = {name: int(v) for name, v in re.findall(r"#define (TROUPE_ERR_\w+) (\d+)", header)}
    classes = [getattr(troupe.errors, n) for n in troupe.errors.__all__ if n != "TroupeError"]
    assert {c.name: c.status for c in classes} == codes
    for cls in classes:
        assert issubclass(cls, troupe.TroupeError)
        assert _native.load().troupe_status_name(cls.status).decode() == cls.name
    with pytest.raises(troupe.IoError) as e:
        troupe.Model("/nonexistent/bundle")
    assert e.value.status == codes["TROUPE_ERR_IO"] and "/nonexistent/bundle" in e.value.message
    with pytest.raises(troupe.InvalidArgument) as e:
        model.session(steps=0)
    assert isinstance(e.value, ValueError)
    with model.session() as s, pytest.raises(troupe.ShapeMismatch):
        s.set_condition(np.zeros(5, np.float32))
    # A code this package does not know (a newer library) is still a TroupeError with its code.
    unknown = troupe.errors.from_status(99, "later", "TROUPE_ERR_UNKNOWN")
    assert type(unknown) is troupe.TroupeError and unknown.status == 99


def test_wrong_types_raise_type_errors_naming_the_type(model):
    from troupe import motion

    with model.session() as s:
        with pytest.raises(TypeError, match="fmt must be a troupe.motion.JointsFormat, got tuple"):
            s.set_joints_format(("m", "y"))
        with pytest.raises(TypeError, match="each of sessions must be a troupe.Session, got str"):
            troupe.step_sessions([s, "not a session"], [np.zeros((0, 262), np.float32)] * 2)
    with pytest.raises(TypeError, match="model must be a troupe.Model, got str"):
        motion.encode("onnx/bundles/armflow-tiny", np.zeros((8, 22, 3), np.float32))
    with pytest.raises(TypeError, match="placement must be a troupe.motion.Placement, got dict"):
        motion.decode(model, np.zeros((1, model.frame_dim), np.float32), {"floor": 0})
    with pytest.raises(TypeError, match="model must be a troupe.Model, got NoneType"):
        troupe.Session(None)
    # Text where numbers belong is a TypeError, never read as a number; a wrong shape is the
    # library's ShapeMismatch (a ValueError too) whichever side notices it.
    with model.session() as s:
        for text in ("abc", [["a"]], b"\x00\x01"):
            with pytest.raises(TypeError, match="actor must be an array of numbers"):
                s.step(text)
        with pytest.raises(troupe.ShapeMismatch, match=r"actor must be \[frames, 262\], got \[4, 5\]"):
            s.step(np.zeros((4, 5), np.float32))
        frames = np.zeros((4, 262), np.float32)
        frames[2, 7] = np.nan
        with pytest.raises(troupe.InvalidArgument, match=r"non-finite value \(NaN\) at frame 2, feature 7"):
            s.step(frames)
    with pytest.raises(TypeError, match="fps must be a number, got str"):
        motion.JointsFormat(fps="30")
    with pytest.raises(OSError):  # IoError is an OSError, as Python's own file errors are
        troupe.Model("/nonexistent/bundle")


def test_integers_outside_the_c_type_are_refused_not_wrapped(model):
    # ctypes alone wraps them: steps=2**32 + 1 ran 1 step, capacity=2**32 + 64 gave 64.
    for settings, field in [({"steps": 2**32 + 1}, "steps"), ({"capacity": 2**32 + 64}, "context_capacity"),
                            ({"seed": -1}, "seed"), ({"seed": 2**64}, "seed")]:
        with pytest.raises(troupe.InvalidArgument, match=f"{field} = .* does not fit uint"):
            model.session(**settings)
    for settings in [{"steps": True}, {"steps": 1.5}, {"seed": "7"}]:
        with pytest.raises(TypeError, match="must be an integer"):
            model.session(**settings)
    with pytest.raises(TypeError, match="cfg_scale must be a number, got bool"):
        model.session(cfg_scale=True)
    with model.session(seed=2**64 - 1, steps=np.uint32(2)) as s:
        with pytest.raises(troupe.InvalidArgument, match="4294967300 does not fit uint32_t"):
            s.set_foot_lock(release_frames=2**32 + 4)
        s.set_foot_lock(release_frames=4)


def test_the_demo_model_and_clip_come_with_the_package():
    from troupe import bundles

    assert (bundles.demo() / "troupe.json").is_file()
    clip = bundles.demo_clip()
    assert clip.shape == (960, 22, 3) and clip.dtype == np.float32
    with pytest.raises(ValueError):
        bundles.path("../armflow-demo")
    with pytest.raises(FileNotFoundError):
        bundles.path("no-such-bundle")


def test_the_package_is_typed():
    assert (Path(troupe.__file__).parent / "py.typed").is_file()


def test_failed_steps_leave_the_session_unchanged(model):
    x = actor(16)
    with model.session(seed=2) as ref:
        want = stream(ref, x, 4)
    with model.session(seed=2) as s:
        got = [s.step(x[:3])]
        bad = x[3:4].copy()
        bad[0, 7] = np.nan
        with pytest.raises(troupe.TroupeError) as e:
            s.step(bad)
        assert "non-finite" in str(e.value)
        with pytest.raises(troupe.TroupeError) as e:
            s.step(x[3:4], out=np.zeros((3, 262), np.float32))
        assert e.value.name == "TROUPE_ERR_BUFFER_TOO_SMALL"
        assert s.output_frames(1) == 4
        got.append(stream(s, x[3:], 4))
    assert np.array_equal(np.concatenate(got), want)


def test_many_sessions_in_one_call_equal_each_alone(model):
    x = actor(48)
    settings = [dict(seed=1), dict(seed=2, steps=2, cfg_scale=2.0), dict(seed=3, capacity=4)]
    ticks = [1, 5, 12]
    alone = []
    for kw, tick in zip(settings, ticks):
        with model.session(**kw) as s:
            alone.append(stream(s, x, tick))
    crowd = [model.session(**kw) for kw in settings]
    got = [[] for _ in crowd]
    fed = [0, 0, 0]
    while any(f < len(x) for f in fed):
        chunks = [x[f : f + t] for f, t in zip(fed, ticks)]
        for i, out in enumerate(troupe.step_sessions(crowd, chunks)):
            got[i].append(out)
        fed = [f + len(c) for f, c in zip(fed, chunks)]
    for want, parts in zip(alone, got):
        assert np.abs(np.concatenate(parts) - want).max() <= 1e-5

    # a bad batch changes no session: each goes on as its twin that never saw it
    for s in crowd:
        s.reset()
    bad = x[:4].copy()
    bad[1, 3] = np.inf
    with pytest.raises(troupe.TroupeError) as e:
        troupe.step_sessions(crowd, [x[:4], bad, x[:4]])
    assert "session 1" in str(e.value) and e.value.name == "TROUPE_ERR_INVALID_ARG"
    with pytest.raises(ValueError):
        troupe.step_sessions([crowd[0], crowd[0]], [x[:4], x[:4]])
    with pytest.raises(ValueError):
        troupe.step_sessions(crowd, [np.zeros((4, 5), np.float32)] * 3)
    for wrong in ([x[:4]] * 2, [x[:4]] * 4):  # one array per session, no more, no fewer
        with pytest.raises(ValueError, match="3 sessions but"):
            troupe.step_sessions(crowd, wrong)
    outs = troupe.step_sessions(crowd, [x[:4]] * 3)
    for out, want in zip(outs, alone):
        assert np.abs(out - want[:4]).max() <= 1e-5
    assert troupe.step_sessions([], []) == []
    for s in crowd:
        s.close()


def test_threads_with_their_own_sessions(model):
    x = actor(64)
    with model.session(seed=9) as s:
        want = stream(s, x, 4)
    results = [None] * 4

    def work(i):
        with model.session(seed=9) as s:
            results[i] = stream(s, x, 4)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(r is not None and np.array_equal(r, want) for r in results)


def test_model_from_bytes_and_closing(model):
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w") as tar:
        for f in sorted(BUNDLE.glob("*")):
            if f.is_file():
                tar.add(f, arcname=f.name)
    x = actor(16)
    with troupe.Model.from_bytes(buf.getvalue()) as m2, m2.session(seed=4) as s2, model.session(seed=4) as s1:
        assert np.array_equal(stream(s2, x, 4), stream(s1, x, 4))
    m3 = troupe.Model(BUNDLE)
    s = m3.session()
    m3.close()  # the session keeps the model alive
    assert s.step(x[:4]).shape == (4, 262)
    s.close()
    with pytest.raises(ValueError):
        s.step(x[:4])
    with pytest.raises(ValueError):
        m3.session()


def test_limits_and_hostile_input_raise_instead_of_killing_the_interpreter(model):
    lim = troupe.limits()
    assert lim["max_steps"] == 10000 and lim["max_text_tokens"] == 77 and lim["max_prompt_bytes"] == 65536
    # A tar member declaring 2^50 bytes: once an abort of the whole interpreter.
    header = tarfile.TarInfo("troupe.json")
    header.size = 2
    block = bytearray(header.tobuf(format=tarfile.GNU_FORMAT))
    block[124:136] = b"\x80" + (1 << 50).to_bytes(11, "big")  # base-256 size field
    block[148:156] = b"        "
    block[148:156] = b"%06o\0 " % sum(block)
    with pytest.raises(troupe.TroupeError, match="declares 1125899906842624 bytes"):
        troupe.Model.from_bytes(bytes(block) + b"{}" + b"\0" * 1534)
    with pytest.raises(troupe.TroupeError, match="limit of 10000"):
        model.session(steps=2**32 - 1)
    with model.session() as s:
        with pytest.raises(troupe.TroupeError, match="INVALID_ARG"):
            s.step(np.full((4, model.frame_dim), 3.4e38, np.float32))
        out = s.step(actor(8))
        assert out.shape == (8, 262) and np.isfinite(out).all()
    before = troupe._lib.troupe_load_threads()
    troupe.set_load_threads(1)
    assert troupe._lib.troupe_load_threads() == 1
    troupe.set_load_threads(0)
    assert troupe._lib.troupe_load_threads() == before


def test_progress_callbacks_report_and_cancel_long_calls():
    seen = []
    with troupe.progress(lambda done, total: seen.append((done, total)) or done < 2):
        with pytest.raises(troupe.TroupeError, match="CANCELLED"):
            troupe.Model(BUNDLE)
    assert seen == [(1, seen[0][1]), (2, seen[0][1])]
    with pytest.raises(ZeroDivisionError):
        with troupe.progress(lambda done, total: 1 / 0):
            troupe.Model(BUNDLE)
    troupe.Model(BUNDLE).close()  # no callback outside the block


UMF = REPO / "onnx" / "bundles" / "umf-tiny"


@pytest.fixture(scope="module")
def umf():
    with troupe.Model(UMF) as m:
        yield m


def umf_golden(name):
    return np.load(UMF / "golden" / f"{name}.npy")


def test_a_call_budget_refuses_work_up_front_and_nests(umf):
    cond = umf_golden("seeded_2p_condition")
    want = umf.umf.generate_group(2, condition=cond, seed=7)
    with troupe.call_budget(work=3):
        with pytest.raises(troupe.InvalidArgument, match="network evaluations, above this thread's call budget of 3"):
            umf.umf.generate_group(2, condition=cond, seed=7)
        with troupe.call_budget(work=10**6, seconds=600.0):
            assert np.array_equal(umf.umf.generate_group(2, condition=cond, seed=7), want)
        with pytest.raises(troupe.InvalidArgument):  # the enclosing budget is back
            umf.umf.generate_group(2, condition=cond, seed=7)
    assert np.array_equal(umf.umf.generate_group(2, condition=cond, seed=7), want)  # none outside
    with pytest.raises(troupe.InvalidArgument, match="seconds"):
        with troupe.call_budget(seconds=-1.0):
            pass
    with pytest.raises(troupe.InvalidArgument, match="does not fit uint64_t"):
        troupe.call_budget(work=-1)


def test_group_generation_matches_the_reference(umf):
    assert (umf.umf.stages, umf.umf.tokens, umf.clip_frames, umf.frame_dim) == (2, 16, 40, 262)
    cond = umf_golden("seeded_2p_condition")
    motion, latents = umf.umf.generate_group(2, condition=cond, seed=7, return_latents=True)
    assert motion.shape == (2, 40, 262) and latents.shape == (2, 16, umf.latent_dim)
    assert np.abs(motion - umf_golden("seeded_2p_motion")).max() <= 1e-4
    assert np.abs(latents - umf_golden("seeded_2p_latents")).max() <= 1e-5
    # The paper's Euler 45/5/10 with injected noise, as the reference ran it.
    noise = (umf_golden("euler_paper_2p_prior_noise"), umf_golden("euler_paper_2p_jump1"),
             umf_golden("euler_paper_2p_reaction_noise"))
    motion = umf.umf.generate_group(2, condition=umf_golden("euler_paper_2p_condition"), cfg_scale=3.0,
                                prior=[("euler", 45), ("euler", 5)], reaction=("euler", 10), noise=noise)
    assert np.abs(motion - umf_golden("euler_paper_2p_motion")).max() <= 1e-4


def test_group_text_branch_and_three_people_match_the_reference(umf):
    assert umf.text_token_dim == 16 and umf.condition_dim == 32
    cond = umf.encode_text(umf_golden("text_clip_tokens"), int(umf_golden("text_eot_index")[0]))
    assert np.abs(cond - umf_golden("text_condition")).max() <= 1e-5
    noise = (umf_golden("text_3p_prior_noise"), umf_golden("text_3p_jump1"), umf_golden("text_3p_reaction_noise"))
    motion, latents = umf.umf.generate_group(3, condition=cond, noise=noise, return_latents=True)
    assert np.abs(latents - umf_golden("text_3p_latents")).max() <= 1e-5
    assert np.abs(motion - umf_golden("text_3p_motion")).max() <= 1e-4
    with pytest.raises(ValueError, match=r"clip_tokens must be \[tokens, 16\]"):
        umf.encode_text(np.zeros((5, 32), np.float32), 0)


def test_group_errors(umf, model):
    with pytest.raises(troupe.TroupeError, match="people is 0") as e:
        umf.umf.generate_group(0)
    assert e.value.name == "TROUPE_ERR_INVALID_ARG"
    with pytest.raises(troupe.TroupeError, match="TROUPE_ERR_SHAPE"):
        umf.umf.generate_group(1, condition=np.zeros(3, np.float32))
    with pytest.raises(troupe.TroupeError, match="1 prior solvers given"):
        umf.umf.generate_group(1, prior=[("rk4", 4)])
    with pytest.raises(ValueError, match="unknown solver"):
        umf.umf.generate_group(1, reaction=("midpoint", 4))
    with pytest.raises(troupe.Unsupported, match="`armflow` model; only umf models"):
        model.umf.generate_group(1)
    with pytest.raises(troupe.TroupeError, match="`umf` model"):
        umf.session()


OFFICIAL = REPO / "onnx" / "bundles" / "armflow-tiny-interhuman"


def official_golden(name):
    return np.load(OFFICIAL / "golden" / f"{name}.npy")


def test_official_clip_loop_and_text_branch_match_the_reference():
    m = troupe.Model(OFFICIAL)
    assert (m.clip_frames, m.armflow.clip_tokens) == (300, 75)
    cond = m.encode_text(official_golden("text_clip_tokens"), int(official_golden("text_eot_index")[0]))
    assert np.abs(cond - official_golden("text_condition")).max() <= 1e-5
    noise = (official_golden("clip_xi"), official_golden("clip_eps"))
    motion, latents = m.armflow.generate_clip(official_golden("clip_actor"), cond, noise=noise, return_latents=True)
    assert np.abs(motion - official_golden("clip_frames")).max() <= 1e-4
    assert np.abs(latents - official_golden("clip_reactor_latents")).max() <= 1e-5
    seeded = m.armflow.generate_clip(official_golden("clip_actor"), seed=4)
    assert np.array_equal(seeded, m.armflow.generate_clip(official_golden("clip_actor"), seed=4))
    with pytest.raises(troupe.TroupeError, match="1..=300 frames"):
        m.armflow.generate_clip(np.zeros((301, 262), np.float32))
    with pytest.raises(troupe.TroupeError, match="reactor_noise"):
        m.armflow.generate_clip(official_golden("clip_actor"), noise=(noise[0], noise[1][:3]))
    with pytest.raises(troupe.TroupeError, match="no `clip` section"):
        troupe.Model(BUNDLE).armflow.generate_clip(np.zeros((4, 262), np.float32))
    with pytest.raises(ValueError, match="clip_tokens must be"):
        m.encode_text(np.zeros((5, 7), np.float32), 0)


def test_guided_clip_matches_the_reference_guided():
    m = troupe.Model(OFFICIAL)
    assert ctypes.sizeof(_native.ClipOptions) == _native.load().troupe_armflow_clip_options_size()
    cond = official_golden("text_condition")
    noise = (official_golden("clip_guided_xi"), official_golden("clip_guided_eps"))
    motion, latents = m.armflow.generate_clip(official_golden("clip_guided_actor"), cond, noise=noise, return_latents=True,
                                      cfg_scale=2.0)
    assert np.abs(latents - official_golden("clip_guided_reactor_latents")).max() <= 1e-5
    assert np.abs(motion - official_golden("clip_guided_frames")).max() <= 1e-4
    unguided = m.armflow.generate_clip(official_golden("clip_guided_actor"), cond, noise=noise)
    assert np.array_equal(unguided, m.armflow.generate_clip(official_golden("clip_guided_actor"), cond, noise=noise,
                                                    cfg_scale=1.0))
    assert np.abs(unguided - motion).max() > 1e-3
    with pytest.raises(troupe.TroupeError, match="(?i)cfg"):
        m.armflow.generate_clip(official_golden("clip_guided_actor"), cond, cfg_scale=float("nan"))


def test_reduced_precision_graphs_are_listed(model):
    assert model.reduced_precision == {}
    with troupe.Model(REPO / "onnx" / "bundles" / "armflow-demo-int8") as int8:
        assert int8.reduced_precision == {"context_layers": "int8", "velocity": "int8"}


def test_named_conditions_of_the_demo_bundle(model):
    assert model.condition_labels == []
    with pytest.raises(troupe.TroupeError, match="has no named conditions"):
        model.condition("mirror")
    with troupe.Model(REPO / "onnx" / "bundles" / "armflow-demo") as demo:
        assert demo.condition_labels == ["mirror", "follow", "keep-away"]
        np.testing.assert_array_equal(demo.condition("keep-away"), [0.0, 0.0, 1.0])
        with pytest.raises(troupe.TroupeError, match="has: mirror, follow, keep-away"):
            demo.condition("dance")
        # a session takes a label wherever it takes a condition vector
        actor = np.zeros((8, demo.frame_dim), np.float32)
        with demo.session(seed=3, condition="follow") as by_name, \
                demo.session(seed=3, condition=demo.condition("follow")) as by_vector:
            np.testing.assert_array_equal(by_name.step(actor), by_vector.step(actor))


PROMPTS = REPO / "onnx" / "bundles" / "armflow-tiny-interhuman"


def test_prompts_encode_as_the_reference_and_condition_sessions_clips_and_groups(model):
    import json

    golden = PROMPTS / "golden"
    prompts = json.loads((golden / "prompts.json").read_text(encoding="utf-8"))
    want = np.load(golden / "prompt_conditions.npy")
    with troupe.Model(PROMPTS) as m:
        assert m.takes_prompts
        for p, c in zip(prompts, want):
            assert np.abs(m.encode_prompt(p) - c).max() <= 1e-5, p
        assert np.abs(m.encode_prompt("") - np.array(json.loads((PROMPTS / "troupe.json").read_text())["condition"]["null"])).max() <= 1e-5
        actor_clip = np.load(golden / "clip_actor.npy")
        by_vector = troupe.Session(m, seed=1, condition=m.encode_prompt(prompts[1])).step(actor_clip)
        assert np.array_equal(troupe.Session(m, seed=1, prompt=prompts[1]).step(actor_clip), by_vector)
        s = troupe.Session(m, seed=1)
        s.set_prompt(prompts[1])
        assert np.array_equal(s.step(actor_clip), by_vector)
        assert np.array_equal(m.armflow.generate_clip(actor_clip, prompt=prompts[2], seed=3),
                              m.armflow.generate_clip(actor_clip, m.encode_prompt(prompts[2]), seed=3))
        with pytest.raises(ValueError, match="not both"):
            troupe.Session(m, condition=by_vector[0, :m.condition_dim], prompt="x")
        with pytest.raises(ValueError, match="NUL"):
            m.encode_prompt("a\0b")
        with pytest.raises(troupe.TroupeError, match="length in bytes"):
            m.encode_prompt("x" * (1 << 20))
    with troupe.Model(REPO / "onnx" / "bundles" / "umf-tiny") as u:
        assert np.array_equal(u.umf.generate_group(2, prompt="two people dance", seed=5),
                              u.umf.generate_group(2, u.encode_prompt("two people dance"), seed=5))
    assert not model.takes_prompts
    with pytest.raises(troupe.TroupeError, match="takes no text prompts"):
        model.encode_prompt("hello")
    with pytest.raises(troupe.Unsupported, match="a text prompt: this `armflow` stream does not take it"):
        troupe.Session(model, prompt="hello")


def test_a_compute_pool_changes_no_output(model):
    a = actor()
    want = troupe.Session(model, seed=2).step(a)
    assert troupe.compute_threads() == 1
    troupe.set_compute_threads(2)
    try:
        assert troupe.compute_threads() == 2
        assert np.array_equal(troupe.Session(model, seed=2).step(a), want)
        with pytest.raises(troupe.TroupeError, match="compute threads"):
            troupe.set_compute_threads(5000)
        assert troupe.compute_threads() == 2
    finally:
        troupe.set_compute_threads(1)
    assert troupe.compute_threads() == 1


# --- MAGNet ---------------------------------------------------------------------------------------

MAGNET = REPO / "onnx" / "bundles" / "magnet-tiny"


@pytest.fixture(scope="module")
def magnet():
    with troupe.Model(MAGNET) as m:
        yield m


def test_magnet_options_mirror_the_library():
    assert ctypes.sizeof(_native.MagnetOptions) == _native.load().troupe_magnet_options_size()


def test_magnet_matches_the_reference_on_every_golden_task(magnet):
    import json

    assert magnet.magnet.people == 2 and magnet.frame_dim == 145
    assert "dd100" in magnet.magnet.configs and len(magnet.magnet.configs) == 8
    frames = np.load(MAGNET / "golden" / "frames.npy")
    cases = json.loads((MAGNET / "golden" / "cases.json").read_text())
    for case, spec in cases.items():
        if case.startswith("live_stream"):
            continue  # streams: test_magnet_live_partner_streams_as_the_reference
        out = magnet.magnet.generate(spec["sampling"], frames)
        want = np.load(MAGNET / "golden" / f"{case}_frames.npy")
        assert out.shape == want.shape, case
        assert np.abs(out - want).max() <= 1e-4 * np.abs(want).max(), case


def test_magnet_released_configuration_with_options(magnet):
    frames = np.load(MAGNET / "golden" / "frames.npy")
    out = magnet.magnet.generate("dd100", frames, samples=1, steps=2, seq_len=64, seed=9, x0_guidance=False)
    assert out.shape == (1, 64, 2, 145) and np.isfinite(out).all()
    again = magnet.magnet.generate("dd100", frames, samples=1, steps=2, seq_len=64, seed=9, x0_guidance=False,
                                   present=np.ones(frames.shape[:2], bool))
    np.testing.assert_array_equal(out, again)
    keys = magnet.magnet.generate("dd100_inbetweening", frames, steps=2, x0_guidance=False, keyframes=[0, 60])
    assert keys.shape == (1, 64, 2, 145)


def test_magnet_live_partner_streams_as_the_reference(magnet, model):
    import json

    frames = np.load(MAGNET / "golden" / "frames.npy")
    cases = json.loads((MAGNET / "golden" / "cases.json").read_text())
    for case in ("live_stream", "live_stream_early"):
        spec = cases[case]
        s = magnet.session(seed=5, live_config=json.dumps(spec["sampling"]),
                           partner_opening=frames[:32, 1], early=spec["early"])
        out = [s.step(frames[a : a + 20, 0]) for a in range(0, 128, 20)]
        got = np.concatenate(out)
        want = np.load(MAGNET / "golden" / f"{case}_frames.npy")
        assert got.shape == want.shape, case
        assert np.abs(got - want).max() <= 1e-4 * np.abs(want).max(), case
        # a crowd stepped together: the same frames
        a, b = (magnet.session(seed=5, live_config=json.dumps(spec["sampling"]),
                               partner_opening=frames[:32, 1], early=spec["early"]) for _ in range(2))
        together = troupe.step_sessions([a, b], [frames[:, 0], frames[:, 0]])
        for t in together:
            assert np.abs(t - want).max() <= 1e-4 * np.abs(want).max(), case
    bare = magnet.session(seed=5)
    with pytest.raises(troupe.TroupeError, match="opening frames"):
        bare.step(frames[:1, 0])
    with pytest.raises(troupe.TroupeError, match="opening frames hold"):
        bare.magnet.set_partner_opening(frames[:31, 1])
    with pytest.raises(troupe.Unsupported, match="text prompt"):
        bare.set_prompt("wave")
    with pytest.raises(troupe.Unsupported, match="TROUPE_ERR_UNSUPPORTED.*only magnet models"):
        model.session().magnet.set_early_emission(True)


def test_magnet_frames_pose_on_the_skeleton(magnet):
    from troupe import motion

    frames = np.load(MAGNET / "golden" / "frames.npy")
    joints = motion.smplx145_positions(frames[:, 0])
    assert joints.shape == (128, 22, 3) and np.isfinite(joints).all()
    # The pelvis sits at the root's translation; bones keep the skeleton's lengths.
    np.testing.assert_allclose(joints[:, 0], frames[:, 0, 142:145], atol=1e-6)
    sk = motion.skeleton()
    for j in range(1, 22):
        bone = np.linalg.norm(joints[:, j] - joints[:, sk.parents[j]], axis=-1)
        np.testing.assert_allclose(bone, np.linalg.norm(sk.rest_offsets[j]), rtol=1e-4)
    bad = frames[:4, 0].copy()
    bad[1, 20] = np.nan
    with pytest.raises(troupe.TroupeError, match="not finite"):
        motion.smplx145_positions(bad)
    with pytest.raises(ValueError, match=r"\[frames, 145\]"):
        motion.smplx145_positions(np.zeros((3, 144), np.float32))


def test_magnet_errors(magnet, model):
    frames = np.load(MAGNET / "golden" / "frames.npy")
    with pytest.raises(troupe.TroupeError, match="no sampling configuration `nope`") as e:
        magnet.magnet.generate("nope", frames)
    assert e.value.name == "TROUPE_ERR_INVALID_ARG"
    with pytest.raises(troupe.TroupeError, match="needs at least 32 frames"):
        magnet.magnet.generate("dd100", frames[:16], steps=2)
    bad = frames.copy()
    bad[5, 0, 3] = np.nan
    with pytest.raises(troupe.TroupeError, match="TROUPE_ERR_INVALID_ARG"):
        magnet.magnet.generate("dd100", bad, steps=2, samples=1)
    with pytest.raises(ValueError, match=r"frames must be \[frames, 2, 145\]"):
        magnet.magnet.generate("dd100", np.zeros((64, 3, 145), np.float32), steps=2)
    with pytest.raises(ValueError, match="present must be"):
        magnet.magnet.generate("dd100", frames, present=np.ones((3, 2), bool))
    with pytest.raises(troupe.Unsupported, match="only magnet models"):
        model.magnet.generate("dd100", frames)


ARFLOW = REPO / "onnx" / "bundles" / "arflow-tiny"


def test_arflow_matches_the_reference_and_refuses_bad_input(model):
    import json

    assert ctypes.sizeof(_native.ArflowOptions) == _native.load().troupe_arflow_options_size()
    cases = json.loads((ARFLOW / "golden" / "cases.json").read_text())
    actor = np.load(ARFLOW / "golden" / "actor.npy")
    with troupe.Model(ARFLOW) as arflow:
        for case in ("euler", "guided", "stochastic"):
            c = cases[case]
            out = arflow.arflow.generate(actor, seed=c["seed"], steps=c["steps"], guidance=c["guidance"],
                                         weight=c["weight"], eta=c["eta"], d_safe=c["d_safe"], sigma=c["sigma"],
                                         squared=c["squared"], guided_backprojection=c["guided_backprojection"],
                                         mixing=c["mixing"])
            want = np.load(ARFLOW / "golden" / f"{case}_reactor.npy")
            bound = 1e-4 if c["guidance"] > 0 else 1e-5
            assert np.abs(out - want).max() <= bound * np.abs(want).max(), case
        with pytest.raises(troupe.TroupeError, match="guidance strength"):
            arflow.arflow.generate(actor, guidance=-1.0)
        with pytest.raises(ValueError, match=r"\[frames, 262\]"):
            arflow.arflow.generate(actor[:, :100])
    with pytest.raises(troupe.Unsupported, match="only arflow models"):
        model.arflow.generate(actor)


def _philox_normals():
    """troupe's generator in Python (onnx/troupe_onnx/shared/noise.py, numpy only), loaded by path."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("troupe_noise", REPO / "onnx" / "troupe_onnx" / "shared" / "noise.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.philox_normals


def test_arflow_injected_draws_replay_the_seeded_run():
    """The seed's own normals, given as draws in the documented order (the start noise, then one
    eps per step, T x 262 each), replay the seeded run exactly; draws the run does not take in
    full are refused."""
    actor = np.load(ARFLOW / "golden" / "actor.npy")
    philox = _philox_normals()
    with troupe.Model(ARFLOW) as arflow:
        settings = dict(steps=3, eta=0.5, sigma=0.1)
        seeded = arflow.arflow.generate(actor, seed=7, **settings)
        draws = np.concatenate([philox(7, i, 9, actor.size) for i in range(4)]).astype(np.float32)
        assert np.array_equal(arflow.arflow.generate(actor, draws=draws, **settings), seeded)
        with pytest.raises(ValueError, match="took .* of the .* normals given"):
            arflow.arflow.generate(actor, draws=np.concatenate([draws, draws[:5]]), **settings)
        with pytest.raises(troupe.TroupeError, match="draw 3 needs"):
            arflow.arflow.generate(actor, draws=draws[:-1], **settings)


def test_magnet_injected_draws_replay_the_seeded_run(magnet):
    """MAGNet's draws as one queue: the seed's normals, each draw's size read from the refusal
    of a queue that stops short of it, replay the seeded run exactly."""
    import re

    frames = np.load(MAGNET / "golden" / "frames.npy")
    philox = _philox_normals()
    settings = dict(samples=1, steps=2, seq_len=64, seed=4, x0_guidance=False)
    seeded = magnet.magnet.generate("dd100", frames, **settings)
    draws = np.zeros(0, np.float32)
    for draw in range(100):
        try:
            replayed = magnet.magnet.generate("dd100", frames, draws=draws, **settings)
            break
        except troupe.TroupeError as e:
            n = int(re.search(rf"draw {draw} needs (\d+) normals", str(e)).group(1))
            draws = np.concatenate([draws, philox(4, draw, 8, n)]).astype(np.float32)
    assert np.array_equal(replayed, seeded)


def test_penetration_metrics():
    from troupe import motion

    actor = np.load(ARFLOW / "golden" / "actor.npy")[:, :66].reshape(-1, 22, 3)
    near = motion.penetration_metrics(actor, actor + np.array([0.1, 0, 0], np.float32))
    assert near["frames_intersecting"] == 40 and near["frequency"] == 1.0 and near["depth_sum"] > 0
    far = motion.penetration_metrics(actor, actor + np.array([3.0, 0, 0], np.float32))
    assert far["frames_intersecting"] == 0 and far["depth_sum"] == 0.0
    bad = actor.copy()
    bad[2, 3, 1] = np.nan
    with pytest.raises(troupe.TroupeError, match="non-finite"):
        motion.penetration_metrics(actor, bad)


def glitched_actor(demo, actor, rule):
    """The clip as a glitching tracker delivers it: every second the actor's position jumps onto
    the spot where `rule`'s partner stands at that frame and stays shifted after. The demo's
    partners keep out of the clip as captured by themselves; a glitch puts the bodies inside
    each other for the frames the model needs to react (tests/penetration_guard.rs likewise)."""
    actor = actor.copy()
    for k in range(30, len(actor) - 10, 30):
        partner = demo.session(seed=7, condition=rule).step(actor)
        shift = partner[k, [0, 2]] - actor[k, [0, 2]]
        for axis, d in zip((0, 2), shift):
            actor[k:, axis:66:3] += d
            actor[k - 1, 66 + axis:132:3] += d  # a frame's velocity is the step to the next
    return actor


def test_the_penetration_guard_on_the_demo():
    from troupe import motion

    clip = np.load(REPO / "tests" / "data" / "mocap" / "cmu-playground.features.npy").astype(np.float32)
    with troupe.Model(REPO / "onnx" / "bundles" / "armflow-demo") as demo:
        actor = glitched_actor(demo, clip, "mirror")
        free = demo.session(seed=7, condition="mirror").step(actor)
        s = demo.session(seed=7, condition="mirror")
        s.set_penetration_guard(True)
        guarded = s.step(actor)
        n = len(free)
        a = actor[:n, :66].reshape(n, 22, 3)
        before = motion.penetration_metrics(a, free[:, :66].reshape(n, 22, 3))
        after = motion.penetration_metrics(a, guarded[:, :66].reshape(n, 22, 3))
        assert before["frames_intersecting"] >= 5, before
        assert after["depth_sum"] < 0.5 * before["depth_sum"], (before, after)
        with pytest.raises(troupe.TroupeError, match="d_safe"):
            s.set_penetration_guard(True, d_safe=-1.0)


def ankle_slides(positions, contacts, threshold):
    """Horizontal slides (metres) of each ankle between frames its contact label is on in both
    (z up: the floor plane is x, y)."""
    slides = []
    for ankle, label in ((7, 0), (8, 2)):
        on = (contacts[1:, label] >= threshold) & (contacts[:-1, label] >= threshold)
        step = positions[1:, ankle] - positions[:-1, ankle]
        slides.append(np.hypot(step[:, 0], step[:, 1])[on])
    return np.concatenate(slides)


def test_the_foot_lock_keeps_the_demo_partners_feet_still():
    from troupe import bundles, motion

    clip = bundles.demo_clip()
    fmt = motion.JointsFormat(units="m", up="z", fps=120)
    # The demo model learnt its contact labels: the default threshold, as the demo
    # runs it.
    threshold = 0.5
    runs = {}
    with troupe.Model(bundles.demo()) as demo:
        for lock in (False, True):
            s = demo.session(seed=7, condition="mirror")
            s.set_joints_format(fmt)
            if lock:
                s.set_foot_lock(True, contact_threshold=threshold)
            runs[lock] = s.step_joints(clip)
        free, locked = runs[False], runs[True]
        # The same motion and labels, the feet held where the labels say: a held foot is let go
        # when the body moves away from it (max_stretch), but while held it does not move at all.
        # Measured on the committed model: 285 labelled ankle moves, 79 % of them held still,
        # the mean slide 2.2 cm -> 0.7 cm.
        np.testing.assert_array_equal(free.contacts, locked.contacts)
        np.testing.assert_array_equal(free.positions[:, 0], locked.positions[:, 0])
        before = ankle_slides(free.positions, free.contacts, threshold)
        after = ankle_slides(locked.positions, locked.contacts, threshold)
        assert len(before) > 200 and (before < 1e-4).mean() == 0.0
        assert (after < 1e-4).mean() > 0.6 and after.mean() < 0.5 * before.mean(), (before.mean(), after.mean())
        s = demo.session(seed=7)
        with pytest.raises(troupe.TroupeError, match="release_frames"):
            s.set_foot_lock(True, release_frames=0)
        with pytest.raises(troupe.TroupeError, match="contact_threshold"):
            s.set_foot_lock(True, contact_threshold=float("nan"))
        s.set_foot_lock(False)


def test_recentring_keeps_the_demo_partner_as_the_actor_walks_away():
    from troupe import bundles, motion

    mocap = REPO / "tests" / "data" / "mocap"
    actor = np.load(mocap / "cmu-playground-walk.npy")  # 30 fps, z up, ends 11.5 m away
    truth = np.load(mocap / "cmu-playground-walk.mirror.npy")
    late = {}
    with troupe.Model(bundles.demo()) as demo:
        for recentring in (False, True):
            s = demo.session(seed=7, condition="mirror")
            s.set_joints_format(motion.JointsFormat(units="m", up="z", fps=30))
            if recentring:
                s.armflow.set_recentring(True)
            out = np.concatenate([s.step_joints(actor[i : i + 4]).positions for i in range(0, len(actor), 4)])
            n = len(out)
            error = np.linalg.norm(out - truth[:n], axis=-1).mean(axis=-1)
            late[recentring] = 100 * error[3 * n // 4 :].mean()
        # Measured on the committed model: about 190 cm without, 25 cm with.
        assert late[True] < 40 and late[False] > 3 * late[True], late
        s = demo.session(seed=7)
        with pytest.raises(troupe.TroupeError, match="distance"):
            s.armflow.set_recentring(True, float("nan"))
        s.armflow.set_recentring(False)
    with troupe.Model(REPO / "onnx" / "bundles" / "magnet-tiny") as magnet:
        with pytest.raises(troupe.Unsupported):
            magnet.session().armflow.set_recentring(True)


def test_the_online_arflow_variant_streams_frame_by_frame():
    online = REPO / "onnx" / "bundles" / "arflow-tiny-online"
    actor = np.load(online / "golden" / "actor.npy")
    want = np.load(online / "golden" / "guided_reactor.npy")
    with troupe.Model(online) as model:
        s = model.session()
        s.arflow.set_options(seed=3)
        got = np.concatenate([s.step(actor[t : t + 1]) for t in range(len(actor))])
        assert np.abs(got - want).max() <= 1e-4 * np.abs(want).max()
        with pytest.raises(TypeError, match="unknown ARFlow settings"):
            s.arflow.set_options(lambda_=2)


def test_an_online_arflow_stream_replays_queued_normals():
    """Queued normals stand for the seed's draws: a stream seeded 99 given the normals seed 5
    draws (per frame the start noise, then one eps per step) streams as the stream seeded 5."""
    online = REPO / "onnx" / "bundles" / "arflow-tiny-online"
    actor = np.load(online / "golden" / "actor.npy")[:6]
    philox = _philox_normals()
    with troupe.Model(online) as m:
        def stream(seed, normals=None):
            s = troupe.Session(m)
            s.arflow.set_options(seed=seed, steps=2, eta=0.4, sigma=0.1)
            if normals is not None:
                s.queue_normals(normals)
            return np.concatenate([s.step(actor[i:i + 1]) for i in range(len(actor))])

        want = stream(5)
        normals = np.concatenate([philox(5, f * 3 + k, 9, 262) for f in range(len(actor)) for k in range(3)])
        assert np.array_equal(stream(99, normals), want)
        s = troupe.Session(m)
        with pytest.raises(troupe.TroupeError, match="normals"):
            s.queue_normals([float("nan")])
    # An armflow stream takes whole tokens (the actor's posterior noise, then the reactor's
    # start noise), as set_noise takes one: the two queue the same stream.
    with troupe.Model(BUNDLE) as armflow:
        with pytest.raises(troupe.TroupeError, match="whole tokens"):
            troupe.Session(armflow).queue_normals([0.0])
        lat = armflow.latent_dim
        token = np.sin(np.arange(2 * lat, dtype=np.float32) * 0.3)
        a, b = troupe.Session(armflow), troupe.Session(armflow)
        a.queue_normals(token)
        b.armflow.queue_noise(token[:lat], token[lat:])
        assert "queued_normals" in a.capabilities and "cfg_scale" in a.capabilities
        frames = np.cos(np.arange(8 * 262, dtype=np.float32) * 0.11).reshape(8, 262)
        assert np.array_equal(a.step(frames), b.step(frames))
    with troupe.Model(online) as m:
        assert troupe.Session(m).capabilities == frozenset({"queued_normals"})


def test_a_snapshot_continues_bit_for_bit_in_another_process(model, tmp_path):
    frames = actor(96)
    whole = stream(model.session(seed=4, capacity=5), frames, 7)
    first = model.session(seed=4, capacity=5)
    head = stream(first, frames[:45], 7)
    snapshot = first.snapshot()
    assert snapshot[:8] == b"TRPSNAP\0" and model.identity in snapshot
    assert len(model.identity) == 32
    # The same process: the rest of the stream, bit for bit.
    again = model.restore(snapshot)
    assert again.snapshot() == snapshot
    rest = stream(again, frames[45:], 5)
    assert np.concatenate([head, rest]).tobytes() == whole.tobytes()
    # Another process, which loads the model itself.
    import subprocess
    import sys
    (tmp_path / "snapshot.bin").write_bytes(snapshot)
    np.save(tmp_path / "rest.npy", frames[45:])
    code = (
        "import sys, numpy as np, troupe\n"
        f"m = troupe.Model({str(BUNDLE)!r})\n"
        f"s = m.restore(open({str(tmp_path / 'snapshot.bin')!r}, 'rb').read())\n"
        f"out = s.step(np.load({str(tmp_path / 'rest.npy')!r}))\n"
        f"np.save({str(tmp_path / 'out.npy')!r}, out)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    other = np.load(tmp_path / "out.npy")
    assert np.concatenate([head, other]).tobytes() == whole.tobytes()


def test_hostile_snapshots_raise(model):
    s = model.session(seed=1)
    s.step(actor(9))
    good = s.snapshot()
    with pytest.raises(troupe.InvalidArgument, match="truncated"):
        model.restore(good[:-5])
    bad = bytearray(good)
    bad[len(bad) // 2] ^= 1
    with pytest.raises(troupe.InvalidArgument, match="checksum"):
        model.restore(bad)
    with pytest.raises(troupe.InvalidArgument, match="not a troupe snapshot"):
        model.restore(b"\0" * 200)
    with troupe.Model(REPO / "onnx" / "bundles" / "armflow-demo") as demo:
        assert demo.identity != model.identity
        with pytest.raises(troupe.InvalidArgument, match="another model"):
            demo.restore(good)
    with troupe.Model(REPO / "onnx" / "bundles" / "magnet-tiny") as magnet:
        with pytest.raises(troupe.InvalidArgument, match="`armflow` stream's, not a `magnet`"):
            magnet.restore(good)


def test_a_sealed_snapshot_restores_with_its_key_only(model):
    key, other = b"k" * 32, b"o" * 32
    s = model.session(seed=1)
    s.step(actor(9))
    sealed = s.snapshot(key=key)
    assert sealed[:8] == b"TRPSEAL\0" and sealed[44:] == s.snapshot()
    assert troupe.seal_snapshot(s.snapshot(), key) == sealed
    again = model.restore(sealed, key=key)
    assert np.array_equal(again.step(actor(4)), s.step(actor(4)))
    with pytest.raises(troupe.InvalidArgument, match="does not match this key"):
        model.restore(sealed, key=other)
    edited = bytearray(sealed)
    edited[-10] ^= 1
    with pytest.raises(troupe.InvalidArgument, match="does not match this key"):
        model.restore(edited, key=key)
    with pytest.raises(troupe.InvalidArgument, match="sealed with a key"):
        model.restore(sealed)
    with pytest.raises(troupe.InvalidArgument, match="not sealed"):
        model.restore(s.snapshot(), key=key)
    with pytest.raises(troupe.InvalidArgument, match="at least 16 bytes"):
        s.snapshot(key=b"short")


def test_every_streaming_family_streams_joint_positions():
    """The same joint positions through ARMFlow, ARFlow online and a MAGNet live partner (its
    SMPL-X frames found by inverse kinematics): poses back from each, with the guard and the
    smoothing on; the foot lock refused where the frames carry no contact labels."""
    clip = troupe.bundles.demo_clip()[:360]
    fmt = troupe.motion.JointsFormat(units="m", up="z", fps=120)
    bundles = REPO / "onnx" / "bundles"
    golden = np.load(bundles / "magnet-tiny" / "golden" / "frames.npy")
    for name, latency in (("armflow-tiny", 1), ("arflow-tiny-online", 1), ("magnet-tiny", 0)):
        with troupe.Model(bundles / name) as m, m.session() as s:
            if name.startswith("magnet"):
                s.magnet.set_partner_opening(golden[:32, 1])
            s.set_joints_format(fmt)
            s.set_penetration_guard(True)
            s.set_root_smoothing(True)
            assert m.joints_latency_frames == m.latency_frames + latency, name
            poses = [s.step_joints(clip[t : t + 12]).positions for t in range(0, len(clip), 12)]
            positions = np.concatenate(poses)
            # 360 frames at 120 fps are 90 at 30: all but the latency come back, finite.
            assert 90 - m.latency_frames - latency <= len(positions) <= 90, (name, len(positions))
            assert positions.shape[1:] == (22, 3) and np.isfinite(positions).all(), name
            if name.startswith("magnet"):
                with pytest.raises(troupe.Unsupported, match="contact labels"):
                    s.set_foot_lock(True)
            else:
                s.set_foot_lock(True)


def test_family_calls_live_in_family_namespaces_and_the_0_1_names_still_work(model):
    """`model.<family>` and `session.<family>` hold what one family offers; another family's
    namespace raises Unsupported. The 0.1 names forward to them with a DeprecationWarning."""
    assert model.family == "armflow"
    for name in ("umf", "magnet", "arflow"):
        with pytest.raises(troupe.Unsupported, match=f"`armflow` model; only {name} models"):
            getattr(model, name)
    with troupe.Model(REPO / "onnx" / "bundles" / "umf-tiny") as umf:
        assert umf.family == "umf"
        with pytest.warns(DeprecationWarning, match="model.umf.generate_group"):
            old = umf.generate_group(2, seed=7, cfg=2.0)
        assert np.array_equal(old, umf.umf.generate_group(2, seed=7, cfg_scale=2.0))
        with pytest.warns(DeprecationWarning, match="model.umf.stages"):
            assert umf.group_stages == umf.umf.stages
    with troupe.Model(REPO / "onnx" / "bundles" / "magnet-tiny") as magnet:
        with pytest.warns(DeprecationWarning, match="model.magnet.configs"):
            assert magnet.magnet_configs == magnet.magnet.configs
        s = magnet.session()
        with pytest.raises(troupe.Unsupported, match="only armflow models"):
            s.armflow.set_recentring(True)
        golden = np.load(REPO / "onnx" / "bundles" / "magnet-tiny" / "golden" / "frames.npy")
        with pytest.warns(DeprecationWarning, match="session.magnet.set_partner_opening"):
            s.set_partner_opening(golden[:32, 1])
    lat = model.latent_dim
    token = np.sin(np.arange(2 * lat, dtype=np.float32) * 0.3)
    frames = np.cos(np.arange(8 * 262, dtype=np.float32) * 0.11).reshape(8, 262)
    a, b = model.session(seed=3), model.session(seed=3)
    a.armflow.queue_noise(token[:lat], token[lat:])
    with pytest.warns(DeprecationWarning, match="session.armflow.queue_noise"):
        b.set_noise(token[:lat], token[lat:])
    assert np.array_equal(a.step(frames), b.step(frames))
    with pytest.warns(DeprecationWarning, match="`cfg_scale`"):
        c = model.session(seed=3, cfg=2.0)
    assert np.array_equal(c.step(frames), model.session(seed=3, cfg_scale=2.0).step(frames))

