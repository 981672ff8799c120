#!/usr/bin/env python3
"""Benchmark troupe's peers on ARMFlow's streaming step, on the same weights troupe loads (its ONNX files,
but for the context encoder: see `ort` below).

    python3 benches/peers.py                                       # onnx/bundles/paper, all peers
    python3 benches/peers.py --bundle /tmp/tiny --histories 10,100 --steps 20     # after `armflow export
                                                  # --preset tiny --out /tmp/tiny --peer-graphs`
    python3 benches/peers.py --histories 10,100 --steps 20 --peers ort,torch-kv \\
        --troupe-binary target/release/examples/stream --json /tmp/peers.json
    python3 benches/peers.py --peers ort --troupe-binary target/release/examples/stream --isa avx2

The paper bundle is not committed: `python3 onnx/cli.py armflow export --preset paper --out onnx/bundles/paper --peer-graphs`.

A **full step** is one reactor token, as troupe's session runs it for an `armflow` bundle with
per-token VAE steps (onnx/README.md): `vae_encoder_step` on the actor's 4 new frames (posterior
sample `(mean + sqrt(exp(logvar)) * xi) * scale` with fixed noise), one `context_step` with S = 1
against a key/value cache of H tokens, one `velocity` call (one MeanFlow step, no CFG:
`b = eps - u(eps, r=0, t=1)`), and one `vae_decoder_step` on `b / scale`. The loop is closed: each
step's `(a, b)` pair is the next step's context token; the VAE convolution states carry over.

Peers:

- `ort`: onnxruntime on the bundle's graphs, sessions created once, `intra_op_num_threads =
  --threads`, `inter_op_num_threads = 1`. The context encoder is the one graph of the same
  weights with attention inside (`peers/context_step.onnx`, written by `armflow export
  --peer-graphs`; troupe's bundle holds it as per-layer graphs with attention in Rust). That
  step uses IOBinding: the cache is bound once as OrtValues and the key/value outputs (`new_*`)
  stay in ORT-allocated memory (no copy to numpy).
- `torch-kv`: the PyTorch reference (`troupe_onnx.armflow.reference`) built by the ARMFlow
  exporter's `build_model` with the bundle's `producer.preset` and `producer.seed`, so that it
  holds the same weights; eager, `torch.inference_mode()`, `SkipAdaLNTransformer.step` with the
  cache, `VaeStep` for the VAE.
- `torch-recompute`: as `torch-kv`, but the context is recomputed over the whole prefix
  `[sos, pairs...]` plus the new token, from scratch, every step, as the official ARMFlow sampler
  does. Slow at long histories (paper bundle: ~0.1 s per step at H = 100, growing with H).
- troupe itself, when `--troupe-binary` names the built `examples/stream` (tract, one thread
  whatever `--threads` says): run once per history with `--synthetic --no-pictures --capacity H+1 --warmup-tokens H
  --frames 4*(H+steps) --tick 4`, so it streams H real tokens before timing; its p50/p99 over
  the calls that produced a token, and its load time, are parsed from its output.

History. A stream is warmed to H cached tokens by one prefill call, not by H full steps: a
single `context_step` with S = H over `[sos, H-1 synthetic pairs]` (seeded normal values; the
cost of a step does not depend on them) builds the cache, then 3 untimed full steps run. Every
step (untimed and timed) runs against that same H-token cache: its key/value outputs are computed
and dropped, so each timed step sees exactly H cached tokens, as troupe's do with `--capacity H+1`
(where the session drops the oldest pair before appending). The peers pay no eviction; troupe
does. `torch-recompute` likewise recomputes over the same H tokens plus the new one.

Method, for noisy machines: at each history every side (each peer, troupe with the cache
holding all H tokens, troupe at the bundle's own capacity) times a block of `--steps` full steps
in turn, `--repeats` times (5 by default), the order of the sides flipping every repetition
(A B B A A B ...) so that a slow phase of the machine falls on all sides alike. Each block gives
its median (p50) and p99; each side is reported as the median over its blocks, with the spread of
its block medians (lowest to highest), and troupe against a peer as the ratio of the medians.
The report names the CPU, its SIMD flags and the kernels troupe chose (its attention build and
tract's instruction sets); `--isa avx2` or `--isa portable` makes troupe run the kernels of an
AVX2-only or a SIMD-less machine here (`TRACT_CPU_ISA`, which troupe's attention follows too),
so one machine shows how troupe does on the others. onnxruntime chooses its kernels by CPUID
and has no such setting.

Reported per history and peer: median and p99 of the full-step wall time over `--steps` timed
steps (p99 as troupe reports it: the sorted sample at rank round(0.99 (n-1))), and the process
RSS growth when one more stream is created at that history (its cache built, after the first
stream's run has grown the allocators), next to the bytes that stream's state holds. Also: ORT's
load time (all sessions plus the conditioning run) and its first full step; the bytes of
initializers a step reads (context_step + velocity + vae_encoder_step + vae_decoder_step, read
with the `onnx` package) divided by a measured single-thread read bandwidth over a 512 MB float32
array, best of 3, the better of numpy's `sum` and a matrix-vector product (BLAS pinned to one
thread; the GEMV is the batch-1 step's own access pattern, and reads 1.2-1.6x faster than
`sum` on the 2-core dev machine): roughly the least a batch-1 step can take when every weight streams from memory once
(weights still in cache can beat it).

Crowd (`--crowd 4,8`): N ORT streams at the first history, stepped one after another, 10 timed
rounds of one token each; a crowd is real time when a round's p99 fits in 4 frames at 30 fps
(133 ms). troupe's crowds, batched and one by one, are `examples/crowd.rs`.

Check (with two peers or more): at the first history every peer's first full step runs on
identical inputs (same cache tokens, zero VAE states, same frames and noise); their velocity
outputs must agree within 1e-3, so the benchmark cannot silently time a wrong loop.

Needs numpy, onnx and onnxruntime; torch only for the torch peers. Linux (RSS from /proc).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["OPENBLAS_NUM_THREADS"] = "1"  # the bandwidth probe's GEMV runs on one thread
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
WARMUP_STEPS = 3  # untimed full steps after the prefill, at every history
AGREEMENT_TOL = 1e-3
BANDWIDTH_BYTES = 512 * 2**20
STEP_ROLES = ("context_step", "velocity", "vae_encoder_step", "vae_decoder_step")
# The peers run the context encoder as one graph with attention inside, the form they run best;
# troupe's bundle holds it as per-layer graphs. `armflow export --peer-graphs` writes the one
# graph of the same weights here.
PEER_FILES = {"context_step": "peers/context_step.onnx"}
PEERS = ("ort", "torch-kv", "torch-recompute")
# What `--isa` asks tract (and so troupe's attention, which follows tract's view) to run, as
# `TRACT_CPU_ISA` edits of the probed set: the AVX2 machines' kernels on an AVX-512 one, or the
# portable ones. onnxruntime (MLAS) chooses its kernels by CPUID and offers no such setting.
ISA_PRESETS = {
    "native": "",
    "avx2": "-avx512f,-avx512vnni,-avx512fp16,-avxvnni,-amx-int8,-amx-bf16",
    "portable": "-avx512f,-avx512vnni,-avx512fp16,-avxvnni,-amx-int8,-amx-bf16,-avx2,-fma,-avx,-f16c",
}
# The CPU flags worth naming beside a timing: the vector units and dot-product instructions.
SIMD_FLAGS = ("sse4_2", "avx", "avx2", "fma", "f16c", "avx512f", "avx512bw", "avx512vl", "avx512_vnni",
              "avx512_bf16", "avx512_fp16", "avx_vnni", "amx_bf16", "amx_int8", "asimd", "sve")


# --------------------------------------------------------------------------------------------
# Bundle and inputs
# --------------------------------------------------------------------------------------------


class Bundle:
    """The manifest of an `armflow` bundle with per-token VAE steps, and the sizes a step needs."""

    def __init__(self, directory: Path):
        self.dir = directory
        self.manifest = json.loads((directory / "troupe.json").read_text())
        m = self.manifest
        if m["family"] != "armflow":
            sys.exit(f"{directory}: family {m['family']!r}, this benchmark runs 'armflow' bundles")
        peer_file = lambda r: r in PEER_FILES and (directory / PEER_FILES[r]).exists()  # noqa: E731
        missing = [r for r in STEP_ROLES if r not in m["graphs"] and not peer_file(r)]
        if missing:
            sys.exit(f"{directory}: no {', '.join(missing)}; re-export it with onnx/cli.py armflow export --peer-graphs")
        self.name = m["name"]
        self.latent = m["latent"]["dim"]
        self.scale = np.float32(m["latent"]["scale"])
        self.fpt = m["latent"]["frames_per_token"]
        self.frame_dim = m["motion"]["frame_dim"]
        self.cond_dim = m["condition"]["dim"]
        ctx = m["context"]
        self.width, self.layers, self.heads, self.head_dim = (
            ctx["width"], ctx["layers"], ctx["heads"], ctx["head_dim"],
        )

    def path(self, role: str) -> str:
        if role not in self.manifest["graphs"]:
            return str(self.dir / PEER_FILES[role])
        return str(self.dir / self.manifest["graphs"][role]["file"])

    def state_shapes(self, role: str) -> list[tuple[str, list[int]]]:
        """The explicit convolution states of a VAE step graph, (name, shape), in input order."""
        inputs = self.manifest["graphs"][role]["inputs"]
        one = lambda shape: [1 if isinstance(d, str) else d for d in shape]  # noqa: E731  (B = 1)
        return [(x["name"], one(x["shape"])) for x in inputs if x["name"].startswith("state_")]

    def cache_bytes(self, tokens: int) -> int:
        return 2 * self.layers * self.heads * tokens * self.head_dim * 4


class Inputs:
    """Everything a stream consumes, seeded by the history, so that every peer sees the same."""

    def __init__(self, b: Bundle, history: int, steps: int):
        rng = np.random.default_rng(history)
        f32 = lambda *shape: rng.standard_normal(shape, dtype=np.float32)  # noqa: E731
        self.history = history
        self.pairs = f32(1, history - 1, b.width)  # the cached tokens after <sos>
        self.first_pair = f32(b.width)  # the token of the first full step
        self.frames = 0.5 * f32(steps, 1, b.fpt, b.frame_dim)
        self.xi = f32(steps, b.latent)
        self.eps = f32(steps, b.latent)


def fixed_condition(b: Bundle) -> np.ndarray:
    """The conditioning vector every peer's session uses (seeded normal values)."""
    return np.random.default_rng(0).standard_normal((1, b.cond_dim), dtype=np.float32)


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def machine() -> dict:
    """The CPU the run is on: its model, logical cores and the SIMD flags of SIMD_FLAGS it has."""
    model, flags = "unknown", set()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and model == "unknown":
                model = value.strip()
            elif key.strip() in ("flags", "Features") and not flags:
                flags = set(value.split())
    except OSError:
        pass
    return {"cpu": model, "cores": os.cpu_count(), "simd": [f for f in SIMD_FLAGS if f in flags]}


def combine(reps: list[dict]) -> dict:
    """One figure per timed block (a repetition) -> the median over the repetitions of each, and
    the spread of the per-block medians (`p50_min`, `p50_max`, every `p50_each`)."""
    p50s = sorted(r["p50"] for r in reps)
    out = dict(reps[0])  # first-step figures and the agreement check come from the first block
    out.update({
        "p50": float(np.median(p50s)), "p50_min": p50s[0], "p50_max": p50s[-1], "p50_each": p50s,
        "p99": float(np.median([r["p99"] for r in reps])), "repeats": len(reps),
    })
    if "max" in reps[0]:
        out["max"] = max(r["max"] for r in reps)
    if "rss_per_stream_bytes" in reps[0]:
        out["rss_per_stream_bytes"] = int(np.median([r["rss_per_stream_bytes"] for r in reps]))
    return out


def spread(r: dict) -> str:
    """`p50 [min-max]` of a combined figure, in ms."""
    return f"{r['p50']:.2f} [{r['p50_min']:.2f}-{r['p50_max']:.2f}]"


def percentiles(samples_ms: list[float]) -> dict:
    s = sorted(samples_ms)
    rank = lambda p: s[round((len(s) - 1) * p)]  # noqa: E731  (as examples/stream.rs)
    return {"p50": rank(0.5), "p99": rank(0.99), "max": s[-1], "n": len(s)}


# --------------------------------------------------------------------------------------------
# onnxruntime
# --------------------------------------------------------------------------------------------


class OrtPeer:
    def __init__(self, b: Bundle, threads: int, condition: np.ndarray):
        import onnxruntime as ort

        self.ort, self.b = ort, b
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = threads
        opts.inter_op_num_threads = 1
        t0 = time.perf_counter()
        self.sess = {
            role: ort.InferenceSession(b.path(role), opts, providers=["CPUExecutionProvider"])
            for role in ("conditioning", *STEP_ROLES)
        }
        self.modulation, self.start_token = self.sess["conditioning"].run(None, {"condition": condition})
        self.load_ms = (time.perf_counter() - t0) * 1e3
        self.library = f"onnxruntime {ort.__version__}"

    def new_stream(self, inp: Inputs) -> "OrtStream":
        return OrtStream(self, inp)


class OrtStream:
    def __init__(self, peer: OrtPeer, inp: Inputs):
        b, ort = peer.b, peer.ort
        self.peer, self.b = peer, b
        ctx = peer.sess["context_step"]
        empty = np.zeros((1, b.heads, 0, b.head_dim), np.float32)
        tokens = np.concatenate([peer.start_token, inp.pairs], axis=1)
        prefill = {
            "tokens": tokens,
            "positions": np.arange(inp.history, dtype=np.int64)[None],
            "modulation": peer.modulation,
            "key_mask": np.zeros((1, 0), np.float32),  # one stream: nothing to mask
        }
        prefill |= {f"past_{kv}_{i}": empty for i in range(b.layers) for kv in ("key", "value")}
        outputs = [x.name for x in ctx.get_outputs()]
        present = dict(zip(outputs, ctx.run(None, prefill)))
        # A bundle's step returns the new tokens' entries (`new_*`; the prefill's are the whole
        # cache) or, exported before the runtime owned the cache, the whole cache (`present_*`).
        self.cache = {
            "past_" + n.split("_", 1)[1]: x for n, x in present.items() if n.startswith(("new_", "present_"))
        }
        self.io = ctx.io_binding()
        self.io.bind_cpu_input("modulation", peer.modulation)
        self.io.bind_cpu_input("key_mask", np.zeros((1, inp.history), np.float32))
        for name, x in self.cache.items():  # OrtValues over self.cache's memory: no copy
            self.io.bind_ortvalue_input(name, ort.OrtValue.ortvalue_from_numpy(x))
        for name in outputs:  # every output, so that ORT computes the new entries
            self.io.bind_output(name, "cpu")
        self.position = np.array([[inp.history]], np.int64)
        self.enc_state = [np.zeros(s, np.float32) for _, s in b.state_shapes("vae_encoder_step")]
        self.dec_state = [np.zeros(s, np.float32) for _, s in b.state_shapes("vae_decoder_step")]
        self.enc_names = [n for n, _ in b.state_shapes("vae_encoder_step")]
        self.dec_names = [n for n, _ in b.state_shapes("vae_decoder_step")]
        self.pair = inp.first_pair
        self.r, self.t = np.zeros(1, np.float32), np.ones(1, np.float32)

    def state_bytes(self) -> int:
        return sum(x.nbytes for x in [*self.cache.values(), *self.enc_state, *self.dec_state])

    def step(self, frames: np.ndarray, xi: np.ndarray, eps: np.ndarray) -> np.ndarray:
        s, b = self.peer.sess, self.b
        mean, logvar, *self.enc_state = s["vae_encoder_step"].run(
            None, {"motion": frames, **dict(zip(self.enc_names, self.enc_state))}
        )
        a = (mean[0, 0] + np.sqrt(np.exp(logvar[0, 0])) * xi) * b.scale
        self.io.bind_cpu_input("tokens", self.pair[None, None])
        self.io.bind_cpu_input("positions", self.position)
        s["context_step"].run_with_iobinding(self.io)
        context = self.io.get_outputs()[0].numpy()  # the new entries are dropped: fixed history
        (u,) = s["velocity"].run(
            None, {"actor": a[None], "noisy": eps[None], "context": context, "r": self.r, "t": self.t}
        )
        reactor = eps - u[0]
        _, *self.dec_state = s["vae_decoder_step"].run(
            None, {"latents": (reactor / b.scale)[None, None], **dict(zip(self.dec_names, self.dec_state))}
        )
        self.pair = np.concatenate([a, reactor])
        return u


# --------------------------------------------------------------------------------------------
# torch eager (the reference modules)
# --------------------------------------------------------------------------------------------


class TorchPeer:
    def __init__(self, b: Bundle, threads: int, condition: np.ndarray, recompute: bool):
        import torch

        sys.path.insert(0, str(ROOT / "onnx"))
        from troupe_onnx.armflow.export import TOOL, build_model
        from troupe_onnx.armflow.reference import VaeStep

        producer = b.manifest.get("producer", {})
        # "onnx/export.py": bundles exported before the exporter moved behind onnx/cli.py
        if producer.get("tool") not in (TOOL, "onnx/export.py"):
            sys.exit(f"{b.dir}: producer is not {TOOL}; the torch peers cannot rebuild its weights")
        torch.set_num_threads(threads)
        self.torch, self.b, self.recompute = torch, b, recompute
        self.library = f"torch {torch.__version__}"
        model = build_model(producer["preset"], producer["seed"])
        self.context, self.velocity = model.armflow.arnet, model.armflow.velocity
        self.encoder, self.decoder = VaeStep(model.vae.encoder), VaeStep(model.vae.decoder)
        with torch.inference_mode():
            self.modulation = self.context.modulation(torch.from_numpy(condition))
            self.start_token = model.armflow.start_token.detach().clone()

    def new_stream(self, inp: Inputs) -> "TorchStream":
        with self.torch.inference_mode():
            return TorchStream(self, inp)


class TorchStream:
    def __init__(self, peer: TorchPeer, inp: Inputs):
        torch, b = peer.torch, peer.b
        self.peer, self.b, self.torch = peer, b, torch
        self.empty = [(torch.zeros(1, b.heads, 0, b.head_dim),) * 2 for _ in range(b.layers)]
        self.prefix = torch.cat([peer.start_token, torch.from_numpy(inp.pairs)], dim=1)
        self.history = inp.history
        if not peer.recompute:
            positions = torch.arange(inp.history)[None]
            _, self.cache = peer.context.step(self.prefix, positions, peer.modulation, self.empty)
        self.enc_state = [torch.zeros(s) for s in peer.encoder.state_shapes()]
        self.dec_state = [torch.zeros(s) for s in peer.decoder.state_shapes()]
        self.pair = torch.from_numpy(inp.first_pair)
        self.r, self.t = torch.zeros(1), torch.ones(1)

    def state_bytes(self) -> int:
        held = [t for kv in self.cache for t in kv] if not self.peer.recompute else [self.prefix]
        return sum(t.numel() * t.element_size() for t in held + self.enc_state + self.dec_state)

    def step(self, frames: np.ndarray, xi: np.ndarray, eps: np.ndarray) -> np.ndarray:
        with self.torch.inference_mode():
            return self._step(frames, self.torch.from_numpy(xi), self.torch.from_numpy(eps))

    def _step(self, frames, xi, eps):
        p, b, torch = self.peer, self.b, self.torch
        out, *self.enc_state = p.encoder(torch.from_numpy(frames), *self.enc_state)
        mean, logvar = out[0, 0, : b.latent], out[0, 0, b.latent :]
        a = (mean + torch.sqrt(torch.exp(logvar)) * xi) * float(b.scale)
        token = self.pair[None, None]
        if p.recompute:  # the whole prefix plus the new token, from an empty cache
            tokens = torch.cat([self.prefix, token], dim=1)
            positions = torch.arange(self.history + 1)[None]
            context, _ = p.context.step(tokens, positions, p.modulation, self.empty)
        else:  # the new entries are dropped: fixed history
            context, _ = p.context.step(token, torch.tensor([[self.history]]), p.modulation, self.cache)
        u = p.velocity(a[None], eps[None], context, self.r, self.t)
        reactor = eps - u[0]
        _, *self.dec_state = p.decoder((reactor / float(b.scale))[None, None], *self.dec_state)
        self.pair = torch.cat([a, reactor])
        return u.numpy()


# --------------------------------------------------------------------------------------------
# Measurements
# --------------------------------------------------------------------------------------------


def run_peer(peer, inp: Inputs, steps: int) -> dict:
    """Warm a stream to the history, time `steps` full steps, then measure one more stream's RSS."""
    stream = peer.new_stream(inp)
    times = []
    gc.collect()
    gc.disable()
    try:
        for k in range(WARMUP_STEPS + steps):
            t0 = time.perf_counter()
            u = stream.step(inp.frames[k], inp.xi[k], inp.eps[k])
            ms = (time.perf_counter() - t0) * 1e3
            if k == 0:
                first_velocity, first_ms = u, ms
            if k >= WARMUP_STEPS:
                times.append(ms)
    finally:
        gc.enable()
    gc.collect()
    before = rss_bytes()
    extra = peer.new_stream(inp)
    grown = rss_bytes() - before
    return percentiles(times) | {
        "first_step_ms": first_ms,
        "rss_per_stream_bytes": grown,
        "state_bytes": extra.state_bytes(),
        "first_velocity": first_velocity,
    }


def run_crowd(peer, inp: Inputs, sizes: list[int], rounds: int) -> dict:
    """N streams of `peer` at the history, stepped one by one: each round gives every stream one
    token (4 frames, 133 ms of motion at 30 fps). Returns round p50 / p99 ms per N."""
    out = {}
    for n in sizes:
        streams = [peer.new_stream(inp) for _ in range(n)]
        times = []
        for k in range(WARMUP_STEPS + rounds):
            t0 = time.perf_counter()
            for stream in streams:
                stream.step(inp.frames[k], inp.xi[k], inp.eps[k])
            if k >= WARMUP_STEPS:
                times.append((time.perf_counter() - t0) * 1e3)
        out[n] = percentiles(times)
        del streams
        gc.collect()
    return out


def initializer_bytes(path: Path) -> int:
    """Bytes of an ONNX file's initializers (its weights), in the types they are stored in."""
    import onnx
    from onnx.helper import tensor_dtype_to_np_dtype

    return sum(int(np.prod(t.dims)) * tensor_dtype_to_np_dtype(t.data_type).itemsize
               for t in onnx.load(path).graph.initializer)


def weight_bytes(b: Bundle) -> dict:
    return {role: initializer_bytes(b.path(role)) for role in STEP_ROLES}


def read_bandwidth() -> dict:
    """Bytes per second one thread reads from a 512 MB float32 array, best of 3, by `sum` and by
    a matrix-vector product over it."""
    x = np.ones((BANDWIDTH_BYTES // 4 // 4096, 4096), np.float32)
    v = np.ones(4096, np.float32)
    probes = {"sum": x.sum, "matvec": lambda: x @ v}
    out = {}
    for name, probe in probes.items():
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            probe()
            best = min(best, time.perf_counter() - t0)
        out[name] = x.nbytes / best
    return out


def troupe_env(isa: str) -> dict:
    """The environment troupe's binary runs in: `TRACT_CPU_ISA` as `--isa` asks."""
    env = dict(os.environ)
    env.pop("TRACT_CPU_ISA", None)
    if ISA_PRESETS[isa]:
        env["TRACT_CPU_ISA"] = ISA_PRESETS[isa]
    return env


def run_troupe(binary: str, bundle: Path, history: int, steps: int, bounded: bool = False,
               isa: str = "native") -> dict:
    """troupe's stream at `history`: the cache holds all H tokens (capacity H + 1), or with
    `bounded` the bundle's own capacity (the oldest pairs slide out)."""
    with tempfile.TemporaryDirectory() as tmp:
        capacity = [] if bounded else ["--capacity", str(history + 1)]
        cmd = [
            binary, "--bundle", str(bundle), "--synthetic", "--no-pictures", *capacity,
            "--warmup-tokens", str(history), "--frames", str(4 * (history + steps)), "--tick", "4",
            "--out", str(Path(tmp) / "reactor.npy"),
        ]
        out = subprocess.run(cmd, capture_output=True, text=True, check=True, env=troupe_env(isa)).stdout
    m = re.search(r"calls that produced a token \((\d+) calls\): p50 ([\d.]+) ms\s+p99 ([\d.]+) ms", out)
    load = re.search(r"loaded in ([\d.]+) ms", out)
    kernels = re.search(r"^kernels: (.*)$", out, re.M)
    if not m or not load or not kernels:
        sys.exit(f"cannot parse the output of {' '.join(cmd)}:\n{out}")
    return {"n": int(m[1]), "p50": float(m[2]), "p99": float(m[3]), "load_ms": float(load[1]),
            "kernels": kernels[1]}


def troupe_first_step(binary: str, bundle: Path, isa: str = "native") -> dict:
    """A fresh process: `Model::load` and a session (troupe's own report), then the first token."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [binary, "--bundle", str(bundle), "--synthetic", "--no-pictures", "--frames", "4", "--tick", "4",
               "--out", str(Path(tmp) / "r.npy")]
        out = subprocess.run(cmd, capture_output=True, text=True, check=True, env=troupe_env(isa)).stdout
    load = re.search(r"loaded in ([\d.]+) ms", out)
    first = re.search(r"every call \(1 calls\): p50 ([\d.]+) ms", out)
    if not load or not first:
        sys.exit(f"cannot parse the output of {' '.join(cmd)}:\n{out}")
    return {"load_ms": float(load[1]), "first_step_ms": float(first[1])}


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


def check_agreement(first: dict) -> dict:
    """Max |diff| of each peer's first-step velocity against the first peer's; asserts the bound."""
    (ref_name, ref), *others = ((n, r.pop("first_velocity")) for n, r in first.items())
    agreement = {}
    for name, u in others:
        diff = agreement[f"{name} vs {ref_name}"] = float(np.abs(u - ref).max())
        assert diff < AGREEMENT_TOL, f"velocity of {name} and {ref_name} differ by {diff:.3g}"
    return agreement


def table(s: dict) -> str:
    """Per history: each side's median over the repetitions of its blocks' p50 [the lowest and
    highest block p50], its median p99, and troupe / peer as the ratio of the medians."""
    troupe, peers, bounded = s["troupe"], s["peers"], s["troupe_bounded"]
    head = ["history"] + ([f"troupe bounded ({s['capacity']}) p50 [spread] / p99 ms",
                           "troupe p50 [spread] / p99 ms"] if troupe else [])
    for p in peers:
        head += [f"{p} p50 [spread] / p99 ms"] + ([f"troupe / {p} (p50, p99)"] if troupe else [])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for h, results in s["results"].items():
        row = [str(h)]
        if troupe:
            row.append(f"{spread(bounded[h])} / {bounded[h]['p99']:.2f}")
            row.append(f"{spread(troupe[h])} / {troupe[h]['p99']:.2f}")
        for p in peers:
            r = results[p]
            row.append(f"{spread(r)} / {r['p99']:.2f}")
            if troupe:
                row.append(f"{troupe[h]['p50'] / r['p50']:.2f}x, {troupe[h]['p99'] / r['p99']:.2f}x")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def print_report(s: dict):
    troupe, results = s["troupe"], s["results"]
    first, last = next(iter(results)), list(results)[-1]
    m = s["machine"]
    print(f"\n## {s['name']}: full streaming step, {s['repeats']} alternating repetitions of {s['steps']} "
          f"timed steps per history and side, {s['threads']} thread(s)\n")
    print(f"CPU: {m['cpu']} ({m['cores']} logical cores), SIMD: {' '.join(m['simd'])}")
    if troupe:
        kernels = sorted({t["kernels"] for t in troupe.values()})
        print(f"troupe kernels (--isa {s['isa']}): {'; '.join(kernels)}")
    print("onnxruntime kernels: MLAS, chosen by CPUID (no setting forces another family)\n")
    print(table(s))
    print()
    print("versions: " + ", ".join(s["versions"]))
    if s["ort_load_ms"] is not None:
        print(f"ORT load (5 sessions + conditioning run): {s['ort_load_ms']:.0f} ms")
    if s["ort_load_ms"] is not None:
        print(f"ORT load to first step: {s['ort_load_ms'] + results[first]['ort']['first_step_ms']:.0f} ms "
              f"(load {s['ort_load_ms']:.0f} + first step at H={first})")
    if troupe:
        f = s["troupe_first"]
        print(f"troupe load to first step (fresh process, Model::load + session + first token): "
              f"{f['load_ms'] + f['first_step_ms']:.0f} ms (load {f['load_ms']:.0f} + {f['first_step_ms']:.1f})")
        b = s["troupe_bounded"]
        print(f"troupe bounded, step at H={last} / step at H={first}: "
              f"p50 {b[last]['p50'] / b[first]['p50']:.2f}x, p99 {b[last]['p99'] / b[first]['p99']:.2f}x")
    print(f"first full step (H={first}): "
          + ", ".join(f"{n} {r['first_step_ms']:.2f} ms" for n, r in results[first].items()))
    if s["velocity_agreement"]:
        print(f"first-step velocity agreement (max |diff|, tolerance {AGREEMENT_TOL:g}): "
              + ", ".join(f"{k} {v:.2e}" for k, v in s["velocity_agreement"].items()))
    weights, bound = s["weights_bytes"], s["bandwidth_bound_ms"]
    parts = ", ".join(f"{r} {v / 1e6:.1f}" for r, v in weights.items())
    probes = ", ".join(f"{k} {v / 1e9:.1f}" for k, v in s["read_bandwidth_bytes_per_s"].items())
    print(f"weights read per step: {sum(weights.values()) / 1e6:.1f} MB ({parts}); "
          f"single-thread read bandwidth GB/s: {probes} -> bandwidth bound {bound:.2f} ms per step")
    if troupe:
        print("troupe p50 / bound: " + ", ".join(f"H={h} {t['p50'] / bound:.2f}x" for h, t in troupe.items()))
    for h, by_peer in results.items():
        print(f"RSS growth per added stream at H={h} (state held): " + ", ".join(
            f"{n} {r['rss_per_stream_bytes'] / 1e6:+.1f} MB ({r['state_bytes'] / 1e6:.1f} MB)"
            for n, r in by_peer.items()))
    if s["ort_crowd"]:
        budget = 1e3 * 4 / 30
        for n, r in s["ort_crowd"].items():
            print(f"ORT crowd of {n} at H={first}, one by one: round p50 {r['p50']:.1f} ms, p99 {r['p99']:.1f} ms "
                  f"({'real time' if r['p99'] <= budget else 'not real time'}: budget {budget:.1f} ms)")
    print(f"(KV cache alone at H={last}: {s['kv_cache_bytes_at_last'] / 1e6:.1f} MB; "
          "RSS growth is approximate: allocators reuse memory freed by the first stream)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, default=ROOT / "onnx" / "bundles" / "paper")
    ap.add_argument("--histories", default="10,100,1000,2000", help="comma-separated cached tokens H")
    ap.add_argument("--steps", type=int, default=50, help="timed full steps per history")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--peers", default=",".join(PEERS), help=f"comma-separated, of {', '.join(PEERS)}")
    ap.add_argument("--troupe-binary", help="the built examples/stream, to time troupe as well")
    ap.add_argument("--json", type=Path, help="also write the results here")
    ap.add_argument("--crowd", help="comma-separated crowd sizes: time ORT streams stepped one by one "
                    "at the first history (compare with examples/crowd.rs)")
    ap.add_argument("--repeats", type=int, default=5,
                    help="alternating repetitions per history: each side times --steps steps in turn, "
                    "A/B/B/A..., and each side's figures are medians over its repetitions")
    ap.add_argument("--isa", choices=sorted(ISA_PRESETS), default="native",
                    help="the kernel family troupe runs (TRACT_CPU_ISA): this machine's, AVX2's or portable")
    args = ap.parse_args()
    histories = [int(h) for h in args.histories.split(",")]
    peer_names = args.peers.split(",")
    if unknown := set(peer_names) - set(PEERS):
        ap.error(f"unknown peers {sorted(unknown)}")
    if min(histories) < 1 or args.steps < 1 or args.repeats < 1:
        ap.error("histories, --steps and --repeats must be >= 1")
    b = Bundle(args.bundle)
    condition = fixed_condition(b)
    peers = {
        name: OrtPeer(b, args.threads, condition) if name == "ort"
        else TorchPeer(b, args.threads, condition, recompute=name == "torch-recompute")
        for name in peer_names
    }

    # Every side times a block of --steps steps in turn, the order flipping each repetition
    # (A B B A A B ...), so that a machine's slow phase falls on both sides alike.
    results, agreement = {}, {}
    troupe = bounded = first = None
    if args.troupe_binary:
        troupe, bounded = {}, {}
    for h in histories:
        inp = Inputs(b, h, WARMUP_STEPS + args.steps)
        sides = [(name, lambda p=p: run_peer(p, inp, args.steps)) for name, p in peers.items()]
        if args.troupe_binary:
            sides.append(("troupe", lambda: run_troupe(args.troupe_binary, args.bundle, h, args.steps, isa=args.isa)))
            sides.append(("troupe bounded", lambda: run_troupe(args.troupe_binary, args.bundle, h, args.steps,
                                                               bounded=True, isa=args.isa)))
        reps = {name: [] for name, _ in sides}
        for r in range(args.repeats):
            for name, run in sides if r % 2 == 0 else reversed(sides):
                reps[name].append(run())
        results[h] = {name: combine(reps[name]) for name in peers}
        if args.troupe_binary:
            troupe[h], bounded[h] = combine(reps["troupe"]), combine(reps["troupe bounded"])
        print(f"history {h}: " + ", ".join(f"{n} p50 {combine(v)['p50']:.2f} ms" for n, v in reps.items()),
              file=sys.stderr)
        if h == histories[0]:  # identical inputs on every peer's first full step
            agreement = check_agreement(results[h])
        for r in results[h].values():
            r.pop("first_velocity", None)
    crowd = None
    if args.crowd and "ort" in peers:
        sizes = [int(n) for n in args.crowd.split(",")]
        crowd = run_crowd(peers["ort"], Inputs(b, histories[0], WARMUP_STEPS + 10), sizes, 10)
    if args.troupe_binary:
        first = troupe_first_step(args.troupe_binary, args.bundle, args.isa)
    weights = weight_bytes(b)
    bandwidth = read_bandwidth()

    summary = {
        "bundle": str(args.bundle), "name": b.name, "steps": args.steps, "threads": args.threads,
        "repeats": args.repeats, "isa": args.isa, "machine": machine(),
        "warmup_steps": WARMUP_STEPS, "peers": peer_names,
        "versions": sorted({f"numpy {np.__version__}"} | {p.library for p in peers.values()}),
        "ort_load_ms": peers["ort"].load_ms if "ort" in peers else None,
        "velocity_agreement": agreement,
        "weights_bytes": weights, "read_bandwidth_bytes_per_s": bandwidth,
        "bandwidth_bound_ms": sum(weights.values()) / max(bandwidth.values()) * 1e3,
        "kv_cache_bytes_at_last": b.cache_bytes(histories[-1]),
        "results": results, "troupe": troupe, "troupe_bounded": bounded, "troupe_first": first,
        "capacity": b.manifest["context"]["capacity_tokens"], "ort_crowd": crowd,
    }
    print_report(summary)
    if args.json:
        args.json.write_text(json.dumps(summary, indent=2) + "\n")  # history keys become strings


if __name__ == "__main__":
    main()
