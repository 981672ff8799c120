"""Where the gateway keeps each stream's last snapshot: Ray's object store (the default) or a
folder the operator names (a shared file system, so that a new gateway could read it too)."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any


class ObjectStoreSnapshots:
    """Snapshots as objects the gateway owns (`ray.put` from the gateway's process): they live in
    the gateway node's object store, so a worker node's death cannot take them along. A newer
    snapshot of a stream releases the older one."""

    key = None  # the store is the gateway's own: nobody else writes it

    def __init__(self) -> None:
        self.refs: dict[str, Any] = {}

    def put(self, stream: str, snapshot: bytes) -> None:
        import ray

        self.refs[stream] = ray.put(snapshot)

    def get(self, stream: str) -> Any:
        """What a worker's `restore` takes: the object reference (Ray hands the worker the bytes,
        fetched from the gateway's node directly)."""
        return self.refs[stream]

    def drop(self, stream: str) -> None:
        self.refs.pop(stream, None)


class DirectorySnapshots:
    """Snapshots as files `<stream>.snapshot` in a folder, each replaced atomically (written
    beside, then renamed over) so a crash never leaves half a snapshot. With `key` (at least 16
    bytes) every file is sealed under it (`troupe.seal_snapshot`) and the workers restore only
    what the key sealed: whoever else can write the folder cannot put another stream there."""

    NAME = re.compile(r"^[A-Za-z0-9_-]{1,128}$")

    def __init__(self, folder: str | os.PathLike, key: bytes | None = None):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.key = key

    def _path(self, stream: str) -> Path:
        if not self.NAME.match(stream):
            raise ValueError(f"stream id {stream!r} is not a plain name")
        return self.folder / f"{stream}.snapshot"

    def put(self, stream: str, snapshot: bytes) -> None:
        if self.key is not None:
            import troupe

            snapshot = troupe.seal_snapshot(snapshot, self.key)
        path = self._path(stream)
        partial = path.with_suffix(".partial")
        with open(partial, "wb") as f:
            f.write(snapshot)
            f.flush()
            os.fsync(f.fileno())
        os.replace(partial, path)

    def get(self, stream: str) -> bytes:
        return self._path(stream).read_bytes()

    def drop(self, stream: str) -> None:
        self._path(stream).unlink(missing_ok=True)
