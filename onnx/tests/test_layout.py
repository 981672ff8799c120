"""The shape of the `troupe_onnx` package (reads the sources; needs no torch): a family imports
`troupe_onnx.shared` and itself, never another family, and `shared` imports no family; a trained
model of ours (`demo`: an ARMFlow trained on motion capture) may also use the family it trains
and the motion tooling; every command a package lists for `onnx/cli.py` is a module of it with
a `main`.
"""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

ONNX = Path(__file__).resolve().parents[1]
PACKAGE = ONNX / "troupe_onnx"
# Packages that build on more than `shared`: what each may import besides itself.
USES = {
    "demo": {"shared", "motion", "armflow"},
    # ARFlow's goldens pose a body on the t2m-22 skeleton, as the Rust family uses `motion`.
    "arflow": {"shared", "motion"},
}


def subpackages() -> list[str]:
    return sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists())


def package_imports(path: Path) -> set[str]:
    """The `troupe_onnx` modules a source file imports, relative imports resolved."""
    package = list(path.relative_to(ONNX).with_suffix("").parts)[:-1]
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            names.add(".".join(base + (node.module.split(".") if node.module else [])))
    return {n for n in names if n.split(".")[0] == "troupe_onnx"}


def test_families_import_only_shared_and_themselves():
    tops = subpackages()
    assert {"shared", "armflow", "umf"} <= set(tops)
    bad = []
    for top in tops:
        allowed = {"shared"} if top == "shared" else {"shared", top} | USES.get(top, set())
        for path in sorted((PACKAGE / top).rglob("*.py")):
            for name in sorted(package_imports(path)):
                parts = name.split(".")
                if len(parts) > 1 and parts[1] not in allowed:
                    bad.append(f"{path.relative_to(ONNX)}: imports {name}")
    assert not bad, "a family reaches outside itself and shared:\n" + "\n".join(bad)


def test_every_command_is_a_module_with_main():
    families = [f for f in subpackages() if hasattr(importlib.import_module(f"troupe_onnx.{f}"), "COMMANDS")]
    assert {"armflow", "umf"} <= set(families)
    for family in families:
        for command, (module, _) in importlib.import_module(f"troupe_onnx.{family}").COMMANDS.items():
            path = PACKAGE / family / f"{module}.py"
            assert path.exists(), f"{family} {command}: no {path}"
            tree = ast.parse(path.read_text())
            assert any(isinstance(n, ast.FunctionDef) and n.name == "main" for n in tree.body), f"{path}: no main"


def test_cli_lists_the_commands_without_importing_torch():
    script = (
        "import runpy, sys; sys.argv = ['cli.py']; "
        f"runpy.run_path({str(ONNX / 'cli.py')!r}, run_name='__main__'); "
        "assert 'torch' not in sys.modules, 'listing the commands imported torch'"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    for line in ("armflow export", "armflow stream-deviation", "umf export", "umf official-parity"):
        assert line in out.stdout, out.stdout
