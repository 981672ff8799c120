#!/usr/bin/env python3
"""Where a streaming step's work goes: instruction counts under valgrind's callgrind, which are
repeatable on a noisy machine (wall time is not), per graph and per kind of work.

    cargo build --release --example stream
    python3 onnx/cli.py armflow export --preset paper --out onnx/bundles/paper
    python3 benches/profile_step.py --bundle onnx/bundles/paper --history 100 --tokens 5
    python3 benches/profile_step.py --bundle onnx/bundles/paper --history 10 --tokens 2 --crowd 64

`examples/stream` streams a synthetic actor one token (4 frames) per `Session::step` call with
`--capacity H+1`, so after `H` warm-up tokens every step sees `H` cached tokens. callgrind
collects only inside `Session::step` and writes one profile per call (`--dump-after`); the last
`--tokens` profiles are the steps at history `H`, and their mean is reported. With `--crowd N`,
`examples/crowd` runs N sessions batched on one thread (`step_sessions`: one call per graph for
all of them), and each profile is one round of N tokens.

- per graph: the inclusive instructions of troupe's typed calls (`ContextEncoder::step` for the context encoder, its attention included,
  `velocity`, `encode_step`, `decode_step`), the rest of the step being troupe's own work;
- per kind: every function's own instructions, sorted by name into matrix products
  (tract-linalg's matmul kernels, packing, im2col), memory copies (memcpy/memmove/memset),
  allocation (malloc/free), element-wise work and reductions (tract-linalg's other kernels,
  tract's ndarray loops), tract's graph machinery (everything else of tract: op dispatch,
  shapes, tensor bookkeeping) and troupe.

Instructions are not time: a vectorised matrix kernel retires more work per instruction than a
copy, and a copy that misses the caches costs more time than its count says. The kinds say
where instructions go; the timings in docs/PERFORMANCE.md say what they cost. Linux, valgrind.
"""

from __future__ import annotations

import argparse
import collections
import json
import re
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

GRAPHS = {
    "context_step": "troupe::armflow::context::ContextEncoder::step",
    "velocity": "troupe::armflow::networks::Networks::velocity",
    "vae_encoder_step": "troupe::armflow::networks::Networks::encode_step",
    "vae_decoder_step": "troupe::armflow::networks::Networks::decode_step",
}

KINDS = [  # (kind, pattern on the function name), first match wins
    ("matrix products (kernels, packing, im2col)",
     re.compile(r"mmm|MatMatMul|matmul|gemm|einsum|pack|Packer|im2col|Patcher|_mmv", re.I)),
    ("memory copies", re.compile(r"memcpy|memmove|memset|__mempcpy")),
    ("allocation", re.compile(r"malloc|free|realloc|__rust_alloc|__rust_dealloc|_int_|calloc|posix_memalign")),
    ("element-wise and reductions", re.compile(
        r"ndarray::zip|tract_linalg|binary|unary|reduce|softmax|sigmoid|exp|tanh|erf|layer_?norm|BinMiniOp|ElementWise",
        re.I)),
    ("tract graph machinery", re.compile(r"tract_|ndarray|smallvec|hashbrown|TDim|dyn_clone", re.I)),
    ("troupe", re.compile(r"troupe")),
]


def parse(path: Path) -> tuple[dict, dict]:
    """Self and inclusive instruction counts per function of one callgrind profile."""
    names: dict[str, str] = {}
    self_cost: collections.Counter = collections.Counter()
    inclusive: collections.Counter = collections.Counter()
    fn = None
    callee = None
    pending_call = False

    def name(spec: str) -> str:
        m = re.match(r"\((\d+)\)(?: (.*))?", spec)
        if not m:
            return spec
        ident, text = m.groups()
        if text:
            names[ident] = text
        return names.get(ident, ident)

    for line in path.read_text(errors="replace").splitlines():
        if line.startswith("fn="):
            fn = name(line[3:])
        elif line.startswith("cfn="):
            callee = name(line[4:])
        elif line.startswith("calls="):
            pending_call = True
        elif line and (line[0].isdigit() or line[0] in "+-*"):
            parts = line.split()
            if len(parts) < 2 or fn is None:
                continue
            cost = int(parts[1])
            if pending_call:
                inclusive[callee] += cost
                pending_call = False
            else:
                self_cost[fn] += cost
    return self_cost, inclusive


def kind_of(function: str) -> str:
    for kind, pattern in KINDS:
        if pattern.search(function):
            return kind
    return "other (libc, std)"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, default=ROOT / "onnx" / "bundles" / "paper")
    ap.add_argument("--history", type=int, default=100, help="cached tokens during the profiled steps")
    ap.add_argument("--tokens", type=int, default=5, help="profiled steps, after the warm-up")
    ap.add_argument("--binary", type=Path, default=ROOT / "target" / "release" / "examples" / "stream")
    ap.add_argument("--top", type=int, default=12, help="functions listed by their own instructions")
    ap.add_argument("--crowd", type=int, default=0,
                    help="profile a batched round of this many sessions (examples/crowd) instead of one stream")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if args.crowd and args.binary.name == "stream":
        args.binary = args.binary.with_name("crowd")

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        tokens = args.history + args.tokens
        entry = "troupe::armflow::session::step_sessions" if args.crowd else "troupe::armflow::session::Session::step"
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", "--collect-atstart=no",
               f"--toggle-collect={entry}", f"--dump-after={entry}", str(args.binary), "--bundle", str(args.bundle)]
        if args.crowd:  # the crowd's warm-up and timed rounds are all batched calls
            cmd += ["--sessions", str(args.crowd), "--history", str(args.history), "--rounds", str(args.tokens),
                    "--threads", "1", "--mode", "batched"]
        else:
            cmd += ["--synthetic", "--frames", str(4 * tokens), "--tick", "4", "--capacity", str(args.history + 1),
                    "--no-pictures", "--out", str(Path(tmp) / "o.npy")]
        subprocess.run(cmd, check=True, capture_output=True)
        dumps = sorted(Path(tmp).glob("callgrind.out.*"), key=lambda p: int(p.suffix[1:]))
        chosen = dumps[-args.tokens:]
        total_self: collections.Counter = collections.Counter()
        total_incl: collections.Counter = collections.Counter()
        for dump in chosen:
            s, i = parse(dump)
            total_self.update(s)
            total_incl.update(i)
    n = len(chosen)
    step = sum(total_self.values()) / n
    graphs = {g: total_incl[f] / n for g, f in GRAPHS.items()}
    graphs["troupe's own work and the rest"] = step - sum(graphs.values())
    kinds: collections.Counter = collections.Counter()
    for f, c in total_self.items():
        kinds[kind_of(f)] += c / n
    top = [(f, c / n, kind_of(f)) for f, c in total_self.most_common(args.top)]
    report = {"bundle": str(args.bundle), "history": args.history, "profiled_steps": n,
              "instructions_per_step": step, "per_graph": graphs, "per_kind": dict(kinds),
              "top_functions": [{"function": f, "instructions": c, "kind": k} for f, c, k in top]}
    what = f"batched round of {args.crowd} sessions" if args.crowd else "step"
    print(f"{args.bundle}, history {args.history}: {step / 1e6:.1f} M instructions per {what} (mean of {n})")
    print("\n| graph | M instructions | share |\n|---|---|---|")
    for g, c in graphs.items():
        print(f"| {g} | {c / 1e6:.1f} | {100 * c / step:.1f} % |")
    print("\n| kind of work | M instructions | share |\n|---|---|---|")
    for k, c in kinds.most_common():
        print(f"| {k} | {c / 1e6:.1f} | {100 * c / step:.1f} % |")
    print("\n| function (own instructions) | M | kind |\n|---|---|---|")
    for f, c, k in top:
        print(f"| `{f[:90]}` | {c / 1e6:.2f} | {k} |")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
