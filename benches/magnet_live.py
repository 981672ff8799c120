#!/usr/bin/env python3
"""The MAGNet live partner as a streaming session at released size (a benchmark, not a test):
per setting, the compute per chunk, the real-time factor, the latency from a user frame to the
partner frame at the same time, and how far the partner's motion moves from the released
settings' on the same input (same user, same opening, same seed).

    # a random checkpoint in the released layout, exported (benches/magnet.py says how)
    cargo build --release --lib
    TROUPE_LIBRARY_PATH=target/release/libtroupe.so python3 benches/magnet_live.py \
        --bundle onnx/bundles/magnet-dd100 --frames /tmp/dd100_frames.npy \
        --json docs/magnet-live-dd100.json

Settings: `released` is `dd100_motion_control` as released (50 DDIM steps, 8 context tokens of
the 16-token window, the x0 guidance on, each token sent once final). The others change one
thing each (the x0 guidance off, fewer steps, early emission: each chunk's tokens sent as
generated, 12 context tokens: a 4-token stride, shorter chunks and more of them) or several;
`released, another seed` is the released settings drawing again, the scale a deviation is read
against.

Latency, in frames at 30 fps, for the partner's frame t: the user's frames up to the end of the
chunk that sends it must have arrived (the algorithmic part: from `4 Tc` to `latency_frames`),
then the chunk computes (its wall time here, on `--threads` compute threads, 1 by default). Deviation: the partner's root position
(RMS and largest difference, metres) and body joint rotations (mean geodesic angle, degrees)
against the released settings' output over the frames both sent. The weights are random, so a
deviation measures how much a setting changes the output, not whether the motion is good.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bindings" / "python"))


def rotations(frames: np.ndarray) -> np.ndarray:
    """[F, 145] -> body joint rotation matrices [F, 21, 3, 3] (6-D: the first two columns)."""
    d6 = frames[:, 10:136].reshape(-1, 21, 6).astype(np.float64)
    a, b = d6[..., :3], d6[..., 3:]
    x = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b - (x * b).sum(-1, keepdims=True) * x
    y = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def deviation(got: np.ndarray, ref: np.ndarray) -> dict:
    n = min(len(got), len(ref))
    g, r = got[:n], ref[:n]
    pos = np.linalg.norm(g[:, 142:145] - r[:, 142:145], axis=-1)
    rel = np.einsum("fjik,fjil->fjkl", rotations(g), rotations(r))
    cos = np.clip((np.trace(rel, axis1=-2, axis2=-1) - 1) / 2, -1, 1)
    return {
        "frames_compared": int(n),
        "root_rms_m": float(np.sqrt((pos**2).mean())),
        "root_max_m": float(pos.max()),
        "body_mean_deg": float(np.degrees(np.arccos(cos)).mean()),
    }


def run(model, name: str, user: np.ndarray, opening_all: np.ndarray, seed: int, config: dict, early: bool) -> dict:
    tc = config["context_len"] // 4
    session = model.session(seed=seed, live_config=json.dumps(config),
                            partner_opening=opening_all[: config["context_len"]], early=early)
    out, chunk_times = [], []
    for t in range(len(user)):  # frame by frame, as an engine would
        start = time.perf_counter()
        frames = session.step(user[t : t + 1])
        elapsed = time.perf_counter() - start
        if len(frames):
            chunk_times.append(elapsed)
            out.append(frames)
    partner = np.concatenate(out)
    window = 16
    stride = window - tc
    chunk_frames = 4 * stride
    median = float(np.median(chunk_times[1:] if len(chunk_times) > 1 else chunk_times))
    algorithmic = (4 * (stride if early else window) - 1, 0 if early else 4 * tc)
    return {
        "setting": name,
        "steps": config["steps"],
        "context_tokens": tc,
        "x0_guidance": config["guidance"]["smoothing"] is not None,
        "early_emission": early,
        "chunks": len(chunk_times),
        "partner_frames": int(len(partner)),
        "chunk_ms_median": median * 1e3,
        "frames_per_chunk": chunk_frames,
        "real_time_factor": (chunk_frames / 30.0) / median,
        "algorithmic_latency_frames": {"worst": algorithmic[0], "best": algorithmic[1]},
        "latency_worst_s": algorithmic[0] / 30.0 + median,
        "_partner": partner,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", default=str(ROOT / "onnx/bundles/magnet-dd100"))
    ap.add_argument("--frames", required=True, help="float32 [F, 2, 145]: person 0 the user, person 1's start the opening")
    ap.add_argument("--seed", type=int, default=1111)
    ap.add_argument("--only", help="semicolon-separated settings to run (default: all)")
    ap.add_argument("--threads", type=int, default=1,
                    help="troupe's compute threads (set_compute_threads): the matrix products split over them")
    ap.add_argument("--json")
    args = ap.parse_args()
    import troupe

    troupe.set_compute_threads(args.threads)

    model = troupe.Model(args.bundle)
    clip = np.load(args.frames).astype(np.float32)
    user, partner = np.ascontiguousarray(clip[:, 0]), np.ascontiguousarray(clip[:, 1])
    manifest = json.loads((Path(args.bundle) / "troupe.json").read_text())
    released = manifest["sampling"]["dd100_motion_control"]
    off = dict(released, guidance=dict(released["guidance"], smoothing=None, foot_skating=None))
    settings = {
        "released": (released, False),
        "x0 guidance off": (off, False),
        "20 steps": (dict(released, steps=20), False),
        "10 steps": (dict(released, steps=10), False),
        "early emission": (released, True),
        "12 context tokens": (dict(released, context_len=48), False),
        "10 steps, guidance off, early": (dict(off, steps=10), True),
        "early emission, 12 context tokens": (dict(released, context_len=48), True),
        # Calibration: the released settings with another seed, a different sample of the same
        # distribution. A setting that moves the output about this much changes it as much as
        # drawing again does.
        "released, another seed": (released, False),
    }
    if args.only:
        settings = {k: v for k, v in settings.items() if k in args.only.split(";")}
    results = []
    reference = None
    for name, (config, early) in settings.items():
        seed = args.seed + 1 if name == "released, another seed" else args.seed
        r = run(model, name, user, partner, seed, config, early)
        if name == "released":
            reference = r["_partner"]
        if reference is not None:
            r["deviation_from_released"] = deviation(r["_partner"], reference)
        del r["_partner"]
        results.append(r)
        print(json.dumps(r), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({
            "bundle": Path(args.bundle).name, "frames": args.frames, "input_frames": int(len(user)),
            "seed": args.seed, "threads": args.threads, "results": results}, indent=2) + "\n")


if __name__ == "__main__":
    main()
