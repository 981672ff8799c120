"""troupe: real-time human interaction motion generation, from Python.

    import numpy as np, troupe
    with troupe.Model("onnx/bundles/armflow-tiny") as model, model.session(seed=7) as session:
        reactor = session.step(np.zeros((4, model.frame_dim), np.float32))  # [frames, frame_dim]

A thin ctypes layer over the C ABI (include/troupe.h): a failed call raises the subclass of
`TroupeError` for its status code (`troupe.errors`: `InvalidArgument`, `ModelError`, `Busy`, ...)
with the library's message, and an argument of the wrong type a `TypeError`; calls release the
GIL, so sessions on several Python threads run in parallel.
A `Model` may be shared by threads; a `Session` is used by one thread at a time.
"""

from __future__ import annotations

import ctypes
import os
import threading
import warnings
from typing import Any, Callable, Sequence

from numpy.typing import ArrayLike

import numpy as np

from . import _native, errors
from .errors import *  # noqa: F403  (the exception classes, re-exported)

#: The package's release; the library it loads says its own with :func:`version` (they match when
#: the wheel was built from one tree; the tests check it).
__version__ = "0.2.0"

__all__ = [*errors.__all__, "Model", "Session", "ArmflowModel", "UmfModel", "MagnetModel", "ArflowModel",
           "ArmflowSession", "MagnetSession", "ArflowSession", "bundles", "errors", "motion", "viewer", "step_sessions", "version", "limits",
           "set_load_threads", "set_compute_threads", "compute_threads", "progress", "call_budget", "seal_snapshot", "ACTOR_LATENT_SAMPLE", "ACTOR_LATENT_MEAN", "EULER", "RK4"]

ACTOR_LATENT_SAMPLE = 0
ACTOR_LATENT_MEAN = 1
EULER = 1  # TROUPE_SOLVER_EULER
RK4 = 2  # TROUPE_SOLVER_RK4
_SOLVERS = {"euler": EULER, "rk4": RK4}

_lib = _native.load()


def _check(status: int) -> None:
    if status != 0:
        message = _lib.troupe_last_error_message()
        name = _lib.troupe_status_name(status).decode()
        raise errors.from_status(status, message.decode() if message else "", name)


def version() -> str:
    """The library's version string."""
    return _lib.troupe_version_string().decode()


def limits() -> dict[str, int]:
    """troupe's limits (`troupe_limits`): every size from a file or a caller is checked against
    them before anything is allocated. Keys: `max_steps`, `max_text_tokens`, ..."""
    out = _native.Limits()
    _check(_lib.troupe_limits_get(ctypes.byref(out), ctypes.sizeof(out)))
    return {field[0]: getattr(out.values, field[0]) for field in _native.LimitValues._fields_}


def set_load_threads(threads: int) -> None:
    """How many threads loading a model may use from now on (0: one per core, 1: only the
    calling thread), process-wide."""
    _lib.troupe_set_load_threads(int(threads))


def set_compute_threads(threads: int) -> None:
    """How many threads the matrix products of every model may split over from now on (1, the
    default: the calling thread only; n >= 2: a pool of n library-owned threads; 0: one per
    core), process-wide."""
    _check(_lib.troupe_set_compute_threads(int(threads)))


def compute_threads() -> int:
    """The `set_compute_threads` setting now (1 by default)."""
    return _lib.troupe_compute_threads()


class progress:
    """Reports the progress of long calls made by this thread inside the `with` block (model
    loads, groups, clips) to `callback(done, total)`; a callback returning False cancels the call,
    which raises `TroupeError` (`TROUPE_ERR_CANCELLED`). An exception in the callback cancels too
    and is raised again after the call.

        with troupe.progress(lambda done, total: not stop.is_set()):
            group = model.generate_group(people=64)
    """

    def __init__(self, callback: Callable[[int, int], bool]):
        self._callback = callback
        self._error: BaseException | None = None

        def call(_user: Any, done: int, total: int) -> int:
            try:
                return 0 if self._callback(done, total) else 1
            except BaseException as e:  # never unwind into the library
                self._error = e
                return 1

        self._c_callback = _native.PROGRESS_FN(call)

    def __enter__(self) -> progress:
        _lib.troupe_set_progress_callback(self._c_callback, None)
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, traceback: Any) -> None:
        _lib.troupe_set_progress_callback(_native.PROGRESS_FN(), None)
        if self._error is not None and kind is not None:
            raise self._error from value


def seal_snapshot(snapshot: bytes | bytearray | memoryview, key: bytes) -> bytes:
    """`snapshot` sealed under `key` (at least 16 bytes, kept secret): an HMAC-SHA-256 tag only a
    holder of the key can make, for snapshot stores others can write. `model.restore(sealed,
    key=key)` restores it; another key or any changed byte is refused (docs/SNAPSHOTS.md)."""
    data, key = bytes(snapshot), bytes(key)
    size = ctypes.c_size_t()
    _check(_lib.troupe_snapshot_seal(data, len(data), key, len(key), None, 0, ctypes.byref(size)))
    buf = ctypes.create_string_buffer(size.value)
    _check(_lib.troupe_snapshot_seal(data, len(data), key, len(key), buf, size.value, ctypes.byref(size)))
    return buf.raw[:size.value]


class call_budget:
    """Bounds the long calls this thread makes inside the `with` block (groups, clips, MAGNet
    and ARFlow generations): a call that would take more than `work` units (a group's network
    evaluations, a clip's tokens x steps, a MAGNet generation's sampler iterations, an ARFlow
    generation's sampler steps) raises `InvalidArgument` before it starts; one that runs past
    `seconds` stops with `TroupeError` (`TROUPE_ERR_CANCELLED`). 0 sets no bound. Blocks nest:
    leaving one puts the enclosing block's budget back.

        with troupe.call_budget(work=5000, seconds=2.0):
            group = model.umf.generate_group(people=4)
    """

    _stack = threading.local()

    def __init__(self, work: int = 0, seconds: float = 0.0):
        self._budget = _native.CallBudget(max_work=work, max_seconds=seconds)

    def __enter__(self) -> call_budget:
        _check(_lib.troupe_set_call_budget(ctypes.byref(self._budget)))
        stack = call_budget._stack.__dict__.setdefault("budgets", [])
        stack.append(self._budget)
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, traceback: Any) -> None:
        stack = call_budget._stack.__dict__["budgets"]
        stack.pop()
        _check(_lib.troupe_set_call_budget(ctypes.byref(stack[-1]) if stack else None))


def _floats(x: ArrayLike, what: str, length: int | None = None) -> np.ndarray:
    """`x` as contiguous float32; a `TypeError` for text or anything not numbers (never a
    string read as a number), a `ShapeMismatch` for the wrong number of floats."""
    if isinstance(x, (str, bytes)):
        raise TypeError(f"{what} must be an array of numbers, got {type(x).__name__}")
    try:
        a = np.ascontiguousarray(x, dtype=np.float32)
    except (TypeError, ValueError) as e:
        raise TypeError(f"{what} must be an array of numbers: {e}") from None
    if length is not None and a.size != length:
        raise errors.ShapeMismatch(f"{what} must have {length} floats, got {a.size}")
    return a


def _ptr(a: np.ndarray) -> Any:
    return a.ctypes.data_as(_native.f32p)


class Model:
    """A loaded bundle (a directory or a tar archive of one). Thread-safe; sessions keep it alive."""

    def __init__(self, path: str | os.PathLike):
        handle = _native.model_p()
        _check(_lib.troupe_model_load_file(os.fsencode(path), ctypes.byref(handle)))
        self._handle = handle

    @classmethod
    def from_bytes(cls, archive: bytes) -> "Model":
        """Loads a bundle from the bytes of an uncompressed tar archive."""
        self = cls.__new__(cls)
        handle = _native.model_p()
        _check(_lib.troupe_model_load_memory(archive, len(archive), ctypes.byref(handle)))
        self._handle = handle
        return self

    def _h(self) -> _native.model_p:
        if not self._handle:
            raise ValueError("the model is closed")
        return self._handle

    family = property(lambda self: _lib.troupe_model_family(self._h()).decode(),
                      doc='the family: "armflow", "umf", "magnet" or "arflow"')

    @property
    def armflow(self) -> ArmflowModel:
        """What only an ARMFlow model offers (the official clip); `Unsupported` for another family."""
        return _family_view(self, self.family, "armflow", ArmflowModel)

    @property
    def umf(self) -> UmfModel:
        """What only a UMF model offers (groups); `Unsupported` for another family."""
        return _family_view(self, self.family, "umf", UmfModel)

    @property
    def magnet(self) -> MagnetModel:
        """What only a MAGNet model offers (its tasks); `Unsupported` for another family."""
        return _family_view(self, self.family, "magnet", MagnetModel)

    @property
    def arflow(self) -> ArflowModel:
        """What only an ARFlow model offers (whole reactions); `Unsupported` for another family."""
        return _family_view(self, self.family, "arflow", ArflowModel)

    frame_dim = property(lambda self: _lib.troupe_model_frame_dim(self._h()), doc="floats per frame")
    fps = property(lambda self: _lib.troupe_model_fps(self._h()), doc="frames per second")
    frames_per_token = property(lambda self: _lib.troupe_model_frames_per_token(self._h()))
    latency_frames = property(lambda self: _lib.troupe_model_latency_frames(self._h()))
    joints_latency_frames = property(lambda self: _lib.troupe_model_joints_latency_frames(self._h()),
                                     doc="latency when the actor streams joint positions (one frame more)")
    condition_dim = property(lambda self: _lib.troupe_model_condition_dim(self._h()))
    latent_dim = property(lambda self: _lib.troupe_model_latent_dim(self._h()))

    @property
    def condition_labels(self) -> list[str]:
        """The named conditions the bundle was trained on (the demo model's partner rules)."""
        h = self._h()
        n = _lib.troupe_model_condition_label_count(h)
        return [_lib.troupe_model_condition_label(h, i).decode() for i in range(n)]

    @property
    def reduced_precision(self) -> dict[str, str]:
        """The graphs whose weights are not float32, by role (`{"velocity": "int8", ...}`), as
        the manifest declares and the load checked; empty for a float32 bundle."""
        h = self._h()
        n = _lib.troupe_model_reduced_precision_count(h)
        return {
            _lib.troupe_model_reduced_precision_graph(h, i).decode():
                _lib.troupe_model_reduced_precision_weights(h, i).decode()
            for i in range(n)
        }

    def condition(self, label: str) -> np.ndarray:
        """The conditioning vector of a named condition (`model.condition("mirror")`)."""
        out = np.empty(self.condition_dim, np.float32)
        _check(_lib.troupe_model_condition_for_label(self._h(), label.encode(), _ptr(out), out.size))
        return out

    def max_output_frames(self, n_actor_frames: int) -> int:
        """The most reactor frames one step with `n_actor_frames` frames can return."""
        return _lib.troupe_model_max_output_frames(self._h(), n_actor_frames)

    @property
    def identity(self) -> bytes:
        """The model's identity (32 bytes): the SHA-256 of its bundle's files as the load read
        them. Two processes hold the same model exactly when their identities are equal."""
        out = ctypes.create_string_buffer(32)
        _check(_lib.troupe_model_identity(self._h(), out))
        return out.raw

    def restore(self, snapshot: bytes | bytearray | memoryview, key: bytes | None = None) -> "Session":
        """A session that goes on exactly where `Session.snapshot()` saved it, bit for bit. The
        snapshot may come from another process or machine, but only from this model (the same
        bundle files); a truncated, altered or foreign one raises InvalidArgument. With `key`,
        the snapshot must be sealed under it (`Session.snapshot(key=...)`, `seal_snapshot`):
        another key, a changed byte or an unsealed snapshot raise InvalidArgument."""
        data = bytes(snapshot)
        handle = _native.session_p()
        if key is None:
            _check(_lib.troupe_session_restore(self._h(), data, len(data), ctypes.byref(handle)))
        else:
            key = bytes(key)
            _check(_lib.troupe_session_restore_sealed(self._h(), data, len(data), key, len(key),
                                                      ctypes.byref(handle)))
        return Session._adopting(self, handle)

    clip_frames = property(lambda self: _lib.troupe_model_clip_frames(self._h()),
                           doc="frames per clip: per person of a umf bundle, of an official "
                               "ARMFlow clip (0 otherwise)")

    # The 0.1 names of the family calls, kept for one release.
    def generate_clip(self, *args: Any, **kwargs: Any) -> Any:
        """Deprecated since 0.2: `model.armflow.generate_clip`."""
        _deprecated("Model.generate_clip", "model.armflow.generate_clip")
        return self.armflow.generate_clip(*args, **kwargs)

    def generate_group(self, *args: Any, cfg: float | None = None, **kwargs: Any) -> Any:
        """Deprecated since 0.2: `model.umf.generate_group` (its `cfg` is `cfg_scale`)."""
        _deprecated("Model.generate_group", "model.umf.generate_group")
        if cfg is not None:
            kwargs["cfg_scale"] = cfg
        return self.umf.generate_group(*args, **kwargs)

    def magnet_generate(self, *args: Any, **kwargs: Any) -> Any:
        """Deprecated since 0.2: `model.magnet.generate`."""
        _deprecated("Model.magnet_generate", "model.magnet.generate")
        return self.magnet.generate(*args, **kwargs)

    def arflow_generate(self, *args: Any, **kwargs: Any) -> Any:
        """Deprecated since 0.2: `model.arflow.generate`."""
        _deprecated("Model.arflow_generate", "model.arflow.generate")
        return self.arflow.generate(*args, **kwargs)

    @property
    def magnet_configs(self) -> list[str]:
        """Deprecated since 0.2: `model.magnet.configs` (empty for another family)."""
        _deprecated("Model.magnet_configs", "model.magnet.configs")
        return self.magnet.configs if self.family == "magnet" else []

    @property
    def magnet_people(self) -> int:
        """Deprecated since 0.2: `model.magnet.people` (0 for another family)."""
        _deprecated("Model.magnet_people", "model.magnet.people")
        return _lib.troupe_magnet_people(self._h())

    @property
    def group_stages(self) -> int:
        """Deprecated since 0.2: `model.umf.stages` (0 for another family)."""
        _deprecated("Model.group_stages", "model.umf.stages")
        return _lib.troupe_umf_stages(self._h())

    @property
    def group_tokens(self) -> int:
        """Deprecated since 0.2: `model.umf.tokens` (0 for another family)."""
        _deprecated("Model.group_tokens", "model.umf.tokens")
        return _lib.troupe_umf_tokens(self._h())

    @property
    def clip_tokens(self) -> int:
        """Deprecated since 0.2: `model.armflow.clip_tokens` (0 for another family)."""
        _deprecated("Model.clip_tokens", "model.armflow.clip_tokens")
        return _lib.troupe_armflow_clip_tokens(self._h())

    text_token_dim = property(lambda self: _lib.troupe_model_text_token_dim(self._h()),
                              doc="width of the CLIP token features encode_text reads (0: no text branch)")

    def encode_text(self, clip_tokens: ArrayLike, eot_index: int) -> np.ndarray:
        """The official text branch (official ARMFlow and UMF bundles): CLIP token features
        [tokens, text_token_dim] and the end-of-text index (argmax of CLIP's token ids) -> the
        condition [condition_dim]."""
        t = _floats(clip_tokens, "clip_tokens")
        if t.ndim != 2 or t.shape[1] != self.text_token_dim:
            raise ValueError(f"clip_tokens must be [tokens, {self.text_token_dim}], got {list(t.shape)}")
        out = np.empty(self.condition_dim, np.float32)
        _check(_lib.troupe_text_encode(self._h(), _ptr(t), t.shape[0], eot_index, _ptr(out), out.size))
        return out

    def _condition_or_prompt(self, condition: str | ArrayLike | None, prompt: str | None) -> Any:
        if prompt is not None:
            if condition is not None:
                raise ValueError("give a condition or a prompt, not both")
            return self.encode_prompt(prompt)
        return None if condition is None else _floats(condition, "condition")

    takes_prompts = property(lambda self: bool(_lib.troupe_model_takes_prompts(self._h())),
                             doc="whether encode_prompt works: the bundle carries CLIP's text tower and tokenizer")

    def encode_prompt(self, prompt: str) -> np.ndarray:
        """A text prompt -> the condition [condition_dim], as the official code computes it:
        CLIP's tokenizer (lower-cased, cleaned, cut at 77 tokens), CLIP's text tower and the
        bundle's text branch. "" is the official "no text". Cached per prompt in the model."""
        if not isinstance(prompt, str):
            raise TypeError(f"prompt must be a str, got {type(prompt).__name__}")
        if "\0" in prompt:
            raise ValueError("prompt holds a NUL character")
        out = np.empty(self.condition_dim, np.float32)
        _check(_lib.troupe_text_prompt_encode(self._h(), prompt.encode("utf-8"), _ptr(out), out.size))
        return out

    def session(self, seed: int = 0, steps: int | None = None, cfg_scale: float | None = None,
                capacity: int | None = None, actor_latent: int | None = None,
                condition: str | ArrayLike | None = None, prompt: str | None = None,
                partner_opening: ArrayLike | None = None, live_config: str | None = None,
                early: bool = False, cfg: float | None = None) -> "Session":
        """Starts a stream: `Session(model, ...)` (its arguments are this call's)."""
        return Session(self, seed, steps, cfg_scale, capacity, actor_latent, condition, prompt,
                       partner_opening=partner_opening, live_config=live_config, early=early, cfg=cfg)

    def close(self) -> None:
        """Releases this reference (sessions keep the model alive)."""
        handle, self._handle = getattr(self, "_handle", None), None  # type: ignore[assignment]
        if handle:
            _lib.troupe_model_free(handle)

    __del__ = close

    def __enter__(self) -> Model:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _deprecated(old: str, new: str) -> None:
    """Warns once per call site that `old` is deprecated since 0.2 and goes in 0.3."""
    warnings.warn(f"{old} is deprecated since troupe 0.2 and goes in 0.3: use {new}", DeprecationWarning,
                  stacklevel=3)


def _family_view(owner: Any, family: str, needed: str, view: Any) -> Any:
    """`view(owner)` when `family` is `needed`; else Unsupported, as the C calls answer."""
    if family != needed:
        article = "an" if family.startswith("a") else "a"
        raise Unsupported(f"this is {article} `{family}` model; only {needed} models have `.{needed}`")
    return view(owner)


class ArmflowModel:
    """What only an ARMFlow model offers, as `model.armflow`: the official clip loop."""

    def __init__(self, model: Model):
        self._model = model

    clip_tokens = property(lambda self: _lib.troupe_armflow_clip_tokens(self._model._h()),
                           doc="tokens of an official ARMFlow clip (0 for a streaming-only bundle)")

    def generate_clip(self, actor: ArrayLike, condition: str | ArrayLike | None = None, seed: int = 0,
                      steps: int = 0, noise: Sequence[ArrayLike] | None = None, return_latents: bool = False,
                      prompt: str | None = None,
                      cfg_scale: float | None = None) -> np.ndarray | tuple[np.ndarray, np.ndarray | None]:
        """The official ARMFlow clip loop (an armflow bundle exported from the official layout):
        `actor` [frames, frame_dim] with 1..clip_frames frames, zero-padded to the clip.
        Returns the reactor motion [clip_frames, frame_dim] (and the reactor tokens
        [clip_tokens, latent_dim] with `return_latents`).

        `condition`: condition_dim floats, or None for the null condition; or `prompt`, a text
        (see encode_prompt). `steps`: MeanFlow steps per token, 0 for the bundle's default.
        `cfg_scale`: classifier-free guidance, None for the bundle's (`sampler.cfg_scale`, which
        the official sampler applies; 1 is off). `noise`: (actor_posterior [clip_tokens,
        latent_dim], reactor_noise [latent_dim]) replacing the seeded draws, the way to
        reproduce another implementation's run exactly. Releases the GIL."""
        h = self._model._h()
        a = _floats(actor, "actor")
        if a.ndim != 2 or a.shape[1] != self._model.frame_dim:
            raise errors.ShapeMismatch(f"actor must be [frames, {self._model.frame_dim}], got {list(a.shape)}")
        cond = self._model._condition_or_prompt(condition, prompt)
        opt = _native.ClipOptions()
        _check(_lib.troupe_armflow_clip_options_init(h, ctypes.byref(opt), ctypes.sizeof(opt)))
        opt.seed = seed
        if steps:
            opt.steps = steps
        if cfg_scale is not None:
            opt.cfg_scale = cfg_scale
        noise_struct = None
        if noise is not None:
            # `arrays` stays alive until the call returns, so the struct's pointers stay valid.
            arrays = [_floats(x, name) for x, name in zip(noise, ("actor_posterior", "reactor_noise"))]
            noise_struct = _native.ClipNoise(*[v for x in arrays for v in (_ptr(x), x.size)])
        motion = np.empty((self._model.clip_frames, self._model.frame_dim), np.float32)
        latents = np.empty((self.clip_tokens, self._model.latent_dim), np.float32) if return_latents else None
        _check(_lib.troupe_armflow_clip_generate_with_options(
            h, ctypes.byref(opt), _ptr(a), a.shape[0],
            None if cond is None else _ptr(cond), 0 if cond is None else cond.size,
            None if noise_struct is None else ctypes.byref(noise_struct),
            _ptr(motion), motion.size,
            None if latents is None else _ptr(latents), 0 if latents is None else latents.size))
        return (motion, latents) if return_latents else motion



class UmfModel:
    """What only a UMF model offers, as `model.umf`: groups from a text."""

    def __init__(self, model: Model):
        self._model = model

    stages = property(lambda self: _lib.troupe_umf_stages(self._model._h()), doc="pyramid stages")
    tokens = property(lambda self: _lib.troupe_umf_tokens(self._model._h()), doc="latent tokens per person")

    def generate_group(self, people: int, condition: str | ArrayLike | None = None, seed: int = 0,
                       cfg_scale: float | None = None, prior: Sequence[tuple[str, int]] | None = None,
                       reaction: tuple[str, int] | None = None, noise: Sequence[ArrayLike] | None = None,
                       return_latents: bool = False,
                       prompt: str | None = None) -> np.ndarray | tuple[np.ndarray, np.ndarray | None]:
        """Generates `people` persons' motion with a `umf` bundle: float32
        [people, clip_frames, frame_dim] (and [people, tokens, latent_dim] latents with
        `return_latents`).

        `condition`: condition_dim floats ([prior text ; reaction text]) or None for the null
        condition; or `prompt`, a text (see encode_prompt). `prior`: one (method, steps) per pyramid stage, method "euler" or "rk4";
        `reaction`: one (method, steps). `noise`: (prior, jumps, reactions) arrays replacing the
        seeded draws (lengths as troupe_umf_noise_lengths gives). Releases the GIL."""
        h = self._model._h()
        opt = _native.GroupOptions()
        _check(_lib.troupe_umf_options_init(h, ctypes.byref(opt), ctypes.sizeof(opt)))
        opt.seed = seed
        if cfg_scale is not None:
            opt.cfg_scale = cfg_scale
        if prior is not None:
            if len(prior) > _native.MAX_STAGES:
                raise ValueError(f"at most {_native.MAX_STAGES} stages")
            opt.stage_count = len(prior)
            for k, (method, steps) in enumerate(prior):
                opt.stage_solver[k] = _solver(method)
                opt.stage_steps[k] = _native.checked_int(f"prior stage {k} steps", steps, ctypes.c_uint32)
        if reaction is not None:
            opt.reaction_solver, opt.reaction_steps = _solver(reaction[0]), reaction[1]
        cond = self._model._condition_or_prompt(condition, prompt)
        noise_struct = None
        if noise is not None:
            # `arrays` stays alive until the call returns, so the struct's pointers stay valid.
            arrays = [_floats(a, name) for a, name in zip(noise, ("prior", "jumps", "reactions"))]
            noise_struct = _native.GroupNoise(*[v for a in arrays for v in (_ptr(a), a.size)])
        motion = np.empty((people, self._model.clip_frames, self._model.frame_dim), np.float32)
        latents = np.empty((people, self.tokens, self._model.latent_dim), np.float32) if return_latents else None
        _check(_lib.troupe_umf_generate(
            h, ctypes.byref(opt),
            None if cond is None else _ptr(cond), 0 if cond is None else cond.size,
            people, None if noise_struct is None else ctypes.byref(noise_struct),
            _ptr(motion), motion.size,
            None if latents is None else _ptr(latents), 0 if latents is None else latents.size))
        return (motion, latents) if return_latents else motion


class MagnetModel:
    """What only a MAGNet model offers, as `model.magnet`: its released tasks."""

    def __init__(self, model: Model):
        self._model = model

    people = property(lambda self: _lib.troupe_magnet_people(self._model._h()),
                      doc="people the model generates together")

    @property
    def configs(self) -> list[str]:
        """The released sampling configurations, by the official YAML's name (`dd100`,
        `dd100_partner_prediction`, ...)."""
        h = self._model._h()
        return [_lib.troupe_magnet_config(h, i).decode("utf-8")
                for i in range(_lib.troupe_magnet_config_count(h))]

    def _options(self, samples: int | None, steps: int | None, seq_len: int | None, seed: int | None,
                        eta: float | None, x0_guidance: bool, keyframes: Sequence[int] | None) -> Any:
        opt = _native.MagnetOptions()
        _check(_lib.troupe_magnet_options_init(ctypes.byref(opt), ctypes.sizeof(opt)))
        opt.samples, opt.steps, opt.seq_len = samples or 0, steps or 0, seq_len or 0
        if seed is not None:
            opt.flags |= _native.MAGNET_SEED
            opt.seed = seed
        if eta is not None:
            opt.flags |= _native.MAGNET_ETA
            opt.eta = eta
        if not x0_guidance:
            opt.flags |= _native.MAGNET_NO_X0_GUIDANCE
        if keyframes is not None:
            if len(keyframes) > _native.MAGNET_MAX_KEYFRAMES:
                raise ValueError(f"at most {_native.MAGNET_MAX_KEYFRAMES} key frames")
            opt.flags |= _native.MAGNET_KEYFRAMES
            opt.keyframe_count = len(keyframes)
            for i, k in enumerate(keyframes):
                opt.keyframes[i] = _native.checked_int(f"key frame {i}", k, ctypes.c_uint32)
        return opt

    def generate(self, config: str | dict, frames: ArrayLike, present: ArrayLike | None = None,
                 samples: int | None = None,
                 steps: int | None = None, seq_len: int | None = None, seed: int | None = None,
                 eta: float | None = None, x0_guidance: bool = True, keyframes: Sequence[int] | None = None,
                 draws: ArrayLike | None = None) -> np.ndarray:
        """Runs a MAGNet sampling configuration on `frames` [F, people, 145] (per person and
        frame: betas, the 21 body joints' 6-D rotations, the root's pose in the world, y up) and
        returns the frames it generates, float32 [samples, frames, people, 145], every root in
        the input's world frame.

        `config`: a name from `configs`, or a whole configuration (a dict with the fields
        of the manifest's `sampling` entries). `present`: [F, people] booleans (None: everyone).
        The other arguments change the configuration for this call (None keeps it);
        `x0_guidance=False` turns the decoder-space corrections off (three to five times
        cheaper, not the released behaviour). `draws`: the run's standard normals instead of
        troupe's generator, one flat array from which each draw (in the order docs/MAGNET.md
        lists) takes the next ones it needs, the way to replay another implementation's
        recorded draws exactly; the run must take all of them. Releases the GIL."""
        import json

        name = (json.dumps(config) if isinstance(config, dict) else str(config)).encode("utf-8")
        data = _floats(frames, "frames")
        h = self._model._h()
        people = _lib.troupe_magnet_people(h)
        if data.ndim != 3 or (people and data.shape[1:] != (people, 145)):
            raise errors.ShapeMismatch(f"frames must be [frames, {people or 'people'}, 145], got shape {data.shape}")
        opt = self._options(samples, steps, seq_len, seed, eta, x0_guidance, keyframes)
        s, f, p = ctypes.c_size_t(), ctypes.c_size_t(), ctypes.c_size_t()
        _check(_lib.troupe_magnet_output_shape(h, name, ctypes.byref(opt), data.shape[0],
                                               ctypes.byref(s), ctypes.byref(f), ctypes.byref(p)))
        mask = None
        if present is not None:
            mask = np.ascontiguousarray(np.asarray(present, dtype=bool).astype(np.uint8))
            if mask.shape != data.shape[:2]:
                raise ValueError(f"present must be {data.shape[:2]}, got {mask.shape}")
        out = np.empty((s.value, f.value, p.value, 145), np.float32)
        present_p = None if mask is None else mask.ctypes.data_as(ctypes.POINTER(ctypes.c_uint8))
        if draws is None:
            _check(_lib.troupe_magnet_generate(h, name, ctypes.byref(opt), _ptr(data), data.shape[0], present_p,
                                               _ptr(out), out.size))
            return out
        normals, used = _normals(draws), ctypes.c_size_t()
        _check(_lib.troupe_magnet_generate_with_draws(h, name, ctypes.byref(opt), _ptr(data), data.shape[0],
                                                      present_p, _ptr(normals), normals.size, ctypes.byref(used),
                                                      _ptr(out), out.size))
        _all_used(used.value, normals.size)
        return out


class ArflowModel:
    """What only an ARFlow model offers, as `model.arflow`: whole reactions with penetration
    guidance."""

    def __init__(self, model: Model):
        self._model = model

    def generate(self, actor: ArrayLike, seed: int = 0, steps: int | None = None, guidance: float | None = None,
                 weight: float | None = None, eta: float | None = None, d_safe: float | None = None,
                 sigma: float | None = None, squared: bool | None = None,
                 guided_backprojection: bool | None = None, mixing: str | None = None,
                 draws: ArrayLike | None = None) -> np.ndarray:
        """ARFlow: the reactor's interhuman262 frames [T, 262] for the actor's (one world frame
        for both). Unset settings take the bundle's defaults (5 steps, guidance λ 2, weight w 0.7,
        η 0, d_safe 0.02 m, linear hinge, guided back-projection, `mixing` "linear"; see
        docs/ARFLOW.md). `draws`: the run's standard normals instead of the seed's, one flat
        array from which each draw (the start noise when σ > 0, then one ε per step when η > 0,
        T × 262 each) takes the next ones; the run must take all of them. Releases the GIL."""
        a = _floats(actor, "actor")
        if a.ndim != 2 or a.shape[1] != 262:
            raise errors.ShapeMismatch(f"actor must be [frames, 262], got {list(a.shape)}")
        h = self._model._h()
        opt = _arflow_options(h, seed, steps, guidance, weight, eta, d_safe, sigma, squared,
                              guided_backprojection, mixing)
        out = np.empty_like(a)
        if draws is None:
            _check(_lib.troupe_arflow_generate(h, ctypes.byref(opt), _ptr(a), a.shape[0], _ptr(out), out.shape[0]))
            return out
        normals, used = _normals(draws), ctypes.c_size_t()
        _check(_lib.troupe_arflow_generate_with_draws(h, ctypes.byref(opt), _ptr(a), a.shape[0], _ptr(normals),
                                                      normals.size, ctypes.byref(used), _ptr(out), out.shape[0]))
        _all_used(used.value, normals.size)
        return out


class ArmflowSession:
    """What only an ARMFlow stream takes, as `session.armflow`."""

    def __init__(self, session: Session):
        self._session = session

    def set_recentring(self, enabled: bool = True, distance: float = 1.0) -> None:
        """Recentring: before each token, when the actor's root is more than `distance` metres
        on the floor from where the networks' frame is centred, the centre moves to the actor
        and the networks' state is rebuilt around it from the last 8 tokens of both people's
        motion (kept while it is on). Frames and poses stay in the stream's frame; a model
        trained near the origin keeps its quality however far the actor walks. Off again with
        `enabled=False`; `Unsupported` for a session that cannot recentre."""
        self._session._call(_lib.troupe_armflow_session_set_recentring, 1 if enabled else 0, distance)

    def queue_noise(self, actor_noise: ArrayLike, reactor_noise: ArrayLike) -> None:
        """Queues one token's noise (latent_dim floats each: the actor posterior's normals, the
        reactor's start noise), used before the seeded generator."""
        a = _floats(actor_noise, "actor_noise")
        r = _floats(reactor_noise, "reactor_noise", a.size)
        self._session._call(_lib.troupe_armflow_session_queue_noise, _ptr(a), _ptr(r), a.size)


class MagnetSession:
    """What only a MAGNet live partner takes, as `session.magnet`."""

    def __init__(self, session: Session):
        self._session = session

    def set_partner_opening(self, frames: ArrayLike) -> None:
        """The partner's opening frames (float32 [context frames, 145]); before the first step
        or after a reset."""
        f = _floats(frames, "frames")
        dim = self._session.frame_dim
        if f.ndim != 2 or f.shape[1] != dim:
            raise errors.ShapeMismatch(f"opening frames must be [frames, {dim}], got {list(f.shape)}")
        self._session._call(_lib.troupe_magnet_session_set_partner_opening, _ptr(f), f.shape[0])

    def set_early_emission(self, early: bool) -> None:
        """Send the partner's frames as each chunk generates them (lower latency); before the
        first step or after a reset."""
        self._session._call(_lib.troupe_magnet_session_set_early_emission, 1 if early else 0)

    def set_live_config(self, config: str) -> None:
        """The sampling configuration the partner runs (a released name or JSON); before the
        first step or after a reset."""
        self._session._call(_lib.troupe_magnet_session_set_live_config, config.encode("utf-8"))


class ArflowSession:
    """What only an ARFlow online stream takes, as `session.arflow`."""

    def __init__(self, session: Session):
        self._session = session

    def set_options(self, seed: int = 0, **settings: Any) -> None:
        """The stream's sampler settings: the bundle's with `settings` changed (the arguments
        of `model.arflow.generate`) and `seed`."""
        opt = _arflow_options(self._session._model._h(), seed, *(settings.pop(k, None) for k in (
            "steps", "guidance", "weight", "eta", "d_safe", "sigma", "squared", "guided_backprojection", "mixing")))
        if settings:
            raise TypeError(f"unknown ARFlow settings: {sorted(settings)}")
        self._session._call(_lib.troupe_arflow_session_set_options, ctypes.byref(opt))


def _normals(draws: ArrayLike) -> np.ndarray:
    """Injected draws as the flat float32 queue the C calls read."""
    return _floats(np.asarray(draws, dtype=np.float32).reshape(-1), "draws")


def _all_used(used: int, given: int) -> None:
    if used != given:
        raise ValueError(f"the run took {used} of the {given} normals given: they are not its draws")


def _arflow_options(h: _native.model_p, seed: int, steps: int | None, guidance: float | None,
                    weight: float | None, eta: float | None, d_safe: float | None, sigma: float | None,
                    squared: bool | None, guided_backprojection: bool | None,
                    mixing: str | None) -> _native.ArflowOptions:
    """The bundle's ARFlow settings with the given changes (None keeps a setting)."""
    if mixing not in (None, "linear", "variance_preserving"):
        raise ValueError(f"mixing is linear or variance_preserving, not {mixing!r}")
    opt = _native.ArflowOptions()
    _check(_lib.troupe_arflow_options_init(h, ctypes.byref(opt), ctypes.sizeof(opt)))
    opt.seed = seed
    for name, value in (("steps", steps), ("guidance", guidance), ("weight", weight), ("eta", eta),
                        ("d_safe", d_safe), ("sigma", sigma)):
        if value is not None:
            setattr(opt, name, value)
    for flag, on in ((_native.ARFLOW_SQUARED_HINGE, squared),
                     (_native.ARFLOW_UNGUIDED_BACKPROJECTION,
                      None if guided_backprojection is None else not guided_backprojection),
                     (_native.ARFLOW_VARIANCE_PRESERVING, None if mixing is None else mixing == "variance_preserving")):
        if on is not None:
            opt.flags = (opt.flags | flag) if on else (opt.flags & ~flag)
    return opt


def _solver(method: str | int) -> int:
    if isinstance(method, str):
        if method.lower() not in _SOLVERS:
            raise ValueError(f"unknown solver {method!r} (euler or rk4)")
        return _SOLVERS[method.lower()]
    return int(method)


def step_sessions(sessions: Sequence[Session], actors: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Advances many sessions of one model in one call (`troupe_sessions_step`): `actors[i]`
    (float32 [n_i, frame_dim], n_i >= 0) goes to `sessions[i]`; returns each session's reactor
    frames. The weights are read once per token for all sessions, which is how a crowd runs in
    real time; each result equals `sessions[i].step(actors[i])` up to float rounding. On error no
    session changes."""
    sessions = [errors.expect_type(s, Session, "each of sessions") for s in sessions]
    actors = list(actors)
    if len(actors) != len(sessions):
        raise ValueError(f"{len(sessions)} sessions but {len(actors)} actor arrays")
    actors = [s._actor(a) for s, a in zip(sessions, actors)]
    if len({id(s) for s in sessions}) != len(sessions):
        raise ValueError("a session appears twice")
    n = len(sessions)
    outs = [s._out_for(a) for s, a in zip(sessions, actors)]
    handles = (_native.session_p * n)(*[s._handle for s in sessions])
    if not all(handles):
        raise ValueError("a session is closed")
    c_size = ctypes.c_size_t
    ins = (_native.f32p * n)(*[_ptr(a) for a in actors])
    outp = (_native.f32p * n)(*[_ptr(o) for o in outs])
    n_in = (c_size * n)(*[a.shape[0] for a in actors])
    cap = (c_size * n)(*[o.shape[0] for o in outs])
    written = (c_size * n)()
    locked = []
    try:
        for s in sessions:
            if not s._lock.acquire(blocking=False):
                raise Busy("a troupe Session is being used by two threads at once")
            locked.append(s)
        _check(_lib.troupe_sessions_step(handles, n, ins, n_in, outp, cap, written))
    finally:
        for s in locked:
            s._lock.release()
    return [o[: written[i]] for i, o in enumerate(outs)]


class Session:
    """One stream: an armflow reactor answering an actor, or a magnet live partner answering a
    user. Use it from one thread at a time."""

    def __init__(self, model: Model, seed: int = 0, steps: int | None = None, cfg_scale: float | None = None,
                 capacity: int | None = None, actor_latent: int | None = None,
                 condition: str | ArrayLike | None = None, prompt: str | None = None,
                 partner_opening: ArrayLike | None = None, live_config: str | None = None, early: bool = False,
                 cfg: float | None = None):
        """Starts a stream on `model`; unset options take the bundle's defaults. Every
        streaming family takes `seed`, `steps` and `capacity` (context tokens); an armflow
        model also `cfg_scale`, `actor_latent`, `condition` or `prompt`; a two-person magnet
        model the partner's `partner_opening` frames (float32 [context frames, 145]), a
        `live_config` (a released name or JSON) and `early` emission (docs/MAGNET.md).
        `cfg` is the deprecated 0.1 name of `cfg_scale`."""
        errors.expect_type(model, Model, "model")
        if condition is not None and prompt is not None:
            raise ValueError("give a condition or a prompt, not both")
        if cfg is not None:
            _deprecated("the `cfg` argument", "`cfg_scale`")
            cfg_scale = cfg if cfg_scale is None else cfg_scale
        h = model._h()
        opt = _native.SessionOptions()
        _check(_lib.troupe_session_options_init(h, ctypes.byref(opt), ctypes.sizeof(opt)))
        opt.seed = seed
        if steps is not None:
            opt.steps = steps
        if capacity is not None:
            opt.context_capacity = capacity
        handle = _native.session_p()
        if model.family == "armflow":
            own = _native.ArmflowSessionOptions()
            _check(_lib.troupe_armflow_session_options_init(h, ctypes.byref(own), ctypes.sizeof(own)))
            if cfg_scale is not None:
                own.cfg_scale = cfg_scale
            if actor_latent is not None:
                own.actor_latent = actor_latent
            _check(_lib.troupe_armflow_session_new(h, ctypes.byref(opt), ctypes.byref(own), ctypes.byref(handle)))
        else:
            # Another family refuses what only ARMFlow takes, as the C call does.
            if cfg_scale is not None:
                opt.cfg_scale = cfg_scale
            if actor_latent is not None:
                opt.actor_latent = actor_latent
            _check(_lib.troupe_session_new(h, ctypes.byref(opt), ctypes.byref(handle)))
        self._adopt(model, handle)
        if condition is not None:
            self.set_condition(condition)
        if prompt is not None:
            self.set_prompt(prompt)
        if live_config is not None:
            self.magnet.set_live_config(live_config)
        if partner_opening is not None:
            self.magnet.set_partner_opening(partner_opening)
        if early:
            self.magnet.set_early_emission(True)

    def _adopt(self, model: Model, handle: _native.session_p) -> None:
        self._handle = handle
        self._lock = threading.Lock()  # a session is single-threaded; fail loudly, not racily
        self.frame_dim = model.frame_dim
        self.condition_dim = model.condition_dim
        self.latent_dim = model.latent_dim
        self._frames_per_token = model.frames_per_token
        # Frames a stream may hold back and send with a later step (a magnet window; 0 for armflow).
        self._held_back = _lib.troupe_model_max_output_frames(model._h(), 0)
        self._model = model
        self.family = model.family

    @property
    def armflow(self) -> ArmflowSession:
        """What only an ARMFlow stream takes (recentring, queued token noise); `Unsupported`
        for another family's stream."""
        return _family_view(self, self.family, "armflow", ArmflowSession)

    @property
    def magnet(self) -> MagnetSession:
        """What only a MAGNet live partner takes (its opening, configuration, early emission);
        `Unsupported` for another family's stream."""
        return _family_view(self, self.family, "magnet", MagnetSession)

    @property
    def arflow(self) -> ArflowSession:
        """What only an ARFlow online stream takes (its sampler settings); `Unsupported` for
        another family's stream."""
        return _family_view(self, self.family, "arflow", ArflowSession)

    @classmethod
    def _adopting(cls, model: Model, handle: _native.session_p) -> "Session":
        """A Session around a handle the library made (a restored stream)."""
        self = cls.__new__(cls)
        self._adopt(model, handle)
        return self

    def snapshot(self, key: bytes | None = None) -> bytes:
        """Everything the stream needs to go on, as bytes (versioned, checksummed, bound to the
        model): `model.restore(snapshot)`, in this process or another, continues it bit for bit.
        The session is unchanged. With `key` (at least 16 bytes, kept secret) the snapshot is
        sealed under it (`seal_snapshot`) and restores only with `model.restore(..., key=key)`."""
        size = ctypes.c_size_t()
        self._call(_lib.troupe_session_snapshot, None, 0, ctypes.byref(size))
        buf = ctypes.create_string_buffer(size.value)
        self._call(_lib.troupe_session_snapshot, buf, size.value, ctypes.byref(size))
        plain = buf.raw[:size.value]
        return plain if key is None else seal_snapshot(plain, key)

    def _call(self, fn: Any, *args: Any) -> None:
        if not self._handle:
            raise ValueError("the session is closed")
        if not self._lock.acquire(blocking=False):
            raise Busy("a troupe Session is being used by two threads at once")
        try:
            _check(fn(self._handle, *args))
        finally:
            self._lock.release()

    def _actor(self, actor: ArrayLike) -> np.ndarray:
        a = _floats(actor, "actor")
        if a.ndim != 2 or a.shape[1] != self.frame_dim:
            raise errors.ShapeMismatch(f"actor must be [frames, {self.frame_dim}], got {list(a.shape)}")
        return a

    def _out_for(self, actor: np.ndarray) -> np.ndarray:
        """A buffer that always holds what a step with these frames returns."""
        fpt = max(self._frames_per_token, 1)  # ARFlow streams frames, not tokens
        rows = -(-actor.shape[0] // fpt) * fpt + self._held_back
        return np.empty((rows, self.frame_dim), np.float32)

    def step(self, actor: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Feeds actor frames (float32 [n, frame_dim], n >= 0) and returns the reactor frames that
        became ready ([m, frame_dim]). With `out` (a C-contiguous float32 [k, frame_dim] array),
        frames are written there and a view of its first m rows is returned."""
        a = self._actor(actor)
        if out is None:
            out = self._out_for(a)
        elif out.dtype != np.float32 or not out.flags.c_contiguous or out.ndim != 2 or out.shape[1] != self.frame_dim:
            raise ValueError(f"out must be a C-contiguous float32 [k, {self.frame_dim}] array")
        written = ctypes.c_size_t()
        self._call(_lib.troupe_session_step, _ptr(a), a.shape[0], _ptr(out), out.shape[0], ctypes.byref(written))
        return out[: written.value]

    def set_joints_format(self, fmt: motion.JointsFormat) -> None:
        """How `step_joints` reads actor positions (a `troupe.motion.JointsFormat`); forgets the
        joint stream's frames and placement."""
        c = motion._format(fmt)
        self._call(_lib.troupe_session_set_joints_format, ctypes.byref(c))

    def step_joints(self, positions: ArrayLike) -> motion.Poses:
        """Feeds actor joint positions ([n, 22, 3], as `set_joints_format` said; metres, Y up at the
        bundle's rate by default) and returns the reactor poses that became ready, in the caller's
        world (a `troupe.motion.Poses`). One frame more latency than `step`."""
        from .motion import _pose_buffers, _positions

        p = _positions(positions, "positions")
        n = ctypes.c_size_t()
        self._call(_lib.troupe_session_joints_ready_after, p.shape[0], ctypes.byref(n))
        poses, buffers = _pose_buffers(n.value)
        written = ctypes.c_size_t()
        self._call(_lib.troupe_session_step_joints, _ptr(p), p.shape[0], ctypes.byref(buffers), n.value,
                   ctypes.byref(written))
        return type(poses)(*(a[: written.value] for a in poses))

    @property
    def joints_placement(self) -> motion.Placement | None:
        """Where the reactor's poses are put (fixed by the first actor joint frame), or None."""
        from .motion import Placement

        c = _native.Placement()
        try:
            self._call(_lib.troupe_session_joints_placement, ctypes.byref(c))
        except TroupeError:
            return None
        return Placement(c)

    def output_frames(self, n_actor_frames: int) -> int:
        """Exactly how many frames a step with `n_actor_frames` frames would return now."""
        n = ctypes.c_size_t()
        self._call(_lib.troupe_session_output_frames, n_actor_frames, ctypes.byref(n))
        return n.value

    def reset(self) -> None:
        """Back to a fresh session with the current settings; queued noise is dropped."""
        self._call(_lib.troupe_session_reset)

    def set_seed(self, seed: int) -> None:
        self._call(_lib.troupe_session_set_seed, seed)

    def set_steps(self, steps: int) -> None:
        self._call(_lib.troupe_session_set_steps, steps)

    def set_cfg_scale(self, scale: float) -> None:
        self._call(_lib.troupe_session_set_cfg_scale, scale)

    def set_condition(self, condition: str | ArrayLike | None) -> None:
        """Sets the conditioning vector (condition_dim floats, or the name of one of the model's
        `condition_labels`); None selects the null condition."""
        if condition is None:
            self._call(_lib.troupe_session_set_condition, None, 0)
            return
        if isinstance(condition, str):
            condition = self._model.condition(condition)
        c = _floats(condition, "condition")
        self._call(_lib.troupe_session_set_condition, _ptr(c), c.size)

    def set_prompt(self, prompt: str) -> None:
        """Conditions the tokens from now on on a text prompt (bundles with takes_prompts)."""
        if not isinstance(prompt, str) or "\0" in prompt:
            raise ValueError("prompt must be a str without NUL characters")
        self._call(_lib.troupe_session_set_prompt, prompt.encode("utf-8"))

    def set_penetration_guard(self, enabled: bool = True, d_safe: float = 0.05, max_speed: float = 2.0) -> None:
        """The penetration guard (every streaming family): each frame sent is shifted in the floor
        plane out of the input person's body (joints nearer than `d_safe` metres), never faster
        than `max_speed` m/s (docs/MOTION.md). Off again with `enabled=False`."""
        self._call(_lib.troupe_session_set_penetration_guard, 1 if enabled else 0, d_safe, max_speed)

    def set_root_smoothing(self, enabled: bool = True, time_constant: float = 0.1) -> None:
        """The root smoothing (every streaming family): the generated person's root path on the
        floor filtered causally with `time_constant` seconds, the body moving with it, before the guard (no
        frame held back; the root lags by about the time constant). Off with `enabled=False`."""
        self._call(_lib.troupe_session_set_root_smoothing, 1 if enabled else 0, time_constant)

    def set_foot_lock(
        self,
        enabled: bool = True,
        contact_threshold: float = 0.5,
        release_frames: int = 4,
        max_stretch: float = 0.25,
    ) -> None:
        """The foot lock of the poses `step_joints` returns (streams whose frames carry contact
        labels: ARMFlow, ARFlow): while a foot's ankle
        contact label is at least `contact_threshold` the ankle stays where the contact began (the
        leg bent by two-bone IK); it returns to the motion over `release_frames` frames when the
        label drops or the motion's ankle is more than `max_stretch` metres away. No frame is
        held back. Off again with `enabled=False`."""
        self._call(
            _lib.troupe_session_set_foot_lock,
            1 if enabled else 0,
            contact_threshold,
            release_frames,
            max_stretch,
        )

    def queue_normals(self, normals: ArrayLike) -> None:
        """Queues standard normals for the stream's next draws (every streaming family), to
        replay another implementation's stream exactly: each draw takes the next ones it needs
        while any are queued, then the seed goes on as if they had been its; reset() drops them.
        An armflow stream takes whole tokens (the actor's posterior noise, then the reactor's
        start noise, latent_dim each), as `session.armflow.queue_noise` queues one."""
        a = _floats(np.asarray(normals, dtype=np.float32).reshape(-1), "normals")
        self._call(_lib.troupe_session_queue_normals, _ptr(a), a.size)

    # The 0.1 names of the family calls, kept for one release.
    def set_partner_opening(self, frames: ArrayLike) -> None:
        """Deprecated since 0.2: `session.magnet.set_partner_opening`."""
        _deprecated("Session.set_partner_opening", "session.magnet.set_partner_opening")
        self.magnet.set_partner_opening(frames)

    def set_early_emission(self, early: bool) -> None:
        """Deprecated since 0.2: `session.magnet.set_early_emission`."""
        _deprecated("Session.set_early_emission", "session.magnet.set_early_emission")
        self.magnet.set_early_emission(early)

    def set_live_config(self, config: str) -> None:
        """Deprecated since 0.2: `session.magnet.set_live_config`."""
        _deprecated("Session.set_live_config", "session.magnet.set_live_config")
        self.magnet.set_live_config(config)

    def set_arflow_options(self, seed: int = 0, **settings: Any) -> None:
        """Deprecated since 0.2: `session.arflow.set_options`."""
        _deprecated("Session.set_arflow_options", "session.arflow.set_options")
        self.arflow.set_options(seed, **settings)

    def set_recentring(self, enabled: bool = True, distance: float = 1.0) -> None:
        """Deprecated since 0.2: `session.armflow.set_recentring`."""
        _deprecated("Session.set_recentring", "session.armflow.set_recentring")
        self.armflow.set_recentring(enabled, distance)

    def set_noise(self, actor_noise: ArrayLike, reactor_noise: ArrayLike) -> None:
        """Deprecated since 0.2: `session.armflow.queue_noise`."""
        _deprecated("Session.set_noise", "session.armflow.queue_noise")
        self.armflow.queue_noise(actor_noise, reactor_noise)

    @property
    def capabilities(self) -> frozenset[str]:
        """What the stream takes beyond frames, seed and steps: any of "condition", "prompt",
        "cfg_scale", "queued_normals". The calls for the others raise `Unsupported`."""
        bits = ctypes.c_uint32()
        self._call(_lib.troupe_session_capabilities, ctypes.byref(bits))
        names = ("condition", "prompt", "cfg_scale", "queued_normals")
        return frozenset(n for i, n in enumerate(names) if bits.value >> i & 1)

    def close(self) -> None:
        handle, self._handle = getattr(self, "_handle", None), None  # type: ignore[assignment]
        if handle:
            _lib.troupe_session_free(handle)

    __del__ = close

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
from . import bundles  # noqa: E402,F401  (needs the names above)
from . import motion  # noqa: E402
from . import viewer  # noqa: E402
