"""Serving troupe streams across machines on Ray (docs/SERVING.md).

A gateway process takes WebSocket clients (one stream each, `protocol.py`) and routes every
stream to one worker actor (`StreamWorker`: one loaded model and a crowd of sessions advanced
together with `troupe.step_sessions`); streams are snapshotted every few tokens and, when a worker
or its node dies, restored on the survivors with no frame lost or sent twice.

    python -m troupe.serve --bundle onnx/bundles/armflow-demo --address auto --workers 8 --port 8765
    python -m troupe.serve.bench --bundle onnx/bundles/armflow-demo --local-cluster 2 --kill-at 6

Needs `ray` and `websockets` (`pip install "troupe[serve]"`); importing this package does not
import Ray, so the rest of troupe never needs it.
"""

from __future__ import annotations

from .client import ServerError, StreamClient
from .gateway import Gateway, NoWorkers, StreamMoved
from .limits import BudgetExceeded, Limits
from .snapshots import DirectorySnapshots, ObjectStoreSnapshots
from .worker import StreamWorker

__all__ = [
    "BudgetExceeded",
    "DirectorySnapshots",
    "Gateway",
    "Limits",
    "NoWorkers",
    "ObjectStoreSnapshots",
    "ServerError",
    "StreamClient",
    "StreamMoved",
    "StreamWorker",
]
