"""A stream worker: one Ray actor holding one loaded model and a crowd of sessions.

Calls to `step` from many streams are gathered for a moment and advanced together with one
`troupe.step_sessions` call (the weights are read once per token for the whole crowd), on a
thread so that the actor keeps taking calls meanwhile. Every `snapshot_every` tokens a stream's
result carries its snapshot, which the gateway keeps where a dead worker cannot take it along.

Streams that chose their own cost (`steps`, `cfg`) are stepped apart from the crowd of streams on
the model's settings, after it, one crowd per choice: the common streams' tokens are answered
before a heavy stream's are computed, and such a stream's share of each step it took part in is
measured against the service's per-token budget (`Limits.token_budget_ms`).
"""

from __future__ import annotations

import asyncio
import ctypes
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import troupe
from troupe._native import checked_int

from .limits import BudgetExceeded

# What a client may set on its stream; everything else is refused.
SESSION_OPTIONS = ("seed", "steps", "cfg", "capacity", "condition")
SETTERS = {
    "penetration_guard": lambda session: session.set_penetration_guard,
    "root_smoothing": lambda session: session.set_root_smoothing,
    "recentring": lambda session: session.armflow.set_recentring,
}


def check_options(options: Any) -> dict:
    """The stream options a client sent, checked for shape (the session checks the values)."""
    if not isinstance(options, dict):
        raise ValueError("options are a JSON object")
    unknown = set(options) - set(SESSION_OPTIONS) - set(SETTERS)
    if unknown:
        raise ValueError(f"unknown stream options {sorted(unknown)}; known: {sorted(SESSION_OPTIONS + tuple(SETTERS))}")
    for name, ctype in (("seed", ctypes.c_uint64), ("steps", ctypes.c_uint32), ("capacity", ctypes.c_size_t)):
        if name in options:
            if not isinstance(options[name], int) or isinstance(options[name], bool):
                raise ValueError(f"{name} is an integer")
            checked_int(name, options[name], ctype)  # refused, not wrapped, where C cannot hold it
    if "cfg" in options and (not isinstance(options["cfg"], (int, float)) or isinstance(options["cfg"], bool)):
        raise ValueError("cfg is a number")
    if "condition" in options and not isinstance(options["condition"], (str, list)):
        raise ValueError("condition is a label or a list of numbers")
    for name in SETTERS:
        if name in options and not isinstance(options[name], (bool, dict)):
            raise ValueError(f"{name} is true, false or an object of its settings")
    return options


def new_session(model: troupe.Model, options: dict) -> troupe.Session:
    # The protocol's `cfg` is the session's `cfg_scale`.
    session = model.session(**{"cfg_scale" if k == "cfg" else k: options[k] for k in SESSION_OPTIONS if k in options})
    try:
        for name, setter in SETTERS.items():
            value = options.get(name)
            if value:
                setter(session)(**(value if isinstance(value, dict) else {}))
    except BaseException:
        session.close()
        raise
    return session


# The options that change what a token costs: streams that set none of them step together.
COST_OPTIONS = ("steps", "cfg")


def cost_class(options: dict) -> tuple:
    """The stream's crowd: () for the model's own settings, else the costly options it chose."""
    return tuple((k, options[k]) for k in COST_OPTIONS if k in options)


@dataclass
class _Stream:
    session: troupe.Session
    tokens: int  # tokens stepped so far: the index the next step must carry
    crowd: tuple = ()  # `cost_class` of its options
    over_budget: int = 0  # tokens in a row whose measured share was over the budget


@dataclass
class _Pending:
    stream: str
    token: int
    frames: np.ndarray
    done: asyncio.Future = field(repr=False)


def settle(done: asyncio.Future, outcome: Any) -> None:
    """Answers a waiting call with its result, or raises `outcome` in it if it is an exception
    (unless the caller is gone)."""
    if done.done():
        return
    if isinstance(outcome, BaseException):
        done.set_exception(outcome)
    else:
        done.set_result(outcome)


class StreamWorker:
    """The actor class (wrap it with `ray.remote`, as `Gateway` does). Its methods are
    coroutines: Ray runs them on one event loop, so the crowd's state needs no lock."""

    def __init__(self, bundle: str, snapshot_every: int = 8, gather_s: float = 0.002,
                 compute_threads: int | None = None, token_budget_ms: float | None = None,
                 budget_strikes: int = 3):
        if snapshot_every < 1:
            raise ValueError("snapshot_every is at least 1")
        if budget_strikes < 1:
            raise ValueError("budget_strikes is at least 1")
        self.token_budget_s = None if token_budget_ms is None else token_budget_ms / 1e3
        self.budget_strikes = budget_strikes
        if compute_threads:
            troupe.set_compute_threads(compute_threads)
        self.model = troupe.Model(bundle)
        self.snapshot_every = snapshot_every
        self.gather_s = gather_s
        self.streams: dict[str, _Stream] = {}
        self.pending: list[_Pending] = []
        self.wake = asyncio.Event()
        self.runner: asyncio.Task | None = None
        # One thread: steps are serialised (a crowd step already uses the compute threads).
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="troupe-crowd")
        self.ticks = 0
        self.stepped = 0

    async def describe(self) -> dict:
        """Where the worker runs and what it holds (the gateway's health check and placement)."""
        import ray

        return {
            "pid": os.getpid(),
            "node": ray.get_runtime_context().get_node_id(),
            "streams": len(self.streams),
            "identity": self.model.identity.hex(),
            "frame_dim": self.model.frame_dim,
            "frames_per_token": self.model.frames_per_token,
            "ticks": self.ticks,
            "tokens": self.stepped,
        }

    async def open(self, stream: str, options: dict) -> bytes:
        """Starts a stream; returns its snapshot at token 0 (the first recovery point)."""
        if stream in self.streams:
            raise ValueError(f"stream {stream} is already open here")
        session = new_session(self.model, check_options(options))
        self.streams[stream] = _Stream(session, 0, cost_class(options))
        return session.snapshot()

    async def restore(self, stream: str, snapshot: bytes, tokens: int, options: dict | None = None,
                      key: bytes | None = None) -> None:
        """Takes over a stream from its snapshot, saved after `tokens` tokens (`options`: those
        it was opened with, which place it in its crowd; `key`: the key it is sealed under)."""
        session = self.model.restore(snapshot, key=key)  # refused: the old stream stays
        old = self.streams.pop(stream, None)
        if old is not None:
            old.session.close()
        self.streams[stream] = _Stream(session, tokens, cost_class(options or {}))

    async def close(self, stream: str) -> None:
        entry = self.streams.pop(stream, None)
        if entry is not None:
            entry.session.close()

    async def step(self, stream: str, token: int, frames: np.ndarray) -> tuple[np.ndarray, bytes | None, float]:
        """Token `token` of `stream`: its reactor frames, the stream's snapshot after it when a
        snapshot is due (else None), and the stream's share of the crowd step's seconds.
        Raises BudgetExceeded (the stream is then ended) when its tokens cost over the budget."""
        entry = self.streams.get(stream)
        if entry is None:
            raise KeyError(f"stream {stream} is not open on this worker")
        if token != entry.tokens + sum(p.stream == stream for p in self.pending):
            raise ValueError(f"stream {stream}: token {token} out of order (next is {entry.tokens})")
        frames = np.asarray(frames, np.float32)
        if frames.ndim != 2 or frames.shape[1] != self.model.frame_dim or not np.isfinite(frames).all():
            raise ValueError(f"a token's frames are finite float32 [n, {self.model.frame_dim}]")
        done = asyncio.get_running_loop().create_future()
        self.pending.append(_Pending(stream, token, frames, done))
        self.wake.set()
        if self.runner is None or self.runner.done():
            self.runner = asyncio.create_task(self._run())
        return await done

    async def step_many(self, tokens: list[tuple[str, int, np.ndarray]]) -> list:
        """`step` for each (stream, token, frames), in one call; each entry of the result is what
        `step` returns or the exception it raised for that token alone."""
        return await asyncio.gather(*(self.step(*t) for t in tokens), return_exceptions=True)

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await self.wake.wait()
            self.wake.clear()
            await asyncio.sleep(self.gather_s)  # let the other streams of this tick arrive
            while self.pending:
                batch: list[_Pending] = []
                rest: list[_Pending] = []
                seen: set[str] = set()
                for p in self.pending:  # one token per stream per crowd step, in order
                    (rest if p.stream in seen else batch).append(p)
                    seen.add(p.stream)
                self.pending = rest
                batch = [p for p in batch if p.stream in self.streams and not p.done.cancelled()]
                # The crowd on the model's settings first, then each costlier choice: the common
                # streams are answered before a heavy stream's token is computed.
                crowds: dict[tuple, list[_Pending]] = {}
                for p in batch:
                    crowds.setdefault(self.streams[p.stream].crowd, []).append(p)
                for key in sorted(crowds, key=lambda k: (k != (), repr(k))):
                    await self._step_crowd(loop, crowds[key])

    async def _step_crowd(self, loop: asyncio.AbstractEventLoop, crowd: list[_Pending]) -> None:
        crowd = [p for p in crowd if p.stream in self.streams]  # one may have been ended meanwhile
        if not crowd:
            return
        try:
            results = await loop.run_in_executor(self.pool, self._step, crowd)
        except Exception:
            # The crowd step changed no session; one stream's fault must not fail the others, so
            # each steps alone and hears only its own error.
            for p in crowd:
                try:
                    settle(p.done, self._charge(p, (await loop.run_in_executor(self.pool, self._step, [p]))[0]))
                except Exception as e:
                    settle(p.done, e)
            return
        for p, result in zip(crowd, results):
            settle(p.done, self._charge(p, result))

    def _charge(self, p: _Pending, result: tuple) -> Any:
        """The token's result, or BudgetExceeded (and the stream ended) when a stream that chose
        its own cost has had a share of its steps over the budget `budget_strikes` tokens in a
        row. Streams on the model's own settings cost what the operator chose by serving the
        model: a slow machine is not their fault."""
        entry = self.streams.get(p.stream)
        if entry is None or self.token_budget_s is None or entry.crowd == ():
            return result
        share = result[2]
        entry.over_budget = entry.over_budget + 1 if share > self.token_budget_s else 0
        if entry.over_budget < self.budget_strikes:
            return result
        self.streams.pop(p.stream).session.close()
        return BudgetExceeded(
            f"stream {p.stream} ended: {entry.over_budget} tokens in a row took {share * 1e3:.1f} ms or more of "
            f"compute, over this service's budget of {self.token_budget_s * 1e3:g} ms a token")

    def _step(self, batch: list[_Pending]) -> list[tuple[np.ndarray, bytes | None, float]]:
        entries = [self.streams[p.stream] for p in batch]
        start = time.perf_counter()
        outs = troupe.step_sessions([e.session for e in entries], [p.frames for p in batch])
        # Each stream's share of the step: what the budget is measured against.
        share = (time.perf_counter() - start) / len(batch)
        self.ticks += 1
        self.stepped += len(batch)
        results = []
        for entry, out in zip(entries, outs):
            entry.tokens += 1
            due = entry.tokens % self.snapshot_every == 0
            results.append((out, entry.session.snapshot() if due else None, share))
        return results
