"""A bundle with int8 weights, from a float32 one (`onnx/cli.py armflow quantize`).

    python3 onnx/cli.py armflow quantize --bundle onnx/bundles/armflow-demo \\
        --out onnx/bundles/armflow-demo-int8                  # context_layers and velocity
    python3 onnx/cli.py armflow quantize --bundle onnx/bundles/armflow-demo \\
        --check onnx/bundles/armflow-demo-int8                # byte-identical, or a non-zero exit

Each named graph goes through onnxruntime's dynamic quantization: the weights of its matrix
products become int8, symmetric, one scale per output channel (`MatMulInteger` with the weights
as constants); the activations are quantized at run time, one scale per tensor
(`DynamicQuantizeLinear`). Every other graph is copied as it is. The manifest says so, never
silently: each quantized graph's entry gets `"weights": "int8"` (troupe checks it against the
file at load), the bundle's name gains `-int8`, and `producer.quantized` records the tool, its
version and the scheme. Goldens are not copied: they hold float32 outputs.

One property changes with int8 activations: a batch of streams (`step_sessions`) quantizes each
graph's input with one scale for the whole batch, so a session's output in a batch differs from
its output alone by up to the quantization error (float32 bundles: by float rounding only).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

from troupe_onnx.shared.export import compare_bundles

DEFAULT_GRAPHS = ("context_layers", "velocity")
SCHEME = "int8 weights, symmetric per output channel; int8 activations, per tensor at run time"


def quantize_bundle(src: Path, out: Path, graphs: list[str]) -> dict:
    """Writes `out`: the bundle `src` with `graphs` quantized. Returns the new manifest."""
    import onnxruntime
    from onnxruntime.quantization import QuantType, quantize_dynamic

    manifest = json.loads((src / "troupe.json").read_text())
    unknown = [g for g in graphs if g not in manifest["graphs"]]
    if unknown:
        sys.exit(f"{src} has no graph {', '.join(unknown)} (it has {', '.join(manifest['graphs'])})")

    def entries(role: str) -> list[dict]:
        """The manifest entries of a role: one graph, or a list of them (`context_layers`),
        each quantized alike."""
        entry = manifest["graphs"][role]
        return entry if isinstance(entry, list) else [entry]

    already = [g for g in graphs if any(e.get("weights", "float32") != "float32" for e in entries(g))]
    if already:
        sys.exit(f"{src}: {', '.join(already)} already hold reduced-precision weights")
    out.mkdir(parents=True, exist_ok=True)
    for f in src.iterdir():
        if f.is_file() and f.name != "troupe.json":
            shutil.copyfile(f, out / f.name)
    for role in graphs:
        for entry in entries(role):
            quantize_dynamic(
                str(src / entry["file"]), str(out / entry["file"]), weight_type=QuantType.QInt8,
                per_channel=True, op_types_to_quantize=["MatMul", "Gemm"],
            )
            entry["weights"] = "int8"
    source_name = manifest["name"]
    manifest["name"] = f"{source_name}-int8"
    manifest["producer"] = {
        **manifest.get("producer", {}),
        "quantized": {
            "tool": "onnx/cli.py armflow quantize (onnxruntime.quantization.quantize_dynamic)",
            "onnxruntime": onnxruntime.__version__,
            "from": source_name,
            "graphs": list(graphs),
            "scheme": SCHEME,
        },
    }
    (out / "troupe.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py armflow quantize`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, required=True, help="the float32 bundle")
    ap.add_argument("--out", type=Path, help="bundle directory to write")
    ap.add_argument("--check", type=Path, help="quantize afresh and compare with this committed bundle")
    ap.add_argument("--graphs", default=",".join(DEFAULT_GRAPHS),
                    help=f"comma-separated roles to quantize (default: {','.join(DEFAULT_GRAPHS)})")
    args = ap.parse_args(argv)
    graphs = [g for g in args.graphs.split(",") if g]
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / "bundle"
            quantize_bundle(args.bundle, fresh, graphs)
            problems = compare_bundles(args.check, fresh)
        for p in problems:
            print(f"MISMATCH {p}")
        print("reproducible" if not problems else f"{len(problems)} difference(s)")
        sys.exit(1 if problems else 0)
    if not args.out:
        ap.error("--out or --check is required")
    quantize_bundle(args.bundle, args.out, graphs)
    size = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    print(f"wrote {args.out} ({size / 1e6:.1f} MB): {', '.join(graphs)} with int8 weights")
