#!/usr/bin/env python3
"""The float32 matrix-product peak of this machine's cores, to set a crowd round's arithmetic
against (docs/PERFORMANCE.md, issue 18's crowd target).

    python3 benches/sgemm_peak.py [--size 2048] [--threads 1,2]

numpy's `matmul` of two `size x size` float32 matrices (OpenBLAS or whatever BLAS numpy links),
one fresh process per thread count (the BLAS reads its thread count at start): the best of 10
runs after 2 warm-up runs, in GFLOP/s (2 size^3 per product).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

PROBE = """
import time, numpy as np
n = {size}
a = np.random.default_rng(0).standard_normal((n, n), dtype=np.float32)
b = np.random.default_rng(1).standard_normal((n, n), dtype=np.float32)
for _ in range(2):
    a @ b
best = min((lambda t0: (a @ b, time.perf_counter() - t0)[1])(time.perf_counter()) for _ in range(10))
print(2 * n ** 3 / best / 1e9)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--threads", default="1,2")
    args = ap.parse_args()
    for t in (int(x) for x in args.threads.split(",")):
        env = {**os.environ, **{k: str(t) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}}
        out = subprocess.run([sys.executable, "-c", PROBE.format(size=args.size)], env=env,
                             capture_output=True, text=True, check=True).stdout
        print(f"sgemm {args.size}x{args.size}, {t} thread(s): {float(out):.1f} GFLOP/s")


if __name__ == "__main__":
    main()
