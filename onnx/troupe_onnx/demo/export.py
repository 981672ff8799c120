"""Export the trained demo checkpoint as a troupe bundle, with goldens from the same reference.

    python3 onnx/cli.py demo export --checkpoint onnx/checkpoints/armflow-demo.pt \\
        --out onnx/bundles/armflow-demo --golden
    python3 onnx/cli.py demo export --checkpoint onnx/checkpoints/armflow-demo.pt \\
        --check onnx/bundles/armflow-demo        # byte-identical re-export, or a non-zero exit

The bundle is ARMFlow's (`onnx/cli.py armflow export` writes it, on the demo configuration of
`train.py` with the checkpoint's latent scale); this command adds what only a trained model has:
the manifest's `producer.training` (recipe, data, final losses, training time, from the
checkpoint) and `condition.labels`, the partner rules by name. Goldens are the armflow
exporter's (stream loop with injected noise, both through the reference and through troupe).
A checkpoint of a recipe with feedback (v3) gives a bundle whose `condition` is the rule's
one-hot (`dim` 3) plus `feedback` (`partner_placement`, 5 floats the runtime appends before every
token; `armflow/feedback.py`), and goldens of the feedback loop.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.armflow import export as armflow_export
from troupe_onnx.demo import rules
from troupe_onnx.demo.train import RECIPES, demo_config
from troupe_onnx.motion.skeleton import REPO
from troupe_onnx.shared.export import check_reexport

NAME = "demo"

ABOUT = {
    "mirror": "faces the actor 1.2 m away and mirrors them (left <-> right), 0.25 s behind",
    "follow": "walks 1.5 m behind the actor, copying their gait and heading, 0.5 s behind",
    "keep-away": "keeps 2 m from the actor's root, facing them, stepping away as they approach",
}


def manifest_extra(record: dict) -> dict:
    labels = [{"name": r, "vector": rules.condition(r).tolist(), "about": ABOUT[r]} for r in rules.RULES]
    return {
        "name": "armflow-demo",
        "producer": {"tool": "onnx/cli.py demo export", "training": record},
        "condition": {"labels": labels, "null_source": "label:mirror"},  # train.py: no condition = mirror
    }


def export(checkpoint: Path, out: Path, golden: bool):
    record = torch.load(checkpoint, map_location="cpu", weights_only=True)["troupe_training"]
    # The checkpoint's own recipe sizes the model; the first checkpoints (v1) did not record it.
    cfg = demo_config(record["recipe"] if "model" in record["recipe"] else RECIPES["v1"])
    cfg.latent_scale = record["latent_scale"]
    extra = manifest_extra(record)
    model = armflow_export.export_bundle(NAME, out, checkpoint=checkpoint, config=cfg, manifest_extra=extra)
    if golden:  # the CMU clip's features (held out of training) as the golden actor
        actor = np.load(REPO / "tests" / "data" / "mocap" / "cmu-playground.features.npy")
        armflow_export.write_golden(model, out, actor)
    return model


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py demo export`."""
    os.environ.setdefault("PYTHONHASHSEED", "0")
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", type=Path, required=True, help="armflow.pt written by `demo train`")
    ap.add_argument("--out", type=Path, help="bundle directory to write")
    ap.add_argument("--golden", action="store_true", help="also write golden outputs")
    ap.add_argument("--check", type=Path, help="re-export and compare with this committed bundle")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    if args.check:
        check_reexport(args.check, lambda fresh, golden: export(args.checkpoint, fresh, golden))
    if not args.out:
        ap.error("--out or --check is required")
    export(args.checkpoint, args.out, args.golden)
    size = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    print(f"wrote {args.out} ({size / 1e6:.1f} MB)")
