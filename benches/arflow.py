#!/usr/bin/env python3
"""ARFlow at paper size (random weights: no trained ARFlow exists): troupe next to onnxruntime
and PyTorch eager running the same sampler on the same network (a benchmark, not a test).

    python3 onnx/cli.py arflow export --preset paper        --out /tmp/arflow-paper
    python3 onnx/cli.py arflow export --preset paper-online --out /tmp/arflow-paper-online
    cargo build --release --lib
    TROUPE_LIBRARY_PATH=target/release/libtroupe.so python3 benches/arflow.py \\
        --offline /tmp/arflow-paper --online /tmp/arflow-paper-online --json docs/arflow-paper.json

Per runtime, the median over `--runs` generations of a `--frames`-frame clip (a synthetic walk)
with the paper's 5 steps, guidance off (λ = 0) and on (λ = 2): troupe's `arflow_generate`;
onnxruntime running the exported graph inside the reference sampler (`sampler.py`, numpy and
torch autograd for the guidance gradient); torch eager running the network inside the same
sampler. And the online stream: troupe's session fed one frame at a time (each frame runs the 5
steps with the per-step caches), milliseconds per frame at the clip's last frames. All on one
thread.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "onnx"))
sys.path.insert(0, str(ROOT / "bindings" / "python"))


def median_ms(fn, runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--offline", required=True)
    ap.add_argument("--online", required=True)
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--json")
    args = ap.parse_args()

    import onnxruntime as ort
    import torch

    import troupe
    from troupe_onnx.arflow.export import build_model, normaliser, synthetic_clip
    from troupe_onnx.arflow.sampler import Sampling, sample

    torch.set_num_threads(1)
    options = ort.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    actor = synthetic_clip(args.frames, seed=5)
    mean, std = normaliser()
    rows = []
    for variant, path, preset in (("offline", args.offline, "paper"), ("online", args.online, "paper-online")):
        manifest = json.loads((Path(path) / "troupe.json").read_text())
        seed = manifest["producer"]["seed"]
        net = build_model(preset, seed)
        sess = ort.InferenceSession(str(Path(path) / "denoiser.onnx"), options, providers=["CPUExecutionProvider"])

        def torch_denoise(x, t):
            with torch.no_grad():
                return net(torch.from_numpy(x)[None], torch.tensor([t]))[0].numpy()

        def ort_denoise(x, t):
            return sess.run(None, {"x": x[None], "t": np.array([t], np.float32)})[0][0]

        with troupe.Model(path) as model:
            for guidance in (0.0, 2.0):
                weight = Sampling().weight if guidance else 1.0  # guidance off: plain Euler
                s = Sampling(guidance=guidance, weight=weight, seed=3)
                ours = median_ms(lambda: model.arflow.generate(actor, seed=3, guidance=guidance, weight=weight), args.runs)
                onnx = median_ms(lambda: sample(ort_denoise, actor, mean, std, s), args.runs)
                eager = median_ms(lambda: sample(torch_denoise, actor, mean, std, s), args.runs)
                row = {"variant": variant, "guidance": guidance, "frames": args.frames,
                       "troupe_ms": ours, "onnxruntime_ms": onnx, "torch_ms": eager,
                       "troupe_over_onnxruntime": ours / onnx, "troupe_over_torch": ours / eager}
                rows.append(row)
                print(json.dumps(row), flush=True)
            if variant == "online":
                for guidance in (0.0, 2.0):
                    session = model.session()
                    session.arflow.set_options(seed=3, guidance=guidance, weight=0.7 if guidance else 1.0)
                    times = []
                    for t in range(args.frames):
                        start = time.perf_counter()
                        session.step(actor[t : t + 1])
                        times.append(time.perf_counter() - start)
                    tail = times[-20:]
                    row = {"variant": "online stream", "guidance": guidance, "frames": args.frames,
                           "troupe_ms_per_frame_last_20": 1e3 * float(np.median(tail)),
                           "troupe_ms_per_frame_first_20": 1e3 * float(np.median(times[:20])),
                           "real_time_factor_at_30fps": (1 / 30) / float(np.median(tail))}
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"threads": 1, "results": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
