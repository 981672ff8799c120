#!/usr/bin/env python3
"""troupe's Python tooling, one command line: `python3 onnx/cli.py FAMILY COMMAND [OPTIONS]`.

    python3 onnx/cli.py armflow export --preset tiny --check onnx/bundles/armflow-tiny
    python3 onnx/cli.py umf export --preset tiny --out onnx/bundles/umf-tiny --golden
    python3 onnx/cli.py armflow export --help

The families and their commands are the subpackages of `troupe_onnx` (beside this file) and the
`COMMANDS` each lists in its `__init__.py`; a new family is a new folder there. Commands import
torch; listing them does not.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import troupe_onnx  # noqa: E402


def families() -> dict:
    """family -> (its one-line description, {command: (module, what it does)})."""
    found = {}
    for info in pkgutil.iter_modules(troupe_onnx.__path__):
        if not info.ispkg:
            continue
        package = importlib.import_module(f"troupe_onnx.{info.name}")
        if hasattr(package, "COMMANDS"):  # `shared` has none
            found[info.name] = ((package.__doc__ or "").strip().splitlines()[0], package.COMMANDS)
    return found


def usage(found: dict) -> str:
    prog = Path(sys.argv[0]).name
    lines = [f"usage: {prog} FAMILY COMMAND [OPTIONS]   ({prog} FAMILY COMMAND --help: its options)"]
    for family, (about, commands) in found.items():
        lines += ["", about]
        lines += [f"  {family + ' ' + command:28s} {what}" for command, (_, what) in commands.items()]
    return "\n".join(lines)


def main(argv: list[str]) -> None:
    found = families()
    if not argv or argv[0] in ("-h", "--help"):
        print(usage(found))
        return
    family, command = argv[0], argv[1] if len(argv) > 1 else None
    if family not in found or command not in found[family][1]:
        sys.exit(f"{usage(found)}\n\nerror: unknown command: {' '.join(argv[:2])}")
    try:
        module = importlib.import_module(f"troupe_onnx.{family}.{found[family][1][command][0]}")
    except ModuleNotFoundError as missing:
        if missing.name and missing.name.split(".")[0] == "troupe_onnx":
            raise
        sys.exit(f"{family} {command} needs the Python package `{missing.name}`: "
                 "pip install torch onnx onnxruntime numpy")
    module.main(argv[2:], prog=f"{Path(sys.argv[0]).name} {family} {command}")


if __name__ == "__main__":
    main(sys.argv[1:])
