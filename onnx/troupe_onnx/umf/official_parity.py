"""UMF at the released sizes, loaded from a checkpoint in the official layout: troupe (through the
Python bindings and the C ABI) against the PyTorch reference, same text-branch condition and
injected noise. Not part of CI (the bundle is 450 MB); the committed `umf-tiny` covers parity there.

    python3 onnx/cli.py umf export --preset interhuman --write-checkpoint /tmp/umfck/umf.ckpt
    python3 onnx/cli.py umf export --preset interhuman --checkpoint /tmp/umfck/umf.ckpt \\
        --mean /tmp/umfck/global_mean.npy --std /tmp/umfck/global_std.npy --out /tmp/umf-interhuman
    cargo build --release
    TROUPE_LIBRARY_PATH=target/release python3 onnx/cli.py umf official-parity \\
        --checkpoint /tmp/umfck/umf.ckpt --bundle /tmp/umf-interhuman --people 3
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.shared.clip import CONTEXT
from troupe_onnx.umf import export as export_umf
from troupe_onnx.umf.reference import block_noise_from_normals, generate_group, stage_tokens

REPO = Path(__file__).resolve().parents[3]


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py umf official-parity`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", type=Path, required=True)
    ap.add_argument("--bundle", type=Path, required=True)
    ap.add_argument("--people", type=int, default=3)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(REPO / "bindings" / "python"))
    import troupe  # the Python bindings; they load the built library

    torch.set_num_threads(1)
    stats = (args.checkpoint.parent / "global_mean.npy", args.checkpoint.parent / "global_std.npy")
    model = export_umf.build_model("interhuman", 0, args.checkpoint, stats)
    cfg = model.cfg
    rng = np.random.default_rng(11)
    normals = lambda *shape: rng.standard_normal(shape).astype(np.float32)  # noqa: E731
    clip_tokens, eot = normals(CONTEXT, cfg.text_dim), 12
    with torch.no_grad():
        condition = model.text_condition(torch.from_numpy(clip_tokens)[None], torch.tensor([eot]))[0].numpy()
    coarse, fine, d = stage_tokens(cfg)[0], cfg.tokens, cfg.latent_dim
    prior = normals(coarse, d)
    jump = block_noise_from_normals(normals(fine * d), cfg.layout, fine, d, cfg.gamma)
    reactions = [normals(fine, d) for _ in range(args.people - 1)]
    start = time.perf_counter()
    latents, motion = generate_group(
        model, condition, args.people, cfg.prior_solvers, cfg.reaction_solver, cfg.cfg_scale, prior, [jump], reactions
    )
    print(f"torch reference: {time.perf_counter() - start:.1f} s")
    bundle = troupe.Model(args.bundle)
    got_condition = bundle.encode_text(clip_tokens, eot)
    print(f"text branch: condition max-abs {np.abs(got_condition - condition).max():.2e}")
    start = time.perf_counter()
    got_motion, got_latents = bundle.generate_group(
        args.people, condition=got_condition, noise=(prior, jump, np.stack(reactions)), return_latents=True
    )
    print(f"troupe: {time.perf_counter() - start:.1f} s")
    for p in range(args.people):
        print(
            f"person {p + 1}: latents max-abs {np.abs(got_latents[p] - latents[p]).max():.2e}, "
            f"features max-abs {np.abs(got_motion[p] - motion[p]).max():.2e} (mean |feature| {np.abs(motion[p]).mean():.2f})"
        )
