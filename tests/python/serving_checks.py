"""The serving gateway's protocol checks (run by tests/serving.rs): a one-node Ray cluster on
127.0.0.1, a gateway keeping its snapshots in a folder, and clients that misbehave.

    python3 tests/python/serving_checks.py BUNDLE SNAPSHOT_DIR

Every bad message gets an `error` naming the fault and leaves the gateway serving; a client whose
connection drops re-attaches to its stream and goes on bit for bit; snapshots are files while a
stream lives and gone once it closes. Prints one line per check and `serving checks: N passed`.
"""

from __future__ import annotations

import asyncio
import json
import struct
import sys
from pathlib import Path
from typing import Any

import numpy as np
from websockets.asyncio.client import connect

import troupe
from troupe.serve import Gateway, ServerError, StreamClient
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


async def main(bundle: str, snapshot_dir: Path) -> None:
    model = troupe.Model(bundle)
    dim, fpt = model.frame_dim, model.frames_per_token
    rng = np.random.default_rng(7)
    tokens = [rng.standard_normal((fpt, dim)).astype(np.float32) for _ in range(10)]
    with new_session(model, {"seed": 5}) as plain:
        want = [plain.step(t) for t in tokens]

    gateway = Gateway(bundle, workers=1, snapshot_every=4, snapshot_dir=str(snapshot_dir),
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
