"""Load and chaos tests of the service: simulated real-time clients against a gateway.

    # a cluster of two one-CPU worker nodes on 127.0.0.1, started and stopped by the command
    python -m troupe.serve.bench --bundle onnx/bundles/armflow-demo --local-cluster 2 --clients 16 --seconds 15
    # the same, and a worker node dies 6 s in (the chaos test)
    python -m troupe.serve.bench --bundle onnx/bundles/armflow-demo --local-cluster 2 --clients 16 --seconds 15 \\
        --kill-at 6
    # against a running service (`python -m troupe.serve`), from any machine
    python -m troupe.serve.bench --bundle onnx/bundles/armflow-demo --url ws://gateway:8765 --clients 500
    # the hostile-tenant case: beside the clients, one heavy and one flooding tenant
    python -m troupe.serve.bench --bundle onnx/bundles/armflow-demo --local-cluster 2 --clients 12 --hostile \
        [--no-limits]

Each client is a player at 30 frames per second: it sends one token of actor frames every
frames-per-token / 30 s, on its own clock (clients start spread over one period), and needs the
token's reactor frames before its next token is due (its deadline). Every client's actor is the
bundle's golden actor clip (or seeded noise) from its own start, under its own seed and
condition. At the end every stream is stepped again in this process by a plain session, token by
token, and compared with what the service sent: the frames must be all there, once each, and
equal bit for bit.

Prints a JSON report (and writes it with --json): token latency p50/p99/max, missed deadlines,
frames lost and duplicated, whether the streams equal the uninterrupted ones, and for --kill-at
the streams moved and the recovery time (from the kill to each moved stream's next
acknowledgement).

With --hostile two tenants misbehave beside the clients: a heavy one opens its stream with
`--heavy-steps` solver steps and guidance (and, when that is refused, with the most the limits
allow) and streams at 30 Hz like the others; a flooding one opens `--flood` streams as fast as it
can and never sends a token. Every tenant connects from its own loopback address (127.0.1.x for
the clients), as tenants of a service do. The report's latency figures are the well-behaved
clients' only; `hostile` says what the two got. --no-limits serves with `Limits.unlimited()`, to
measure what the limits buy.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .gateway import Gateway
from .limits import Limits

FPS = 30.0


@dataclass
class ClientRecord:
    options: dict
    tokens: list[np.ndarray]
    sent_at: dict[int, float] = field(default_factory=dict)
    acked_at: dict[int, float] = field(default_factory=dict)
    frames: dict[int, np.ndarray] = field(default_factory=dict)
    duplicates: int = 0
    resumes: int = 0
    error: str = ""
    address: str | None = None  # the loopback address it connects from (None: the default)


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def client_plan(bundle: str, clients: int, tokens: int, loopback_addresses: bool = False) -> list[ClientRecord]:
    """Each client's options and actor tokens (deterministic); with `loopback_addresses` each
    client connects from its own 127.0.1.x."""
    import troupe

    with troupe.Model(bundle) as model:
        fpt, dim, labels = model.frames_per_token, model.frame_dim, model.condition_labels
    golden = Path(bundle) / "golden" / "actor.npy"
    clip = np.load(golden).astype(np.float32) if golden.is_file() else None
    plans = []
    for i in range(clients):
        if clip is not None and clip.ndim == 2 and clip.shape[1] == dim:
            start = (i * 37) % clip.shape[0]
            frames = np.resize(np.roll(clip, -start, axis=0), (tokens * fpt, dim))
        else:
            frames = np.random.default_rng(i).standard_normal((tokens * fpt, dim)).astype(np.float32)
        options: dict = {"seed": i}
        if labels:  # a trained model: the rules in turn, with the demo's clean-ups
            options |= {"condition": labels[i % len(labels)], "penetration_guard": True, "root_smoothing": True,
                        "recentring": True}
        plans.append(ClientRecord(options, [frames[t * fpt:(t + 1) * fpt] for t in range(tokens)],
                                  address=f"127.0.1.{1 + i % 250}" if loopback_addresses else None))
    return plans


async def run_client(url: str, rec: ClientRecord, start_at: float, period: float, timeout_s: float) -> None:
    from .client import StreamClient

    loop = asyncio.get_running_loop()
    try:
        async with StreamClient(url, rec.options, local_address=rec.address) as client:
            async def sender() -> None:
                for i, frames in enumerate(rec.tokens):
                    await asyncio.sleep(max(0.0, start_at + i * period - loop.time()))
                    rec.sent_at[i] = loop.time()
                    await client.send(frames)

            sending = asyncio.create_task(sender())
            while len(rec.acked_at) < len(rec.tokens):
                index, frames = await asyncio.wait_for(client.receive(), timeout_s)
                if index in rec.acked_at:
                    rec.duplicates += 1
                    continue
                rec.acked_at[index] = loop.time()
                rec.frames[index] = frames
            await sending
            rec.resumes = client.resumes
    except Exception as e:  # reported, and counted as lost frames
        rec.error = f"{type(e).__name__}: {e}"


async def heavy_tenant(url: str, rec: ClientRecord, heavy_steps: int, allowed_steps: int | None,
                       start_at: float, period: float, timeout_s: float, until: asyncio.Event) -> dict:
    """Asks for `heavy_steps` steps with guidance; refused, takes the most the limits allow.
    Streams at 30 Hz until its tokens run out, the service ends its stream or `until` is set."""
    from .client import ServerError

    first: dict = {"asked_steps": heavy_steps, "refused": ""}
    options = {"seed": 999, "steps": heavy_steps, "cfg": 2.0}
    if allowed_steps is not None and heavy_steps > allowed_steps:
        # A refusal is immediate: ask once to record it, then stream at the allowed maximum.
        from .client import StreamClient

        try:
            async with StreamClient(url, options, local_address=rec.address):
                pass
        except ServerError as e:
            first["refused"] = str(e)
        options = options | {"steps": allowed_steps}
    rec.options = options
    running = asyncio.create_task(run_client(url, rec, start_at, period, timeout_s))
    stop = asyncio.create_task(until.wait())
    await asyncio.wait({running, stop}, return_when=asyncio.FIRST_COMPLETED)
    for task in (running, stop):
        task.cancel()
    await asyncio.gather(running, stop, return_exceptions=True)
    return first | {"steps": options["steps"], "tokens_acknowledged": len(rec.acked_at), "ended": rec.error}


async def flooding_tenant(url: str, streams: int, until: asyncio.Event) -> dict:
    """Opens `streams` streams as fast as it can from one address and holds them, sending no
    token, until `until` is set."""
    from websockets.asyncio.client import connect

    from . import protocol

    held, refused, reasons = [], 0, set()
    for i in range(streams):
        try:
            ws = await connect(url, local_addr=("127.0.2.1", 0), compression=None)
            await ws.send(protocol.encode_control("open", options={"seed": 10_000 + i}))
            reply = protocol.decode_control(await asyncio.wait_for(ws.recv(), 30))
        except Exception as e:  # the service may refuse the connection itself
            refused += 1
            reasons.add(type(e).__name__)
            continue
        if reply["type"] == "ready":
            held.append(ws)
        else:
            refused += 1
            reasons.add(reply.get("message", ""))
            await ws.close()
    await until.wait()
    for ws in held:
        await ws.close()
    return {"asked": streams, "opened": len(held), "refused": refused, "reasons": sorted(reasons)[:3]}


def reference(bundle: str, plans: list[ClientRecord]) -> list[np.ndarray]:
    """Every stream run uninterrupted by a plain session in this process, token by token."""
    import troupe

    from .worker import new_session

    outs = []
    with troupe.Model(bundle) as model:
        for rec in plans:
            with new_session(model, rec.options) as session:
                outs.append(np.concatenate([session.step(t) for t in rec.tokens]))
    return outs


def report(plans: list[ClientRecord], expected: list[np.ndarray], period: float, kill_at: float | None) -> dict:
    latencies, missed = [], 0
    lost_tokens = lost_frames = duplicates = 0
    identical, max_diff = True, 0.0
    recovery = []
    for rec, want in zip(plans, expected):
        for i, at in rec.acked_at.items():
            latency = at - rec.sent_at[i]
            latencies.append(latency)
            missed += latency > period
        lost_tokens += len(rec.tokens) - len(rec.acked_at)
        duplicates += rec.duplicates
        got = np.concatenate([rec.frames[i] for i in sorted(rec.frames)]) if rec.frames else np.zeros((0, want.shape[1]))
        lost_frames += max(0, want.shape[0] - got.shape[0])
        if got.shape != want.shape:
            identical = False
        else:
            identical &= bool(np.array_equal(got, want))
            max_diff = max(max_diff, float(np.abs(got - want).max(initial=0.0)))
        if kill_at is not None and rec.resumes:
            recovery.append(min(at for at in rec.acked_at.values() if at >= kill_at) - kill_at)
    ms = np.array(latencies) * 1e3 if latencies else np.zeros(1)
    return {
        "tokens": int(sum(len(r.tokens) for r in plans)),
        "latency_ms": {"p50": float(np.percentile(ms, 50)), "p99": float(np.percentile(ms, 99)),
                       "max": float(ms.max())},
        "deadline_ms": period * 1e3,
        "missed_deadlines": int(missed),
        "tokens_lost": int(lost_tokens),
        "frames_lost": int(lost_frames),
        "duplicates": int(duplicates),
        "equal_to_uninterrupted": identical,
        "max_abs_diff": max_diff,
        "client_errors": [r.error for r in plans if r.error],
        "streams_resumed": sum(1 for r in plans if r.resumes),
        "recovery_s": {"median": float(np.median(recovery)), "max": float(max(recovery))} if recovery else None,
    }


def start_local_cluster(nodes: int) -> tuple[Any, list[Any]]:
    """A head node (no CPUs: it runs this process, the gateway) and `nodes` one-CPU worker nodes,
    all on 127.0.0.1."""
    # Ray binds to the machine's address unless told that this is a one-machine cluster.
    os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    # The workers import troupe as this process does (a checkout's package, or the wheel's).
    package_root = str(Path(__file__).resolve().parents[2])
    paths = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    os.environ["PYTHONPATH"] = os.pathsep.join([package_root, *paths])
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    workers = [cluster.add_node(num_cpus=1) for _ in range(nodes)]
    ray.init(address=cluster.address, log_to_driver=False)
    return cluster, workers


async def kill_worker_node(gateway: Gateway, cluster: Any, nodes: list[Any]) -> tuple[str, float]:
    """Kills the node of the worker holding the most streams, as a machine dies: its worker
    process and its Ray processes at once, nothing told beforehand."""
    slot = max((w for w in gateway.workers if w.alive), key=lambda w: len(w.streams))
    node = next(n for n in nodes if n.node_id == slot.node)
    at = asyncio.get_running_loop().time()
    os.kill(slot.pid, signal.SIGKILL)
    await asyncio.get_running_loop().run_in_executor(None, lambda: cluster.remove_node(node, allow_graceful=False))
    return slot.name, at


async def main_async(args: argparse.Namespace) -> dict:
    period = args.frames_per_token / FPS
    tokens = int(round(args.seconds / period))
    plans = client_plan(args.bundle, args.clients, tokens, loopback_addresses=args.hostile)
    limits = Limits.unlimited() if args.no_limits else Limits()
    cluster: Any = None
    serving: asyncio.Task | None = None
    gateway: Gateway | None = None
    nodes: list[Any] = []
    result: dict = {"cpu": cpu_name(), "clients": args.clients, "seconds": args.seconds, "bundle": args.bundle}
    try:
        url = args.url
        if url is None:
            cluster, nodes = start_local_cluster(args.local_cluster)
            gateway = Gateway(args.bundle, workers=args.local_cluster, snapshot_every=args.snapshot_every,
                              worker_options={"num_cpus": 1}, limits=limits)
            started = time.monotonic()
            await gateway.start()
            result |= {"workers": args.local_cluster, "snapshot_every": args.snapshot_every,
                       "workers_start_s": time.monotonic() - started}
            ready = asyncio.get_running_loop().create_future()
            serving = asyncio.create_task(gateway.serve("127.0.0.1", 0, ready))
            url = f"ws://127.0.0.1:{await ready}"
        loop = asyncio.get_running_loop()
        t0 = loop.time() + 0.5
        clients = [asyncio.create_task(run_client(url, rec, t0 + period * i / len(plans), period, args.timeout))
                   for i, rec in enumerate(plans)]
        hostile: list[asyncio.Task] = []
        finished = asyncio.Event()
        if args.hostile:
            heavy = client_plan(args.bundle, 1, tokens)[0]
            heavy.address = "127.0.3.1"
            hostile = [asyncio.create_task(heavy_tenant(url, heavy, args.heavy_steps, limits.max_steps, t0,
                                                        period, args.timeout, finished)),
                       asyncio.create_task(flooding_tenant(url, args.flood, finished))]
        kill = None
        if args.kill_at is not None and gateway is not None:
            await asyncio.sleep(max(0.0, t0 + args.kill_at - loop.time()))
            kill = await kill_worker_node(gateway, cluster, nodes)
        await asyncio.gather(*clients)
        finished.set()
        if hostile:
            heavy_result, flood_result = await asyncio.gather(*hostile)
            result["hostile"] = {"limits": "none" if args.no_limits else "default", "heavy": heavy_result,
                                 "flood": flood_result}
        result |= report(plans, reference(args.bundle, plans), period, kill[1] if kill else None)
        if kill and gateway is not None:
            result["killed"] = kill[0]
            result["streams_moved"] = len(gateway.recoveries)
            # restoring and stepping the logged tokens again, on the survivor
            result["restore_s"] = {"max": max((r["restore_s"] for r in gateway.recoveries), default=0.0)}
        if gateway is not None:
            result["gateway"] = gateway.stats()
    finally:
        if serving is not None:
            serving.cancel()
        if cluster is not None:
            import ray

            ray.shutdown()
            cluster.shutdown()
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m troupe.serve.bench", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", required=True, help="the model's bundle (the service's, for --url)")
    ap.add_argument("--url", help="a running gateway; without it --local-cluster starts one")
    ap.add_argument("--local-cluster", type=int, default=2, metavar="NODES", help="worker nodes of the local cluster")
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=15.0, help="each client's stream length")
    ap.add_argument("--frames-per-token", type=int, default=4)
    ap.add_argument("--snapshot-every", type=int, default=8, help="tokens between a stream's snapshots")
    ap.add_argument("--kill-at", type=float, help="kill the busiest worker's node this many seconds in")
    ap.add_argument("--timeout", type=float, default=60.0, help="longest wait for one acknowledgement")
    ap.add_argument("--hostile", action="store_true", help="add a heavy and a flooding tenant")
    ap.add_argument("--heavy-steps", type=int, default=10_000, help="steps the heavy tenant asks for")
    ap.add_argument("--flood", type=int, default=500, help="streams the flooding tenant opens")
    ap.add_argument("--no-limits", action="store_true", help="serve with no limits (Limits.unlimited())")
    ap.add_argument("--json", type=Path, help="also write the report here")
    args = ap.parse_args(argv)
    if args.kill_at is not None and args.url is not None:
        ap.error("--kill-at needs the local cluster (it kills one of its nodes)")
    result = asyncio.run(main_async(args))
    text = json.dumps(result, indent=2)
    print(text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    ok = result["frames_lost"] == 0 and result["duplicates"] == 0 and result["equal_to_uninterrupted"]
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
