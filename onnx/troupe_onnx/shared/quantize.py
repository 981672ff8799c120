"""A bundle with int8 or float16 weights, from a float32 one (`onnx/cli.py armflow quantize`).

    python3 onnx/cli.py armflow quantize --bundle onnx/bundles/armflow-demo \\
        --out onnx/bundles/armflow-demo-int8                  # context_layers and velocity
    python3 onnx/cli.py armflow quantize --bundle onnx/bundles/armflow-demo \\
        --check onnx/bundles/armflow-demo-int8                # byte-identical, or a non-zero exit
    python3 onnx/cli.py armflow quantize --weights float16 --bundle onnx/bundles/armflow-demo \\
        --out onnx/bundles/armflow-demo-f16                   # every streaming graph

float16: every float32 weight of a matrix product (`MatMul`, `Gemm`; two-dimensional, at least
4096 values) is stored as float16 and cast to float32 where it is used, so the file is valid ONNX
that any runtime runs; troupe keeps those weights in 16 bits and multiplies them with float32
activations. Nothing else changes: norms, biases, embeddings and activations stay float32, and a
session's output does not depend on its batch mates. The manifest says `"weights": "float16"`.

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

from troupe_onnx.shared.manifest import write_manifest
from troupe_onnx.shared.export import compare_bundles

DEFAULT_GRAPHS = {
    "int8": ("context_layers", "velocity"),
    "float16": ("context_layers", "velocity", "vae_encoder_step", "vae_decoder_step"),
}
SCHEMES = {
    "int8": "int8 weights, symmetric per output channel; int8 activations, per tensor at run time",
    "float16": "float16 weights of the matrix products (cast to float32 where used); float32 activations",
}
SUFFIX = {"int8": "int8", "float16": "f16"}
HALF_MIN_VALUES = 4096  # smaller weights are not worth a cast


def half_weights(src: Path, dst: Path) -> int:
    """Writes `src` with its matrix products' large float32 weights stored as float16 (each
    behind a `Cast` to float32). Returns how many weights it converted."""
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    model = onnx.load(str(src))
    graph = model.graph
    users: dict[str, list] = {}
    for node in graph.node:
        for name in node.input:
            users.setdefault(name, []).append(node)
    casts, converted = [], 0
    for init in list(graph.initializer):
        values = numpy_helper.to_array(init)
        used = users.get(init.name, [])
        if (values.dtype != np.float32 or values.ndim != 2 or values.size < HALF_MIN_VALUES
                or not used or any(n.op_type not in ("MatMul", "Gemm") for n in used)):
            continue
        graph.initializer.remove(init)
        graph.initializer.append(numpy_helper.from_array(values.astype(np.float16), f"{init.name}_float16"))
        casts.append(helper.make_node("Cast", [f"{init.name}_float16"], [init.name], to=TensorProto.FLOAT,
                                      name=f"{init.name}_to_float32"))
        converted += 1
    for cast in reversed(casts):
        graph.node.insert(0, cast)
    onnx.save(model, str(dst))
    return converted


def quantize_bundle(src: Path, out: Path, graphs: list[str], weights: str = "int8") -> dict:
    """Writes `out`: the bundle `src` with `graphs` in `weights` (`int8` or `float16`). Returns
    the new manifest."""
    import onnxruntime

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
            if weights == "float16":
                if half_weights(src / entry["file"], out / entry["file"]) == 0:
                    sys.exit(f"{src / entry['file']}: no matrix-product weight to store in float16")
            else:
                from onnxruntime.quantization import QuantType, quantize_dynamic

                quantize_dynamic(
                    str(src / entry["file"]), str(out / entry["file"]), weight_type=QuantType.QInt8,
                    per_channel=True, op_types_to_quantize=["MatMul", "Gemm"],
                )
            entry["weights"] = weights
    source_name = manifest["name"]
    manifest["name"] = f"{source_name}-{SUFFIX[weights]}"
    tool = {
        "int8": "onnx/cli.py armflow quantize (onnxruntime.quantization.quantize_dynamic)",
        "float16": "onnx/cli.py armflow quantize --weights float16 (onnx, numpy float16)",
    }[weights]
    manifest["producer"] = {
        **manifest.get("producer", {}),
        "quantized": {
            "tool": tool,
            "onnxruntime": onnxruntime.__version__,
            "from": source_name,
            "graphs": list(graphs),
            "scheme": SCHEMES[weights],
        },
    }
    manifest = write_manifest(out, manifest)
    return manifest


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py armflow quantize`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, required=True, help="the float32 bundle")
    ap.add_argument("--out", type=Path, help="bundle directory to write")
    ap.add_argument("--check", type=Path, help="quantize afresh and compare with this committed bundle")
    ap.add_argument("--weights", choices=sorted(DEFAULT_GRAPHS), default="int8")
    ap.add_argument("--graphs", help="comma-separated roles to quantize (default: int8 "
                    f"{','.join(DEFAULT_GRAPHS['int8'])}; float16 {','.join(DEFAULT_GRAPHS['float16'])})")
    args = ap.parse_args(argv)
    graphs = [g for g in (args.graphs or ",".join(DEFAULT_GRAPHS[args.weights])).split(",") if g]
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / "bundle"
            quantize_bundle(args.bundle, fresh, graphs, args.weights)
            problems = compare_bundles(args.check, fresh)
        for p in problems:
            print(f"MISMATCH {p}")
        print("reproducible" if not problems else f"{len(problems)} difference(s)")
        sys.exit(1 if problems else 0)
    if not args.out:
        ap.error("--out or --check is required")
    quantize_bundle(args.bundle, args.out, graphs, args.weights)
    size = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    print(f"wrote {args.out} ({size / 1e6:.1f} MB): {', '.join(graphs)} with {args.weights} weights")
