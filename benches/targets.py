#!/usr/bin/env python3
"""Every speed target of performance round four (issue 55), measured in one run and set against
its bound.

    cargo build --release --lib --example stream --example crowd
    python3 onnx/cli.py armflow export --preset paper --out onnx/bundles/paper --peer-graphs
    python3 onnx/cli.py armflow export --preset interhuman --out onnx/bundles/paper-interhuman
    python3 benches/targets.py --json /tmp/targets.json \
        --magnet-bundle onnx/bundles/magnet-dd100 \
        --magnet-checkpoint /tmp/magnet-release/checkpoints/dfot/magnet_dd100/v0/checkpoints_500000 \
        --magnet-frames /tmp/dd100_frames.npy

(`docs/MAGNET.md`, "Speed at released size", makes the MAGNet bundle, checkpoint and clip.)

This script measures nothing itself: it runs the benchmarks that each own a target, one after
the other on this machine, reads what they report, and prints one table of target, measured
value and whether it is met. Each part can be left out (`--skip magnet,prompt`); a part left out
is a row that says so, never a pass. Every timing is taken with nothing else running: the
script runs its parts one at a time. The parts and their commands:

- `step`: `benches/peers.py` at H = 10, 100, 1000, 2000, onnxruntime and troupe's
  `examples/stream` alternating (batch 1, every token cached; load to the first step).
- `avx2`: the same with troupe on the AVX2 kernels (`--isa avx2`: how troupe does on a machine
  without AVX-512; onnxruntime keeps its own choice, which it has no setting for).
- `f16`: `examples/stream` at H = 100 on the paper bundle with float16 weights (made once by
  `armflow quantize --weights float16` under `target/bench/`), alternating with the float32
  bundle 5 times; the ratio of their medians times the `step` part's alternated troupe /
  onnxruntime ratio at H = 100 sets it against onnxruntime f32; and against the time its
  weights' bytes take to read at the `step` part's measured single-thread bandwidth.
- `demo`: `examples/stream --synthetic --frames 40000 --tick 4` on the demo bundle: 10,000
  token calls with the clean-ups on (p50, p99, max).
- `crowd`: `examples/crowd` on two threads at `--crowd-sizes` (history 100, batched), then
  `benches/sgemm_peak.py` on two threads; a session-token does at least two FLOP per float32
  weight of the step (`peers.py`'s `weights_bytes`), which sets the round's arithmetic against
  that peak. Mixed histories: 16 streams at 10 to 2000 against 16 at the mean.
- `magnet`: `benches/magnet.py` (troupe against torch eager, per iteration) and
  `benches/magnet_live.py` on two compute threads (the released live partner and the
  low-latency setting).
- `prompt`: `benches/prompts.py` on the official-size text path.
- `exactness`: the tests that hold batched = alone and the golden parity of the streaming path
  (`cargo test --release --test batch --test context_cache --test golden`).

Needs what those need: numpy, onnx, onnxruntime; torch for the MAGNet and prompt peers.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benches"))
PARTS = ("step", "avx2", "f16", "demo", "crowd", "magnet", "prompt", "exactness")
HISTORIES = (10, 100, 1000, 2000)
BUDGET_MS = 4 / 30 * 1e3  # a round is real time when its p99 fits in one token's 4 frames
STEP_TARGET = 0.85  # troupe / onnxruntime, batch 1, every history
STEP_GRAPHS = ("vae_encoder_step", "context_layers", "velocity", "vae_decoder_step")


def sh(cmd: list[str], env: dict | None = None) -> str:
    """Runs `cmd` from the repository root, echoing it; its stdout, or exit with its stderr."""
    print("$", " ".join(cmd), flush=True)
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env={**os.environ, **(env or {})})
    if done.returncode != 0:
        sys.exit(f"failed ({done.returncode}): {' '.join(cmd)}\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}")
    return done.stdout


def step_bytes(bundle: Path) -> int:
    """Bytes of the weights a streaming step reads: the initializers of its graphs."""
    from peers import initializer_bytes

    graphs = json.loads((bundle / "troupe.json").read_text())["graphs"]
    files = [g["file"] for role in STEP_GRAPHS for g in (graphs[role] if isinstance(graphs[role], list) else [graphs[role]])]
    return sum(initializer_bytes(bundle / f) for f in files)


def crowd_rows(out: str) -> dict[int, dict]:
    """`examples/crowd`'s table rows: sessions -> round p50 (median of the blocks, and their
    spread) / p99 ms."""
    rows = {}
    row = r"^\| (\d+) \| batched \| ([\d.]+) \[([\d.]+)-([\d.]+)\] \| ([\d.]+) \|"
    for m in re.finditer(row, out, re.M):
        rows[int(m[1])] = {"p50": float(m[2]), "p50_min": float(m[3]), "p50_max": float(m[4]), "p99": float(m[5])}
    if not rows:
        sys.exit(f"cannot parse the crowd's output:\n{out}")
    return rows


class Table:
    """The target rows, in the issue's order."""

    def __init__(self):
        self.rows: list[dict] = []

    def add(self, target: str, measured: str, met: bool | None):
        self.rows.append({"target": target, "measured": measured, "met": met})

    def skipped(self, target: str, part: str):
        self.add(target, f"not measured: part `{part}` left out", None)

    def markdown(self) -> str:
        word = {True: "yes", False: "no", None: "skipped"}
        lines = ["| target | measured | met? |", "|---|---|---|"]
        lines += [f"| {r['target']} | {r['measured']} | {word[r['met']]} |" for r in self.rows]
        met = sum(r["met"] is True for r in self.rows)
        skipped = sum(r["met"] is None for r in self.rows)
        lines.append(f"\n{met} of {len(self.rows)} targets met, {skipped} not measured")
        return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, default=ROOT / "onnx/bundles/paper")
    ap.add_argument("--prompt-bundle", type=Path, default=ROOT / "onnx/bundles/paper-interhuman")
    ap.add_argument("--magnet-bundle", type=Path, default=ROOT / "onnx/bundles/magnet-dd100")
    ap.add_argument("--magnet-checkpoint", type=Path)
    ap.add_argument("--magnet-frames", type=Path, help="float32 [F, 2, 145], for the live partner")
    ap.add_argument("--crowd-sizes", default="96,112,128,150")
    ap.add_argument("--steps", type=int, default=30, help="timed batch-1 steps per history")
    ap.add_argument("--skip", default="", help=f"comma-separated parts to leave out, of {', '.join(PARTS)}")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--resume", action="store_true",
                    help="keep the results of the parts an interrupted run finished (in target/bench/targets)")
    args = ap.parse_args(argv)
    skip = {s for s in args.skip.split(",") if s}
    if skip - set(PARTS):
        sys.exit(f"--skip: unknown parts {sorted(skip - set(PARTS))}")
    if "magnet" not in skip and not (args.magnet_checkpoint and args.magnet_frames):
        sys.exit("the magnet part needs --magnet-checkpoint and --magnet-frames (or --skip magnet)")
    release = ROOT / "target/release"
    stream, crowd = str(release / "examples/stream"), str(release / "examples/crowd")
    library = release / "libtroupe.so"
    for built in (stream, crowd, library):
        if not Path(built).exists():
            sys.exit(f"{built} is missing: cargo build --release --lib --example stream --example crowd")
    lib_env = {"TROUPE_LIBRARY_PATH": str(library)}
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), "unknown CPU")
    report: dict = {"cpu": cpu, "parts_skipped": sorted(skip)}
    table = Table()
    tmp = ROOT / "target/bench/targets"
    if not args.resume:
        shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True, exist_ok=True)

    def once(name: str, measure):
        """`measure()`'s result, or the one an interrupted run saved with `--resume`."""
        saved = tmp / f"{name}.result.json"
        if saved.exists():
            print(f"(kept from the interrupted run: {name})", flush=True)
            return json.loads(saved.read_text())
        result = measure()
        saved.write_text(json.dumps(result))
        return result

    # --- ARMFlow batch 1 --------------------------------------------------------------------
    peers = None
    if "step" not in skip:
        def measure_steps():
            sh([sys.executable, "benches/peers.py", "--bundle", str(args.bundle), "--histories",
                ",".join(map(str, HISTORIES)), "--steps", str(args.steps), "--peers", "ort",
                "--troupe-binary", stream, "--json", str(tmp / "peers.json")])
            return json.loads((tmp / "peers.json").read_text())

        peers = report["step"] = once("step", measure_steps)
        ratios = {h: peers["troupe"][str(h)]["p50"] / peers["results"][str(h)]["ort"]["p50"] for h in HISTORIES}
        table.add(f"ARMFlow batch 1, f32, all cached: ≤ {STEP_TARGET}× onnxruntime at H = 10, 100, 1000, 2000 "
                  "(this machine's kernels)",
                  ", ".join(f"{r:.2f}×" for r in ratios.values()), all(r <= STEP_TARGET for r in ratios.values()))
    else:
        table.skipped(f"ARMFlow batch 1, f32: ≤ {STEP_TARGET}× onnxruntime", "step")

    if "avx2" not in skip:
        def measure_avx2():
            sh([sys.executable, "benches/peers.py", "--bundle", str(args.bundle), "--histories",
                ",".join(map(str, HISTORIES)), "--steps", str(args.steps), "--peers", "ort", "--isa", "avx2",
                "--troupe-binary", stream, "--json", str(tmp / "peers-avx2.json")])
            return json.loads((tmp / "peers-avx2.json").read_text())

        avx2 = report["avx2"] = once("avx2", measure_avx2)
        ratios = {h: avx2["troupe"][str(h)]["p50"] / avx2["results"][str(h)]["ort"]["p50"] for h in HISTORIES}
        table.add(f"the same with troupe on the AVX2 kernels: ≤ {STEP_TARGET}× onnxruntime (on its own kernels)",
                  ", ".join(f"{r:.2f}×" for r in ratios.values()), all(r <= STEP_TARGET for r in ratios.values()))
    else:
        table.skipped(f"ARMFlow batch 1 on the AVX2 kernels: ≤ {STEP_TARGET}× onnxruntime", "avx2")

    if "f16" not in skip and peers:
        from peers import combine, run_troupe, spread

        f16 = ROOT / "target/bench/paper-f16"
        if not (f16 / "troupe.json").exists():
            sh([sys.executable, "onnx/cli.py", "armflow", "quantize", "--weights", "float16",
                "--bundle", str(args.bundle), "--out", str(f16)])
        print("$", stream, "--bundle", f16, "(H = 100), alternating with", args.bundle, flush=True)

        def measure_f16():
            # float16 and float32 troupe alternate (A/B/A/B...), so the ratio of their medians holds
            # on a machine whose speed drifts; the step part's alternated troupe/onnxruntime ratio
            # at H = 100 then carries it over to onnxruntime.
            halves, fulls = [], []
            for _ in range(5):
                halves.append(run_troupe(stream, f16, 100, args.steps))
                fulls.append(run_troupe(stream, args.bundle, 100, args.steps))
            return {**combine(halves), "f32": combine(fulls)}

        half = report["f16"] = once("f16", measure_f16)
        ort_over_troupe = peers["results"]["100"]["ort"]["p50"] / peers["troupe"]["100"]["p50"]
        ratio = half["p50"] / half["f32"]["p50"] / ort_over_troupe
        table.add("float16 weights ≤ 0.5× onnxruntime f32 at H = 100",
                  f"{ratio:.2f}× (float16 {spread(half)} ms against troupe float32 {spread(half['f32'])} ms, "
                  f"alternated; troupe f32 / onnxruntime {1 / ort_over_troupe:.2f}× from the step part)",
                  ratio <= 0.5)
        bound = step_bytes(f16) / max(peers["read_bandwidth_bytes_per_s"].values()) * 1e3
        table.add("float16 weights ≤ 1.3× the time to read the bytes of the step",
                  f"{half['p50'] / bound:.2f}× ({half['p50']:.2f} / {bound:.2f} ms)", half["p50"] <= 1.3 * bound)
    else:
        table.skipped("float16 weights ≤ 0.5× onnxruntime f32 at H = 100", "f16" if "f16" in skip else "step")
        table.skipped("float16 weights ≤ 1.3× the bytes' bound", "f16" if "f16" in skip else "step")

    if "demo" not in skip:
        def measure_demo():
            out = sh([stream, "--synthetic", "--frames", "40000", "--no-pictures", "--tick", "4",
                      "--out", str(tmp / "demo.npy")])
            m = re.search(r"every call \((\d+) calls\): p50 ([\d.]+) ms  p99 ([\d.]+) ms  max ([\d.]+) ms", out)
            return {"calls": int(m[1]), "p50": float(m[2]), "p99": float(m[3]), "max": float(m[4])}

        d = report["demo"] = once("demo", measure_demo)
        table.add(f"demo model, clean-ups on, {d['calls']} token calls: p50 ≤ 0.6, p99 ≤ 2, max ≤ 8 ms",
                  f"p50 {d['p50']:.3f}, p99 {d['p99']:.3f}, max {d['max']:.3f} ms",
                  d["p50"] <= 0.6 and d["p99"] <= 2 and d["max"] <= 8)
    else:
        table.skipped("demo model, clean-ups on: p50 ≤ 0.6, p99 ≤ 2, max ≤ 8 ms", "demo")

    if peers:
        growth = peers["troupe"]["2000"]["p50"] / peers["troupe"]["10"]["p50"]
        table.add("unbounded step at H = 2000 ≤ 1.3× the step at H = 10",
                  f"{growth:.2f}× ({peers['troupe']['2000']['p50']:.2f} / {peers['troupe']['10']['p50']:.2f} ms)",
                  growth <= 1.3)
        first = peers["troupe_first"]
        total = (first["load_ms"] + first["first_step_ms"]) / 1e3
        table.add("load to first step ≤ 0.35 s (paper bundle)",
                  f"{total:.3f} s (load {first['load_ms']:.0f} ms + first token {first['first_step_ms']:.1f} ms)",
                  total <= 0.35)
    else:
        table.skipped("unbounded step at H = 2000 ≤ 1.3× H = 10", "step")
        table.skipped("load to first step ≤ 0.35 s", "step")

    # --- crowds -----------------------------------------------------------------------------
    if "crowd" not in skip:
        common = ["--bundle", str(args.bundle), "--rounds", "10", "--threads", "2", "--mode", "batched"]
        def measure_crowd():
            rows = crowd_rows(sh([crowd, *common, "--sessions", args.crowd_sizes, "--history", "100"]))
            peak_out = sh([sys.executable, "benches/sgemm_peak.py", "--threads", "2"])
            return {"rows": rows, "sgemm_peak_gflops": float(re.findall(r"([\d.]+) GFLOP/s", peak_out)[-1])}

        measured = report["crowd"] = once("crowd", measure_crowd)
        rows = {int(n): r for n, r in measured["rows"].items()}
        peak = measured["sgemm_peak_gflops"]
        live = [n for n, r in rows.items() if r["p99"] <= BUDGET_MS]
        largest = max(live, default=0)
        table.add("≥ 150 real-time paper-size streams on 2 cores",
                  f"{largest} of the sizes tried ({args.crowd_sizes}); " + ", ".join(
                      f"{n}: p99 {r['p99']:.1f} ms" for n, r in sorted(rows.items())), largest >= 150)
        if peers:
            flop = 2 * sum(peers["weights_bytes"].values()) / 4  # a lower bound: two per float32 weight
            at = largest or min(rows)
            gflops = flop * at / (rows[at]["p50"] / 1e3) / 1e9
            table.add("crowd arithmetic ≥ 40 % of the sgemm peak of the same run (round three's)",
                      f"{100 * gflops / peak:.0f} % ({gflops:.1f} of {peak:.1f} GFLOP/s, {at} sessions)",
                      gflops / peak >= 0.4)
        else:
            table.skipped("crowd arithmetic ≥ 40 % of the sgemm peak", "step")
        mix = report["mixed_histories"] = once("mixed", lambda: {
            "mixed_p50": crowd_rows(sh([crowd, *common, "--sessions", "16", "--history", "10..2000"]))[16]["p50"],
            "uniform_p50": crowd_rows(sh([crowd, *common, "--sessions", "16", "--history", "1004..1006"]))[16]["p50"],
        })
        mixed, uniform = mix["mixed_p50"], mix["uniform_p50"]
        table.add("mixed histories (16 streams, 10 to 2000) cost what their lengths cost: "
                  "round ≤ 1.2× 16 streams at the mean history",
                  f"{mixed / uniform:.2f}× ({mixed:.1f} / {uniform:.1f} ms)", mixed / uniform <= 1.2)
    else:
        for t in ("≥ 150 real-time streams", "crowd arithmetic ≥ 40 % of peak", "mixed histories"):
            table.skipped(t, "crowd")

    # --- MAGNet -----------------------------------------------------------------------------
    if "magnet" not in skip:
        def measure_magnet():
            sh([sys.executable, "benches/magnet.py", "--bundle", str(args.magnet_bundle), "--checkpoint",
                str(args.magnet_checkpoint), "--json", str(tmp / "magnet.json")], lib_env)
            return json.loads((tmp / "magnet.json").read_text())["per_iteration_ms"]

        per = report["magnet"] = once("magnet", measure_magnet)
        ratios = {f"S = {s}, guidance {g}": per[f"troupe_S{s}_guidance_{g}"] / per[f"torch_S{s}_guidance_{g}"]
                  for s in (1, 10) for g in ("off", "on")}
        table.add("MAGNet DD100 iteration ≤ 0.8× torch eager at S = 10, guidance on (others for reference: "
                  + "; ".join(ratios) + ")",
                  ", ".join(f"{r:.2f}×" for r in ratios.values()), ratios["S = 10, guidance on"] <= 0.8)
        def measure_live():
            sh([sys.executable, "benches/magnet_live.py", "--bundle", str(args.magnet_bundle), "--frames",
                str(args.magnet_frames), "--only", "released;10 steps, guidance off, early", "--threads", "2",
                "--json", str(tmp / "live.json")], lib_env)
            return {r["setting"]: r for r in json.loads((tmp / "live.json").read_text())["results"]}

        live = report["magnet_live"] = once("live", measure_live)
        released, fast = live["released"]["real_time_factor"], live["10 steps, guidance off, early"]["real_time_factor"]
        table.add("MAGNet live partner, released settings, two compute threads: ≥ 1.0× real time",
                  f"{released:.2f}×", released >= 1.0)
        table.add("MAGNet live partner, lower-latency setting (10 steps, guidance off, early; round three's): "
                  "≥ 1.5× real time", f"{fast:.2f}×", fast >= 1.5)
    else:
        table.skipped("MAGNet DD100 iteration ≤ 0.8× torch eager", "magnet")
        table.skipped("MAGNet live partner ≥ 1.0× real time", "magnet")
        table.skipped("MAGNet lower-latency setting ≥ 1.5× real time", "magnet")

    # --- prompts ----------------------------------------------------------------------------
    if "prompt" not in skip:
        env = {**lib_env, "PYTHONPATH": os.pathsep.join([str(ROOT / "bindings/python"), str(ROOT / "onnx")])}
        def measure_prompts():
            sh([sys.executable, "benches/prompts.py", "--bundle", str(args.prompt_bundle), "--json",
                str(tmp / "prompts.json")], env)
            return json.loads((tmp / "prompts.json").read_text())

        p = report["prompt"] = once("prompt", measure_prompts)
        table.add("prompt → condition ≤ 0.9× onnxruntime",
                  f"{p['troupe_vs_ort']:.2f}× ({p['troupe']['median_ms']:.1f} / {p['ort']['median_ms']:.1f} ms)",
                  p["troupe_vs_ort"] <= 0.9)
    else:
        table.skipped("prompt → condition ≤ 0.9× onnxruntime", "prompt")

    # --- exactness --------------------------------------------------------------------------
    if "exactness" not in skip:
        out = sh(["cargo", "test", "--release", "--test", "batch", "--test", "context_cache", "--test", "golden"])
        passed = sum(int(n) for n in re.findall(r"test result: ok\. (\d+) passed", out))
        table.add("batched = alone ≤ 1e-5 in f32; golden parity unchanged", f"{passed} tests passed", True)
    else:
        table.skipped("batched = alone ≤ 1e-5 in f32; golden parity unchanged", "exactness")

    report["targets"] = table.rows
    print(f"\nCPU: {cpu}\n")
    print(table.markdown())
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
