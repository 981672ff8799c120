#!/usr/bin/env python3
"""Benchmark a text prompt to a condition: troupe against onnxruntime and torch, side by side,
on the same bundle, the same prompts and one thread each.

    cargo build --release --lib
    python3 onnx/cli.py armflow export --preset interhuman --out onnx/bundles/paper-interhuman
    TROUPE_LIBRARY_PATH=target/release/libtroupe.so PYTHONPATH=bindings/python:onnx \\
        python3 benches/prompts.py --bundle onnx/bundles/paper-interhuman --json /tmp/prompts.json

A bundle exported with the official layout carries CLIP ViT-L/14@336px's text tower
(`text_encoder`: 12 layers, width 768, 77 tokens) and ARMFlow's text branch (`text_branch`). One
encode is: tokenize, the tower on the 77 ids, the branch at the end-of-text token.

- `troupe`: `Model.encode_prompt` through the Python binding (the release library; tract, one
  thread). Every timed prompt is new, so the model's prompt cache never answers; a second figure
  times a prompt asked again (the cache).
- `ort`: onnxruntime on the bundle's two graphs (`intra_op_num_threads = 1`), the ids from
  OpenAI's own tokenizer over the bundle's merges.
- `torch`: the reference modules (`troupe_onnx.armflow.reference`) rebuilt by the exporter's
  `build_model` from the bundle's `producer.preset` and `producer.seed`, so with the same
  weights; eager, `torch.inference_mode()`, one thread; the same ids.

Before timing, the three conditions of the first prompt must agree within 1e-4 (max-abs), so
the benchmark cannot time a wrong pipeline. Reported: median and p90 per encode in ms over
`--prompts` prompts, and troupe's time relative to each peer.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np


def prompts(n: int) -> list[str]:
    verbs = ["waves at", "pushes", "hugs", "follows", "dances with", "bows to", "shakes hands with", "avoids"]
    return [f"a person {verbs[i % len(verbs)]} the other {i + 2} times, then steps back" for i in range(n)]


def timed(fn, items) -> list[float]:
    out = []
    for item in items:
        t0 = time.perf_counter()
        fn(item)
        out.append((time.perf_counter() - t0) * 1e3)
    return out


def summary(ms: list[float]) -> dict:
    s = sorted(ms)
    return {"median_ms": statistics.median(s), "p90_ms": s[round(0.9 * (len(s) - 1))], "n": len(s)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, required=True)
    ap.add_argument("--prompts", type=int, default=30, help="timed prompts per peer")
    ap.add_argument("--json", type=Path, help="also write the results here")
    args = ap.parse_args()

    import onnxruntime as ort
    import torch
    import troupe

    from troupe_onnx.armflow import export
    from troupe_onnx.shared.clip import reference_tokenizer, tokenize

    torch.set_num_threads(1)
    manifest = json.loads((args.bundle / "troupe.json").read_text())
    producer = manifest["producer"]
    tokenizer = reference_tokenizer(args.bundle / manifest["tokenizer"]["merges_file"])

    t0 = time.perf_counter()
    model = troupe.Model(args.bundle)
    load_s = time.perf_counter() - t0

    opts = ort.SessionOptions()
    opts.intra_op_num_threads, opts.inter_op_num_threads = 1, 1
    graphs = manifest["graphs"]
    tower = ort.InferenceSession(str(args.bundle / graphs["text_encoder"]["file"]), opts, providers=["CPUExecutionProvider"])
    branch = ort.InferenceSession(str(args.bundle / graphs["text_branch"]["file"]), opts, providers=["CPUExecutionProvider"])

    def ort_encode(prompt: str) -> np.ndarray:
        ids = tokenize(tokenizer, prompt)[None]
        (features,) = tower.run(None, {"token_ids": ids})
        (condition,) = branch.run(None, {"clip_tokens": features, "eot_index": ids.argmax(axis=-1)})
        return condition[0]

    reference = export.build_model(producer["preset"], producer.get("seed", 0)).text_encoder

    def torch_encode(prompt: str) -> np.ndarray:
        ids = torch.from_numpy(tokenize(tokenizer, prompt))[None]
        with torch.inference_mode():
            return reference(reference.clip_features(ids), ids.argmax(dim=-1))[0].numpy()

    check = "two people shake hands"
    results = {"troupe": model.encode_prompt(check), "ort": ort_encode(check), "torch": torch_encode(check)}
    agreement = {k: float(np.abs(v - results["torch"]).max()) for k, v in results.items()}
    assert max(agreement.values()) <= 1e-4, f"the peers disagree: {agreement}"

    texts = prompts(args.prompts + 3)
    warm, timed_texts = texts[:3], texts[3:]
    report = {"bundle": str(args.bundle), "troupe_load_s": load_s, "agreement_max_abs_vs_torch": agreement}
    for name, fn in (("troupe", model.encode_prompt), ("ort", ort_encode), ("torch", torch_encode)):
        for w in warm:
            fn(w)
        report[name] = summary(timed(fn, timed_texts))
    report["troupe_cached"] = summary(timed(model.encode_prompt, timed_texts))
    for peer in ("ort", "torch"):
        report[f"troupe_vs_{peer}"] = report["troupe"]["median_ms"] / report[peer]["median_ms"]
    print(json.dumps(report, indent=2))
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
