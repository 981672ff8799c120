"""troupe's portable noise generator in Python: Philox4x32-10 + Box-Muller (mirrors src/shared/noise.rs).

The normals troupe draws for (seed, token, stream), shared by the families; each family numbers
its own streams (`STREAM_*` in its reference). The golden tests check that the Rust generator
gives the same normals bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

_PHILOX_M0, _PHILOX_M1 = 0xD2511F53, 0xCD9E8D57
_PHILOX_W0, _PHILOX_W1 = 0x9E3779B9, 0xBB67AE85
_MASK32 = 0xFFFFFFFF


def philox4x32(counter, key):
    c0, c1, c2, c3 = counter
    k0, k1 = key
    for _ in range(10):
        p0, p1 = _PHILOX_M0 * c0, _PHILOX_M1 * c2
        c0, c1, c2, c3 = (
            ((p1 >> 32) ^ c1 ^ k0) & _MASK32,
            p1 & _MASK32,
            ((p0 >> 32) ^ c3 ^ k1) & _MASK32,
            p0 & _MASK32,
        )
        k0, k1 = (k0 + _PHILOX_W0) & _MASK32, (k1 + _PHILOX_W1) & _MASK32
    return c0, c1, c2, c3


def philox_normals(seed: int, token: int, stream: int, n: int) -> np.ndarray:
    """The n standard normals troupe draws for (seed, token, stream); see src/shared/noise.rs."""
    key = (seed & _MASK32, (seed >> 32) & _MASK32)
    out = []
    block = 0
    while len(out) < n:
        words = philox4x32((block, token & _MASK32, (token >> 32) & _MASK32, stream), key)
        for a, b in ((words[0], words[1]), (words[2], words[3])):
            u1 = (a + 0.5) * 2.0**-32
            u2 = (b + 0.5) * 2.0**-32
            rad = math.sqrt(-2.0 * math.log(u1))
            out += [rad * math.cos(2.0 * math.pi * u2), rad * math.sin(2.0 * math.pi * u2)]
        block += 1
    return np.array(out[:n], dtype=np.float64).astype(np.float32)
