"""Writing a bundle's `troupe.json` with the SHA-256 of every file it names, which troupe checks
at load (a damaged or edited graph is refused there, naming the file, not found when a step
fails). Needs only the standard library, so a bundle can be re-recorded without torch."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Iterator

MANIFEST = "troupe.json"
# The manifest field troupe reads the digests from: {file name: lowercase hex SHA-256}.
DIGESTS = "sha256"


def named_files(value: Any, bundle: Path) -> Iterator[str]:
    """Every string in the manifest that names a file of `bundle` (graphs, a codebook, a
    tokenizer's merges): what the loader will read."""
    if isinstance(value, dict):
        for v in value.values():
            yield from named_files(v, bundle)
    elif isinstance(value, list):
        for v in value:
            yield from named_files(v, bundle)
    elif isinstance(value, str) and value != MANIFEST and "/" not in value and (bundle / value).is_file():
        yield value


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_manifest(bundle: Path, manifest: dict) -> dict:
    """Writes `manifest` as `bundle/troupe.json` with the digests of the files it names, as
    they are now (so call it once every file is written); returns what it wrote."""
    manifest = {k: v for k, v in manifest.items() if k != DIGESTS}
    manifest[DIGESTS] = {name: sha256_of(bundle / name) for name in sorted(set(named_files(manifest, bundle)))}
    (bundle / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest
