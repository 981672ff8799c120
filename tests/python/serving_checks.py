"""The serving gateway's protocol checks (run by tests/serving.rs): a one-node Ray cluster on
127.0.0.1, a gateway keeping its snapshots in a folder, and clients that misbehave.

    python3 tests/python/serving_checks.py BUNDLE SNAPSHOT_DIR

Every bad message gets an `error` naming the fault and leaves the gateway serving; a client whose
connection drops re-attaches to its stream and goes on bit for bit; snapshots are files while a
stream lives and gone once it closes. The operator's limits: options beyond them, a client's
streams beyond its share and a full service are refused at open, each in one log line; a silent
connection and one that does not read are dropped; a worker ends a stream over its compute
budget and answers the common crowd before a heavy stream. Prints one line per check and
`serving checks: N passed`.
"""

from __future__ import annotations

import asyncio
import json
import logging
import socket
import struct
import sys
from pathlib import Path
from typing import Any

import numpy as np
from websockets.asyncio.client import connect

import troupe
from troupe.serve import BudgetExceeded, Gateway, Limits, ServerError, StreamClient, StreamWorker
from troupe.serve.bench import start_local_cluster
from troupe.serve.worker import new_session

passed = 0


def check(condition: bool, what: str) -> None:
    global passed
    if not condition:
        raise AssertionError(what)
    passed += 1
    print(f"ok: {what}")


async def refused(url: str, messages: list[Any], expect: str) -> None:
    """Sends `messages` on a new connection (after an `open` when the first is not text) and
    expects an `error` containing `expect`."""
    async with connect(url) as ws:
        for m in messages:
            await ws.send(m)
        reply = None
        while True:
            text = await asyncio.wait_for(ws.recv(), 30)
            if isinstance(text, str) and json.loads(text)["type"] == "error":
                reply = json.loads(text)["message"]
                break
    check(reply is not None and expect in reply, f"refused ({expect!r}): {reply}")


class Lines(logging.Handler):
    """Keeps the gateway's log records."""

    def __init__(self) -> None:
        super().__init__()
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(self.format(record))


async def worker_checks(bundle: str, tokens: list[np.ndarray]) -> None:
    """A worker in this process (no Ray): the budget, and the order in which crowds are stepped."""
    worker = StreamWorker(bundle, token_budget_ms=1e-6, budget_strikes=2)
    await worker.open("a", {"seed": 1, "steps": 2})
    await worker.open("common", {"seed": 1})
    await asyncio.gather(worker.step("a", 0, tokens[0]), worker.step("common", 0, tokens[0]))
    try:
        await asyncio.gather(worker.step("a", 1, tokens[1]), worker.step("common", 1, tokens[1]))
        check(False, "a stream over its budget two tokens in a row is ended")
    except BudgetExceeded as e:
        check("over this service's budget" in str(e) and "a" not in worker.streams,
              f"a stream that chose its steps, over its budget two tokens in a row, is ended: {e}")
    await worker.step("common", 2, tokens[2])
    check(worker.streams["common"].tokens == 3, "a stream on the model's settings is not charged")
    worker.runner.cancel()

    worker = StreamWorker(bundle)
    await worker.open("light", {"seed": 1})
    await worker.open("heavy", {"seed": 2, "steps": 8})
    order: list[str] = []

    async def step(name: str) -> None:
        await worker.step(name, 0, tokens[0])
        order.append(name)

    await asyncio.gather(step("heavy"), step("light"))
    check(order == ["light", "heavy"], f"the crowd on the model's settings is answered first: {order}")
    key = b"sixteen byte key"
    sealed = worker.streams["light"].session.snapshot(key=key)
    await worker.restore("moved", sealed, 1, {}, key)
    await worker.step("moved", 1, tokens[1])
    try:
        await worker.restore("light", sealed, 1, {}, b"another sixteen b")
        check(False, "a worker refuses a snapshot sealed under another key")
    except troupe.InvalidArgument:
        check("light" in worker.streams, "a worker refuses a snapshot sealed under another key, the stream kept")
    worker.runner.cancel()


async def slow_reader(url: str, frames: np.ndarray) -> bool:
    """Opens a stream, sends tokens and never reads; True when the gateway drops it."""
    from troupe.serve import protocol

    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    host, port = url.removeprefix("ws://").split(":")
    sock.connect((host, int(port)))
    from websockets.asyncio.client import connect

    async with connect(url, sock=sock, max_queue=1, compression=None) as ws:
        await ws.send(protocol.encode_control("open", options={"seed": 3}))
        await ws.recv()  # `ready`
        from websockets.exceptions import ConnectionClosed

        try:
            for index in range(5000):
                await asyncio.wait_for(ws.send(struct.pack("<Q", index) + frames.tobytes()), 30)
                await asyncio.sleep(0)
        except ConnectionClosed:  # the gateway dropped the connection
            return True
    return False


async def main(bundle: str, snapshot_dir: Path) -> None:
    model = troupe.Model(bundle)
    dim, fpt = model.frame_dim, model.frames_per_token
    rng = np.random.default_rng(7)
    tokens = [rng.standard_normal((fpt, dim)).astype(np.float32) for _ in range(10)]
    with new_session(model, {"seed": 5}) as plain:
        want = [plain.step(t) for t in tokens]
    await worker_checks(bundle, tokens)
    lines = Lines()
    logging.getLogger("troupe.serve").addHandler(lines)
    logging.getLogger("troupe.serve").setLevel(logging.INFO)

    key = b"the gateway's snapshot key, 32 b"
    gateway = Gateway(bundle, workers=1, snapshot_every=4, snapshot_dir=str(snapshot_dir), snapshot_key=key,
                      worker_options={"num_cpus": 1}, detached_ttl_s=60)
    await gateway.start()
    ready = asyncio.get_running_loop().create_future()
    serving = asyncio.create_task(gateway.serve("127.0.0.1", 0, ready))
    url = f"ws://127.0.0.1:{await ready}"
    try:
        opening = json.dumps({"type": "open", "options": {"seed": 1}})
        token = struct.pack("<Q", 0) + tokens[0].tobytes()
        await refused(url, [token], "a text message")
        await refused(url, ["not json"], "JSON object")
        await refused(url, [json.dumps({"type": "step"})], "first message is `open`")
        await refused(url, [json.dumps({"type": "open", "options": {"temperature": 2}})], "unknown stream options")
        await refused(url, [json.dumps({"type": "open", "options": {"penetration_guard": 3}})], "penetration_guard")
        await refused(url, [json.dumps({"type": "open", "options": {"seed": "x"}})], "seed is an integer")
        # Values a C integer cannot hold are refused, not wrapped (2**32 + 1 steps used to run 1);
        # a JSON boolean is not a number.
        await refused(url, [json.dumps({"type": "open", "options": {"steps": 2**32 + 1}})], "does not fit uint32_t")
        await refused(url, [json.dumps({"type": "open", "options": {"seed": -1}})], "does not fit uint64_t")
        await refused(url, [json.dumps({"type": "open", "options": {"cfg": True}})], "cfg is a number")
        await refused(url, [json.dumps({"type": "open", "options": {"condition": "dance"}})], "dance")
        await refused(url, [json.dumps({"type": "open", "stream": "0" * 32})], "no stream")
        await refused(url, [opening, b"\x01\x02"], "at least 8 bytes")
        await refused(url, [opening, token[:-3]], "not whole frames")
        await refused(url, [opening, struct.pack("<Q", 0) + tokens[0][:3].tobytes()], f"a token is {fpt} frames")
        await refused(url, [opening, struct.pack("<Q", 1) + tokens[0].tobytes()], "out of order")
        nan = tokens[0].copy()
        nan[1, 2] = np.nan
        await refused(url, [opening, struct.pack("<Q", 0) + nan.tobytes()], "finite")
        await refused(url, [opening, json.dumps({"type": "open"})], "`close`")

        # A dropped connection: the stream waits, the client re-attaches and goes on.
        client = StreamClient(url, {"seed": 5})
        await client.__aenter__()
        got = []
        for t in tokens[:6]:
            await client.send(t)
            got.append((await client.receive())[1])
        stream = client.stream
        check(stream is not None and (snapshot_dir / f"{stream}.snapshot").is_file(), "the stream's snapshot is a file")
        sealed = (snapshot_dir / f"{stream}.snapshot").read_bytes()
        check(sealed[:8] == b"TRPSEAL\0" and model.restore(sealed, key=key).close() is None,
              "the file is sealed under the gateway's key")
        try:
            model.restore(sealed, key=b"a key the gateway does not hold")
            check(False, "a snapshot file sealed under another key is refused")
        except troupe.InvalidArgument as e:
            check("does not match this key" in str(e), f"a snapshot file sealed under another key is refused: {e}")
        await client.ws.close()  # no `close`: the connection just drops
        await asyncio.sleep(0.3)  # the gateway notices the drop and detaches the stream
        await refused(url, [json.dumps({"type": "open", "stream": stream}), json.dumps({"type": "open"})], "`close`")
        await asyncio.sleep(0.3)
        again = StreamClient(url, stream=stream)
        again.next_token = 6
        async with again:
            for t in tokens[6:]:
                await again.send(t)
                got.append((await again.receive())[1])
            check(gateway.streams[stream].acked == 10, "the re-attached stream took tokens 6-9")
            try:
                async with StreamClient(url, stream=stream):
                    pass
                check(False, "a second connection to an attached stream is refused")
            except ServerError as e:
                check("attached to another connection" in str(e), f"a second connection is refused: {e}")
        check(all(np.array_equal(a, b) for a, b in zip(got, want)) and len(got) == len(want),
              "across the dropped connection the stream equals a plain session bit for bit")
        await asyncio.sleep(0.5)
        check(not (snapshot_dir / f"{stream}.snapshot").exists(), "a closed stream's snapshot is deleted")
        check(gateway.stats()["workers"][0]["alive"], "after every refusal the worker is alive and serving")

        # The operator's limits (Limits' defaults: steps 8, cfg 10, capacity 4096).
        await refused(url, [json.dumps({"type": "open", "options": {"steps": 10000, "cfg": 2}})],
                      "steps 10000 is above this service's limit of 8")
        await refused(url, [json.dumps({"type": "open", "options": {"cfg": 11.5}})], "above this service's limit of 10")
        await refused(url, [json.dumps({"type": "open", "options": {"capacity": 5000}})], "limit of 4096")
        # Streams the refused connections above left detached still count until they expire.
        held = gateway.client_streams.get("127.0.0.1", 0)
        gateway.limits = gateway.limits.with_(max_streams_per_client=held + 2)
        async with StreamClient(url, {"seed": 1}), StreamClient(url, {"seed": 2}):
            await refused(url, [opening], f"this client holds {held + 2} streams, this service's limit per client")
        await asyncio.sleep(0.3)
        async with StreamClient(url, {"seed": 3}, local_address="127.0.0.2"):
            check(True, "another address opens its own streams")
        async with StreamClient(url, {"seed": 4}):
            check(True, "a client's closed streams no longer count against it")
        gateway.limits = gateway.limits.with_(max_streams_per_worker=len(gateway.workers[0].streams))
        await refused(url, [opening], "no live worker has room")
        gateway.limits = gateway.limits.with_(max_streams_per_worker=None, idle_s=0.5)
        await refused(url, [opening], "no message for 0.5 s, this service's idle limit")
        gateway.limits = gateway.limits.with_(idle_s=None, slow_reader_s=0.5)
        check(await slow_reader(url, tokens[0]), "a client that does not read is dropped")
        check(any("slow-reader limit" in line for line in lines.records), "the dropped reader is logged")
        refusals = [line for line in lines.records if "open refused" in line]
        check(len(refusals) == gateway.refused and all("\n" not in line for line in refusals),
              f"every refused open ({gateway.refused}) is one log line")
    finally:
        serving.cancel()
    print(f"serving checks: {passed} passed")


if __name__ == "__main__":
    bundle, folder = sys.argv[1], Path(sys.argv[2])
    cluster, _ = start_local_cluster(1)
    try:
        asyncio.run(main(bundle, folder))
    finally:
        import ray

        ray.shutdown()
        cluster.shutdown()
