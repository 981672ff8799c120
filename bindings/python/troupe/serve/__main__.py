"""`python -m troupe.serve`: the gateway of a Ray cluster's troupe service (docs/SERVING.md).

    ray start --head                                   # on the head node
    ray start --address HEAD:6379                      # on each worker node
    python -m troupe.serve --bundle /models/armflow-demo --address auto --workers 8 --port 8765

Every node needs troupe installed and the bundle at the same path (or `--bundle` on a shared
file system).
"""

from __future__ import annotations

import argparse
import asyncio
import logging
from typing import Any

from .limits import Limits


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m troupe.serve", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", required=True, help="the model's bundle folder, at this path on every node")
    ap.add_argument("--address", default="auto", help="the Ray cluster (ray.init's address)")
    ap.add_argument("--workers", type=int, default=2, help="worker actors (one model and one crowd each)")
    ap.add_argument("--cpus-per-worker", type=float, default=1.0)
    defaults = Limits()
    limits = ap.add_argument_group("limits", "what one stream and one client may cost (docs/SERVING.md); "
                                   "a value of 0 lifts that bound")
    limits.add_argument("--max-steps", type=int, default=defaults.max_steps, help="solver steps per token")
    limits.add_argument("--max-cfg", type=float, default=defaults.max_cfg, help="largest guidance scale")
    limits.add_argument("--max-capacity", type=int, default=defaults.max_capacity, help="tokens of context cache")
    limits.add_argument("--token-budget-ms", type=float, default=defaults.token_budget_ms,
                        help="compute one stream's token may take; a stream over it "
                             f"{defaults.budget_strikes} tokens in a row is ended")
    limits.add_argument("--max-streams-per-worker", type=int, default=defaults.max_streams_per_worker)
    limits.add_argument("--max-streams-per-client", type=int, default=defaults.max_streams_per_client,
                        help="streams one remote address may hold at once")
    limits.add_argument("--slow-reader-s", type=float, default=defaults.slow_reader_s,
                        help="seconds an acknowledgement may wait for a client that does not read")
    limits.add_argument("--idle-s", type=float, default=defaults.idle_s,
                        help="seconds a connection may send nothing")
    limits.add_argument("--no-limits", action="store_true", help="lift every bound (for measurements only)")
    ap.add_argument("--snapshot-every", type=int, default=8, help="tokens between a stream's snapshots")
    ap.add_argument("--snapshot-dir", help="keep snapshots in this folder instead of Ray's object store")
    ap.add_argument("--snapshot-key-file", help="seal the folder's snapshots under the key this file holds "
                    "(at least 16 bytes): a snapshot others wrote there is refused")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8765)
    args = ap.parse_args(argv)
    if args.no_limits:
        chosen = Limits.unlimited()
    else:
        bounds: dict[str, Any] = {name: (getattr(args, name) or None) for name in (
            "max_steps", "max_cfg", "max_capacity", "token_budget_ms", "max_streams_per_worker",
            "max_streams_per_client", "slow_reader_s", "idle_s")}
        chosen = Limits(**bounds)
    key = open(args.snapshot_key_file, "rb").read() if args.snapshot_key_file else None
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")

    import ray

    from .gateway import Gateway

    ray.init(address=args.address)
    gateway = Gateway(args.bundle, workers=args.workers, snapshot_every=args.snapshot_every,
                      snapshot_dir=args.snapshot_dir, worker_options={"num_cpus": args.cpus_per_worker},
                      limits=chosen, snapshot_key=key)

    async def run() -> None:
        await gateway.start()
        logging.getLogger("troupe.serve").info("serving %s on ws://%s:%d", args.bundle, args.host, args.port)
        await gateway.serve(args.host, args.port)

    asyncio.run(run())


if __name__ == "__main__":
    main()
