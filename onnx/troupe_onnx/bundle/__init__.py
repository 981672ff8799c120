"""Bundles of any family: commands on a written bundle (no torch needed)."""

# `onnx/cli.py bundle COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "digests": ("digests", "record (or, with --check, verify) the SHA-256 of every file a bundle's troupe.json names"),
}
