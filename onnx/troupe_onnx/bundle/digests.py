"""`onnx/cli.py bundle digests BUNDLE...`: records in each bundle's `troupe.json` the SHA-256 of
every file it names (what the exporters write; for bundles written before they did, or edited
by hand since). `--check` changes nothing and fails when a recorded digest is missing or stale."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from troupe_onnx.shared.manifest import DIGESTS, MANIFEST, named_files, sha256_of, write_manifest


def main(argv: list[str], prog: str) -> None:
    parser = argparse.ArgumentParser(prog=prog, description=__doc__)
    parser.add_argument("bundles", nargs="+", type=Path, help="bundle directories")
    parser.add_argument("--check", action="store_true", help="verify, write nothing")
    args = parser.parse_args(argv)
    stale = []
    for bundle in args.bundles:
        manifest = json.loads((bundle / MANIFEST).read_text())
        if args.check:
            recorded = manifest.get(DIGESTS, {})
            names = sorted(set(named_files(manifest, bundle)))
            wrong = [n for n in names if recorded.get(n) != sha256_of(bundle / n)]
            if wrong or sorted(recorded) != names:
                stale.append(f"{bundle}: {', '.join(wrong) or 'the list of files'}")
        else:
            written = write_manifest(bundle, manifest)
            print(f"{bundle}: {len(written[DIGESTS])} files")
    if stale:
        sys.exit("digests missing or stale (run `onnx/cli.py bundle digests BUNDLE`):\n  " + "\n  ".join(stale))
