"""The gateway: the WebSocket endpoint, the router and the keeper of snapshots.

It runs in one process (the driver of a Ray job; `python -m troupe.serve`). Each stream is held
by one worker (session affinity) chosen by load when it opens; every token goes to that worker
and comes back as an acknowledgement carrying the reactor frames. The gateway keeps, per stream,
the last snapshot (in Ray's object store or a folder) and the actor tokens stepped since, so that
when a worker dies the stream is restored on a survivor, the logged tokens are stepped again there
(their frames were already sent, so they are dropped) and the client is asked to send again every
token after the last acknowledged one: no frame is lost and none is sent twice.

Tenants share the workers, so the gateway applies the operator's `Limits`: options beyond the
bounds, a client's streams beyond its share and a full service are refused when a stream opens
(in one log line each); a connection that sends nothing, or does not read its acknowledgements,
is dropped after a bound; the workers end a stream whose tokens keep costing more than the
per-token budget.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import os
import time
import uuid
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import protocol
from .limits import BudgetExceeded, Limits, one_line
from .snapshots import DirectorySnapshots, ObjectStoreSnapshots
from .worker import StreamWorker, check_options, settle

log = logging.getLogger("troupe.serve")


class StreamMoved(Exception):
    """The stream's worker died during a step: the stream now lives on another worker and the
    client must send again from the last acknowledged token."""


class NoWorkers(RuntimeError):
    """No live worker is left to hold a stream."""


class _SlowReader(Exception):
    """A client left an acknowledgement unread past the slow-reader limit."""


@dataclass(eq=False)
class WorkerSlot:
    """One worker actor as the router sees it."""

    name: str
    handle: Any
    node: str = ""
    pid: int = 0
    streams: set[str] = field(default_factory=set)
    alive: bool = True
    # Tokens for this worker gathered during one window, sent as one call (`Gateway._submit`).
    outbox: list[tuple[str, int, np.ndarray, asyncio.Future]] = field(default_factory=list)
    flushing: bool = False


@dataclass(eq=False)
class StreamState:
    """One stream as the gateway holds it."""

    id: str
    worker: WorkerSlot
    options: dict = field(default_factory=dict)  # as opened: a restore puts it in the same crowd
    client: str = ""  # who opened it (`Gateway.client_of`), for the per-client limit
    acked: int = 0  # tokens acknowledged: the index the next token must carry
    snapshot_tokens: int = 0  # tokens the last snapshot holds
    log: list[np.ndarray] = field(default_factory=list)  # actor tokens since that snapshot
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)  # one step or move at a time
    awaiting_resend: bool = False
    attached: bool = True
    closed: bool = False


def _actor_failure_types() -> tuple[type[BaseException], ...]:
    from ray import exceptions

    return (exceptions.RayActorError, exceptions.ActorUnavailableError, asyncio.TimeoutError)


class Gateway:
    """Serves one model's streams across `workers` Ray actors.

    Use it inside a connected Ray job (`ray.init(...)` first):

        gateway = Gateway("onnx/bundles/armflow-demo", workers=4)
        await gateway.start()
        await gateway.serve("0.0.0.0", 8765)      # until cancelled

    `worker_options` go to `ray.remote(...).options` (default: one CPU each, spread over the
    nodes); `snapshot_dir` keeps snapshots in a folder instead of the object store, sealed under
    `snapshot_key` when one is given (docs/SNAPSHOTS.md); `limits` are
    what one stream and one client may cost (`Limits()`'s defaults when not given;
    `Limits.unlimited()` lifts every bound). `max_streams_per_worker`, when given, overrides the
    limits' value.
    """

    def __init__(self, bundle: str, workers: int = 2, snapshot_every: int = 8, snapshot_dir: str | None = None,
                 worker_options: dict | None = None, step_timeout_s: float = 10.0,
                 max_streams_per_worker: int | None = None, detached_ttl_s: float = 30.0, gather_s: float = 0.002,
                 limits: Limits | None = None, snapshot_key: bytes | None = None):
        # Absolute: workers run in Ray's own folders. On a real cluster the bundle must lie at
        # this path on every node (a shared file system, or the same image everywhere).
        self.bundle = os.path.abspath(bundle)
        self.initial_workers = workers
        self.snapshot_every = snapshot_every
        if snapshot_key is not None and not snapshot_dir:
            raise ValueError("a snapshot key seals the files of a snapshot folder: give snapshot_dir too")
        self.snapshots: DirectorySnapshots | ObjectStoreSnapshots = (
            DirectorySnapshots(snapshot_dir, snapshot_key) if snapshot_dir else ObjectStoreSnapshots())
        self.worker_options = {"num_cpus": 1, "scheduling_strategy": "SPREAD"} | (worker_options or {})
        self.step_timeout_s = step_timeout_s
        self.limits = limits or Limits()
        if max_streams_per_worker is not None:
            self.limits = self.limits.with_(max_streams_per_worker=max_streams_per_worker)
        self.client_streams: dict[str, int] = {}  # open streams per client
        self.refused = 0  # opens refused by a limit or for want of room
        self.detached_ttl_s = detached_ttl_s
        self.gather_s = gather_s
        self.workers: list[WorkerSlot] = []
        self.streams: dict[str, StreamState] = {}
        self.frame_dim = 0
        self.frames_per_token = 0
        self.identity = ""
        self.recoveries: list[dict] = []  # one entry per stream moved off a dead worker
        self._names = itertools.count()
        self._failures = _actor_failure_types()

    # Workers ------------------------------------------------------------------------------

    async def start(self) -> None:
        """Starts the workers and waits until each has loaded the model."""
        await asyncio.gather(*(self.add_worker() for _ in range(self.initial_workers)))

    async def add_worker(self, **options: Any) -> WorkerSlot:
        """One more worker (e.g. on a node that joined); new streams go to it first."""
        import ray

        remote: Any = ray.remote(StreamWorker).options(**(self.worker_options | options))
        # The gateway already gathers a window per call: the worker only merges calls that meet.
        handle = remote.remote(self.bundle, self.snapshot_every, self.gather_s / 4,
                               token_budget_ms=self.limits.token_budget_ms,
                               budget_strikes=self.limits.budget_strikes)
        about = await handle.describe.remote()
        if self.identity and about["identity"] != self.identity:
            ray.kill(handle, no_restart=True)
            raise RuntimeError("a worker loaded another model than the others (bundle files differ between nodes)")
        self.identity = about["identity"]
        self.frame_dim, self.frames_per_token = about["frame_dim"], about["frames_per_token"]
        slot = WorkerSlot(f"worker-{next(self._names)}", handle, about["node"], about["pid"])
        self.workers.append(slot)
        log.info("%s up on node %s (pid %d)", slot.name, slot.node[:8], slot.pid)
        return slot

    def _least_loaded(self, exclude: WorkerSlot | None = None, room: bool = True) -> WorkerSlot:
        """The live worker holding the fewest streams; with `room`, only one under the per-worker
        limit (a recovery takes a dead worker's streams whether or not there is room)."""
        alive = [w for w in self.workers if w.alive and w is not exclude]
        cap = self.limits.max_streams_per_worker
        if room and cap is not None:
            alive = [w for w in alive if len(w.streams) < cap]
        if not alive:
            raise NoWorkers("no live worker has room for a stream" if room else "no live worker is left")
        return min(alive, key=lambda w: len(w.streams))

    def _worker_died(self, slot: WorkerSlot, why: BaseException) -> None:
        """Marks a worker dead once, kills it for good (an actor that was only unreachable must
        never answer again: its streams are about to live elsewhere) and moves its idle streams."""
        if not slot.alive:
            return
        import ray

        slot.alive = False
        log.warning("%s (node %s) is gone: %s", slot.name, slot.node[:8], why)
        try:
            ray.kill(slot.handle, no_restart=True)
        except Exception:  # already dead
            pass
        for stream_id in list(slot.streams):
            asyncio.get_running_loop().create_task(self._move_when_free(self.streams[stream_id]))

    async def _move_when_free(self, st: StreamState) -> None:
        async with st.lock:
            if not st.closed and not st.worker.alive:
                try:
                    await self._move(st, time.monotonic())
                except NoWorkers as e:
                    log.error("stream %s cannot be restored: %s", st.id, e)

    async def _move(self, st: StreamState, since: float) -> None:
        """Restores `st` on a live worker from its last snapshot and steps the logged tokens
        again (caller holds `st.lock`)."""
        dead, began = st.worker, time.monotonic()
        while True:
            target = self._least_loaded(exclude=dead, room=False)
            try:
                await self._call(target.handle.restore.remote(st.id, self.snapshots.get(st.id),
                                                              st.snapshot_tokens, st.options,
                                                              self.snapshots.key))
                for i, frames in enumerate(st.log):
                    await self._submit(target, st.id, st.snapshot_tokens + i, frames)
                break
            except self._failures as e:
                self._worker_died(target, e)
        dead.streams.discard(st.id)
        target.streams.add(st.id)
        st.worker = target
        self.recoveries.append({"stream": st.id, "from": dead.name, "to": target.name,
                                "replayed_tokens": len(st.log), "restore_s": time.monotonic() - began,
                                "outage_s": time.monotonic() - since})
        log.info("stream %s moved %s -> %s (%d tokens stepped again)", st.id, dead.name, target.name, len(st.log))

    async def _call(self, ref: Any) -> Any:
        """A worker's answer, or the failure that says the worker is gone (a timeout included)."""
        return await asyncio.wait_for(asyncio.wrap_future(ref.future()), self.step_timeout_s)

    async def _submit(self, slot: WorkerSlot, stream: str, token: int, frames: np.ndarray) -> tuple:
        """One token for `slot`, sent with the others that reach it within `gather_s` as one
        call: a Ray call costs the gateway far more than a token's bytes, so a busy gateway
        makes one per worker per window, not one per token."""
        done = asyncio.get_running_loop().create_future()
        slot.outbox.append((stream, token, frames, done))
        if not slot.flushing:
            slot.flushing = True
            asyncio.get_running_loop().create_task(self._flush(slot))
        return await done

    async def _flush(self, slot: WorkerSlot) -> None:
        await asyncio.sleep(self.gather_s)
        batch, slot.outbox, slot.flushing = slot.outbox, [], False
        try:
            results = await self._call(slot.handle.step_many.remote([b[:3] for b in batch]))
        except BaseException as e:  # the worker failed (or the call did): every token hears it
            results = [e] * len(batch)
        for (*_, done), result in zip(batch, results):
            settle(done, result)  # each token's frames, or its own error

    # Streams ------------------------------------------------------------------------------

    async def open_stream(self, options: dict, client: str = "") -> StreamState:
        """A new stream on the least loaded worker, its first snapshot kept. Refused (ValueError,
        or NoWorkers when the service is full) beyond the limits, before any worker is asked."""
        check_options(options)
        self.limits.check_open(options)
        cap = self.limits.max_streams_per_client
        if cap is not None and self.client_streams.get(client, 0) >= cap:
            raise ValueError(f"this client holds {cap} streams, this service's limit per client")
        while True:
            slot = self._least_loaded()
            stream_id = uuid.uuid4().hex
            slot.streams.add(stream_id)  # counted at once, so concurrent opens spread
            try:
                snapshot = await self._call(slot.handle.open.remote(stream_id, options))
                break
            except self._failures as e:
                slot.streams.discard(stream_id)
                self._worker_died(slot, e)
            except BaseException:
                slot.streams.discard(stream_id)
                raise
        self.snapshots.put(stream_id, snapshot)
        st = StreamState(stream_id, slot, dict(options), client)
        self.streams[stream_id] = st
        self.client_streams[client] = self.client_streams.get(client, 0) + 1
        return st

    async def step(self, st: StreamState, token: int, frames: np.ndarray) -> np.ndarray | None:
        """Token `token` of the stream: its reactor frames, or None for a copy of a token already
        acknowledged. Raises StreamMoved when the worker died (the client sends again from
        `st.acked`) and ValueError for a token out of order."""
        async with st.lock:
            if st.closed:
                raise ValueError("the stream is closed")
            if token < st.acked:
                return None
            if token > st.acked:
                if st.awaiting_resend:
                    return None  # sent before the client heard `resume`; it will come again
                raise ValueError(f"token {token} out of order: {st.acked} tokens are acknowledged")
            st.awaiting_resend = False
            since = time.monotonic()
            if not st.worker.alive:
                await self._move(st, since)
            slot = st.worker
            try:
                out, snapshot, _ = await self._submit(slot, st.id, token, frames)
            except self._failures as e:
                self._worker_died(slot, e)
                await self._move(st, since)
                st.awaiting_resend = True
                raise StreamMoved(st.id) from e
            if snapshot is not None:
                self.snapshots.put(st.id, snapshot)
                st.snapshot_tokens = token + 1
                st.log.clear()
            else:
                st.log.append(frames)
            st.acked = token + 1
            return out

    async def close_stream(self, st: StreamState) -> None:
        async with st.lock:
            if st.closed:
                return
            st.closed = True
            self.streams.pop(st.id, None)
            left = self.client_streams.get(st.client, 1) - 1
            if left > 0:
                self.client_streams[st.client] = left
            else:
                self.client_streams.pop(st.client, None)
            self.snapshots.drop(st.id)
            st.worker.streams.discard(st.id)
            if st.worker.alive:
                try:
                    await self._call(st.worker.handle.close.remote(st.id))
                except self._failures as e:
                    self._worker_died(st.worker, e)

    async def _expire(self, st: StreamState) -> None:
        await asyncio.sleep(self.detached_ttl_s)
        if not st.attached:
            await self.close_stream(st)

    # The WebSocket endpoint ---------------------------------------------------------------

    async def serve(self, host: str = "127.0.0.1", port: int = 8765, ready: asyncio.Future | None = None) -> None:
        """Serves until cancelled; `ready` (if given) gets the bound port."""
        from websockets.asyncio.server import serve

        async with serve(self.connection, host, port, max_size=2**24, compression=None) as server:
            if ready is not None:
                ready.set_result(server.sockets[0].getsockname()[1])
            await asyncio.Future()

    @staticmethod
    def client_of(ws: Any) -> str:
        """Who a connection is, for the per-client limit: its remote address. Behind a proxy,
        override this to read what the proxy vouches for (a header, a token)."""
        address = getattr(ws, "remote_address", None)
        return str(address[0]) if address else ""

    async def connection(self, ws: Any) -> None:
        """One client: `open`, then tokens, then `close` (protocol.py)."""
        from websockets.exceptions import ConnectionClosed

        st = None
        client = self.client_of(ws)
        try:
            try:
                st = await self._attach(ws, protocol.decode_control(await self._receive(ws)), client)
            except ConnectionClosed:
                raise
            except Exception as e:  # refused: one line in the log, the reason to the client
                self.refused += 1
                log.info("open refused for %s: %s", client or "?", one_line(e))
                await self._refuse(ws, e)
                return
            await self._send(ws, protocol.encode_control("ready", stream=st.id, next_token=st.acked,
                                                         frame_dim=self.frame_dim,
                                                         frames_per_token=self.frames_per_token))
            while True:
                message = await self._receive(ws)
                if isinstance(message, str):
                    if protocol.decode_control(message)["type"] == "close":
                        await self.close_stream(st)
                        return
                    raise ValueError("after `open`, a text message is `close`")
                token, frames = protocol.decode_token(message, self.frame_dim)
                if frames.shape[0] != self.frames_per_token:
                    raise ValueError(f"a token is {self.frames_per_token} frames, got {frames.shape[0]}")
                try:
                    out = await self.step(st, token, frames)
                except StreamMoved:
                    await self._send(ws, protocol.encode_control("resume", next_token=st.acked))
                    continue
                except BudgetExceeded:
                    await self.close_stream(st)  # the worker has ended it
                    raise
                if out is not None:
                    await self._send(ws, protocol.encode_token(token, out))
        except ConnectionClosed:
            pass
        except _SlowReader as e:
            log.info("connection of %s dropped: %s", client or "?", e)
            ws.transport.abort()  # it does not read: no closing handshake to wait for
        except Exception as e:  # a bad message, no worker left, the budget: the client hears why
            log.info("stream %s of %s closed on error: %s", st.id if st else "-", client or "?", one_line(e))
            await self._refuse(ws, e)
        finally:
            if st is not None and not st.closed:
                st.attached = False
                asyncio.get_running_loop().create_task(self._expire(st))

    async def _receive(self, ws: Any) -> Any:
        """The client's next message; a connection silent for `Limits.idle_s` is closed."""
        try:
            return await asyncio.wait_for(ws.recv(), self.limits.idle_s)
        except asyncio.TimeoutError:
            raise ValueError(f"no message for {self.limits.idle_s:g} s, this service's idle limit") from None

    async def _send(self, ws: Any, message: Any) -> None:
        """Sends, waiting at most `Limits.slow_reader_s` for a client that does not read."""
        try:
            await asyncio.wait_for(ws.send(message), self.limits.slow_reader_s)
        except asyncio.TimeoutError:
            raise _SlowReader(f"an acknowledgement waited {self.limits.slow_reader_s:g} s for the client to "
                              "read, this service's slow-reader limit") from None

    @staticmethod
    async def _refuse(ws: Any, error: BaseException) -> None:
        """Tells the client why (one line) and closes."""
        from websockets.exceptions import ConnectionClosed

        try:
            await asyncio.wait_for(ws.send(protocol.encode_control("error", message=one_line(error))), 5)
            await asyncio.wait_for(ws.close(), 5)
        except (ConnectionClosed, asyncio.TimeoutError):
            ws.transport.abort()

    async def _attach(self, ws: Any, message: dict, client: str = "") -> StreamState:
        if message["type"] != "open":
            raise ValueError("the first message is `open`")
        if "stream" in message:
            st = self.streams.get(message["stream"])
            if st is None or st.closed:
                raise KeyError(f"no stream {message['stream']!r} (closed, expired or never opened)")
            if st.attached:
                raise ValueError(f"stream {st.id} is attached to another connection")
            st.attached = True
            return st
        return await self.open_stream(message.get("options", {}), client)

    def stats(self) -> dict:
        return {
            "workers": [{"name": w.name, "node": w.node, "pid": w.pid, "alive": w.alive, "streams": len(w.streams)}
                        for w in self.workers],
            "streams": len(self.streams),
            "refused_opens": self.refused,
            "recoveries": list(self.recoveries),
        }
