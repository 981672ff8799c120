"""Given the true past, how far is the model's next token? A per-rule diagnosis of a checkpoint.

    python3 onnx/cli.py demo diagnose --checkpoint onnx/checkpoints/armflow-demo.pt

Streams drift when the model's own output feeds it; a rule it cannot predict even from the true
history is a different failure. This runs each rule's partner of the held-out clips through the
checkpoint *teacher-forced*: windows of 32 tokens that start a stream (placed as troupe places
one, the rule started afresh there), the context built from the true pairs (and, for a model with
condition feedback, the true partner's placement), and every next partner token sampled in one
MeanFlow step at zero noise. It prints, per rule, the root error of those tokens decoded against
the decoded true tokens (cm, on the floor), beside the VAE's own round trip of the true partner,
the floor any model of these latents has. The v2 model: 16.1 cm (mirror), 19.1 (follow), 122.5
(keep-away): it did not know where its keep-away partner stood; the committed model, recipe v3,
with its placement fed back: 14.6, 17.1, 17.3 (docs/DEMO.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from troupe_onnx.armflow import feedback
from troupe_onnx.armflow.reference import Armflow
from troupe_onnx.demo import dataset, rules, sources
from troupe_onnx.demo.train import RECIPES, causal_context, demo_config

TOKENS = 32
STARTS = (0, 150, 300, 450)  # window starts (frames) in each clip long enough


def load(checkpoint: Path) -> Armflow:
    state = torch.load(checkpoint, map_location="cpu", weights_only=True)
    record = state["troupe_training"]
    cfg = demo_config(record["recipe"] if "model" in record["recipe"] else RECIPES["v1"])
    cfg.latent_scale = record["latent_scale"]
    model = Armflow(cfg)
    model.load_state_dict(state["state_dict"])
    return model.eval()


@torch.no_grad()
def window_errors(model: Armflow, positions: np.ndarray, rule: str) -> tuple[float, float]:
    """(teacher-forced root error, VAE round-trip root error) in cm of one window of actor
    positions [TOKENS * fpt + 1, 22, 3], its partner the rule started at its first frame."""
    cfg, fpt = model.cfg, model.cfg.frames_per_token
    fa = dataset.features(positions)
    fb = dataset.features(rules.partner(positions, rule, sources.FPS))
    yaw, shift = dataset.placement_at(fa[0])
    a, b = (torch.from_numpy(dataset.rigid(f, yaw, shift)[None]) for f in (fa, fb))
    za, zb = (model.vae.encoder(x)[0] * cfg.latent_scale for x in (a, b))  # posterior means
    cond = torch.from_numpy(rules.condition(rule))[None]
    if cfg.condition_feedback:
        joints = lambda x: x[..., :66].reshape(*x.shape[:2], 22, 3)  # noqa: E731
        cond = feedback.token_conditions(cond, joints(b).double(), joints(a).double(), fpt).float()
    c = causal_context(model, za, zb, torch.zeros(1, dtype=torch.long), model.armflow.arnet.modulation(cond))
    n = za.shape[1]
    zero = torch.zeros(n, cfg.latent_dim)
    guess = zero - model.armflow.velocity(za[0], zero, c[0], torch.zeros(n), torch.ones(n))
    decode = lambda z: model.vae.decoder(z[None] / cfg.latent_scale)[0, :, [0, 2]].numpy()  # noqa: E731
    true_root = decode(zb[0])
    forced = 100 * np.linalg.norm(decode(guess) - true_root, axis=-1).mean()
    vae = 100 * np.linalg.norm(true_root - b[0, : len(true_root), [0, 2]].numpy(), axis=-1).mean()
    return float(forced), float(vae)


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py demo diagnose`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", type=Path, required=True, help="armflow.pt written by `demo train`")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    model = load(args.checkpoint)
    frames = TOKENS * model.cfg.frames_per_token + 1
    clips = [c for c in sources.load() if c.split == "held_out"]
    print(f"{args.checkpoint}: teacher-forced next-token root error (cm), held-out clips, {TOKENS}-token windows")
    print("| rule | teacher-forced | VAE round trip | windows |\n|---|---|---|---|")
    for rule in rules.RULES:
        rows = [window_errors(model, c.positions[s : s + frames], rule)
                for c in clips for s in STARTS if s + frames <= len(c.positions)]
        forced, vae = np.mean(rows, axis=0)
        print(f"| {rule} | {forced:.1f} | {vae:.1f} | {len(rows)} |")
