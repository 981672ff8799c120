"""What the families' exporters share: the export of one graph, the bundle comparison behind
`--check`, and the exporter command line (`onnx/cli.py FAMILY export`)."""

from __future__ import annotations

import argparse
import filecmp
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.shared.checkpoint import CheckpointError

FORMAT_VERSION = 1
OPSET = 17


def export_graph(module, args, spec, out_dir: Path, fold_constants: bool = True):
    names_in = [x["name"] for x in spec["inputs"]]
    names_out = [x["name"] for x in spec["outputs"]]
    dynamic = {}
    for x in spec["inputs"] + spec["outputs"]:
        axes = {i: str(v).replace("+", "_plus_") for i, v in enumerate(x["shape"]) if isinstance(v, str)}
        if axes:
            dynamic[x["name"]] = axes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the legacy exporter's deprecation notice
        torch.onnx.export(
            module, args, str(out_dir / spec["file"]), input_names=names_in, output_names=names_out,
            dynamic_axes=dynamic, opset_version=OPSET, do_constant_folding=fold_constants, dynamo=False,
        )


# --------------------------------------------------------------------------------------------
# Reproducibility check
# --------------------------------------------------------------------------------------------


def compare_bundles(committed: Path, fresh: Path) -> list[str]:
    """Differences between two bundle directories. ONNX files are compared byte-wise, then (as
    a fallback across torch versions) node by node and initializer by initializer; goldens
    within 1e-6."""
    import onnx
    from onnx import numpy_helper

    problems = []
    names = sorted(p.relative_to(fresh).as_posix() for p in fresh.rglob("*") if p.is_file())
    have = sorted(p.relative_to(committed).as_posix() for p in committed.rglob("*") if p.is_file())
    if names != have:
        problems.append(f"file lists differ: committed {have} vs exported {names}")
    for name in set(names) & set(have):
        a, b = committed / name, fresh / name
        if filecmp.cmp(a, b, shallow=False):
            continue
        if name.endswith(".npy"):
            x, y = np.load(a), np.load(b)
            if x.shape != y.shape or not np.allclose(x, y, atol=1e-6, rtol=0):
                problems.append(f"{name}: arrays differ")
        elif name.endswith(".onnx"):
            ma, mb = onnx.load(a), onnx.load(b)
            ops = lambda m: [(n.op_type, list(n.input), list(n.output)) for n in m.graph.node]  # noqa: E731
            inits = lambda m: {i.name: numpy_helper.to_array(i) for i in m.graph.initializer}  # noqa: E731
            ia, ib = inits(ma), inits(mb)
            if ops(ma) != ops(mb):
                problems.append(f"{name}: graph nodes differ")
            elif ia.keys() != ib.keys() or any(not np.array_equal(ia[k], ib[k]) for k in ia):
                problems.append(f"{name}: weights differ")
        else:
            problems.append(f"{name}: contents differ")
    return problems


def check_reexport(committed: Path, rebuild) -> None:
    """`--check`: `rebuild(dir, golden)` writes the bundle afresh into a temporary directory
    (goldens too when `committed` has them); exits 0 when it is byte-identical to `committed`,
    1 naming every difference otherwise."""
    with tempfile.TemporaryDirectory() as tmp:
        fresh = Path(tmp) / "bundle"
        rebuild(fresh, (committed / "golden").exists())
        problems = compare_bundles(committed, fresh)
    for p in problems:
        print(f"MISMATCH {p}")
    print("reproducible" if not problems else f"{len(problems)} difference(s)")
    sys.exit(1 if problems else 0)


def exporter_cli(
    doc: str, presets: dict, export_bundle, write_golden, write_checkpoint=None, normaliser: bool = False,
    config_file: bool = False, argv: list[str] | None = None, prog: str | None = None, peer_graphs=None,
):
    """The command line every exporter shares: `--preset P --out DIR [--golden]` writes a
    bundle; `--preset P --check DIR` re-exports into a temporary directory and exits non-zero
    unless it is byte-identical to DIR (goldens included when DIR has them). Exporters that
    take official checkpoints add `--checkpoint FILE` and `--write-checkpoint FILE`; those whose
    feature normaliser lives outside the checkpoint add `--mean FILE --std FILE`; those whose
    checkpoints store no configuration add `--config FILE` (JSON: configuration fields that
    replace the preset's); those with `peer_graphs(model, dir)` add `--peer-graphs` (graphs for
    the benchmarks' peers only, under `peers/`). `argv` and `prog` default to the process's."""
    ap = argparse.ArgumentParser(prog=prog, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", choices=sorted(presets), required=True)
    ap.add_argument("--out", type=Path, help="bundle directory to write")
    ap.add_argument("--golden", action="store_true", help="also write golden outputs (tiny presets)")
    ap.add_argument("--seed", type=int, default=0, help="weight initialisation seed")
    ap.add_argument("--check", type=Path, help="re-export and compare with this committed bundle")
    if write_checkpoint:
        ap.add_argument("--checkpoint", type=Path, help="official checkpoint to export (else random weights)")
        ap.add_argument("--write-checkpoint", type=Path, help="save the random weights as an official checkpoint")
    if normaliser:
        ap.add_argument("--mean", type=Path, help="the dataset's feature mean (.npy) to denormalise with")
        ap.add_argument("--std", type=Path, help="the dataset's feature std (.npy)")
    if peer_graphs:
        ap.add_argument("--peer-graphs", action="store_true",
                        help="also write the graphs benches/peers.py runs in onnxruntime (peers/, not read by troupe)")
    if config_file:
        ap.add_argument("--config", type=Path, help="JSON of configuration fields replacing the preset's")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    if getattr(args, "write_checkpoint", None):
        write_checkpoint(args.preset, args.seed, args.write_checkpoint)
        print(f"wrote {args.write_checkpoint}")
        return
    checkpoint = {"checkpoint": args.checkpoint} if getattr(args, "checkpoint", None) else {}
    if normaliser and (args.mean or args.std):
        if not (args.mean and args.std):
            ap.error("--mean and --std go together")
        checkpoint["normaliser"] = (args.mean, args.std)
    if getattr(args, "config", None):
        checkpoint["config_file"] = args.config
    if args.check:

        def rebuild(fresh: Path, golden: bool):
            model = export_bundle(args.preset, fresh, args.seed)
            if golden:
                write_golden(model, fresh)

        check_reexport(args.check, rebuild)
    if not args.out:
        ap.error("--out, --check or --write-checkpoint is required")
    try:
        model = export_bundle(args.preset, args.out, args.seed, **checkpoint)
    except CheckpointError as e:
        sys.exit(f"error: {e}")
    if args.golden:
        write_golden(model, args.out)
    if getattr(args, "peer_graphs", False):
        peer_graphs(model, args.out)
    size = sum(f.stat().st_size for f in args.out.rglob("*.onnx"))
    print(f"wrote {args.out} ({size / 1e6:.1f} MB of ONNX)")
