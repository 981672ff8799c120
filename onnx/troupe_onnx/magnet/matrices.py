"""MAGNet's scheduling matrices (`docs/spec/magnet.md` §4): one row of noise levels per
iteration, one column per flattened window token `f = t * P + p`; iteration r goes from row r to
row r + 1. Mirrored by `src/magnet/matrices.rs`.
"""

from __future__ import annotations

import math

import numpy as np

from troupe_onnx.magnet.schedule import CLEAN, PURE_NOISE, level_table

SCHEDULES = ("full_sequence", "causal_uncertainty", "autoregressive")


def index_matrix(kind: str, steps: int, length: int, group: int, offset_proportion: float = 0.0) -> np.ndarray:
    """Step indices 0..steps (§4.1) for a window of `length` flat tokens in groups of `group`."""
    n, f = steps, np.arange(length)
    if kind == "full_sequence":
        rows = n + 1
        return np.repeat((n - np.arange(rows))[:, None], length, axis=1)
    if kind == "causal_uncertainty":
        rows = n + length // group
        m = np.arange(rows)[:, None]
        return np.clip(n + f[None] // group - m, 0, n)
    if kind == "autoregressive":
        off = int(n * (1 - offset_proportion))
        groups = math.ceil(length / group)
        d = max(n - off, 0)
        rows = n + (groups - 1) * d + 1
        m = np.arange(rows)[:, None]
        return np.clip(n + (f[None] // group) * d - m, 0, n)
    raise ValueError(f"unknown schedule {kind!r}: one of {', '.join(SCHEDULES)}")


def prune(levels: np.ndarray) -> np.ndarray:
    """Drops the leading rows equal to their successor, keeping the last of them (§4.2 step 3)."""
    for i in range(levels.shape[0] - 1):
        if not np.array_equal(levels[i + 1], levels[i]):
            return levels[i:]
    return levels


def level_matrix(
    kind: str, steps: int, window: int, persons: int, group: int, context_tokens: int,
    offset_proportion: float = 0.0, do_prune: bool = True,
) -> np.ndarray:
    """The first window's level matrix (§4.2): indices mapped through the level table, the first
    `context_tokens` time steps (all persons) clean, leading duplicates pruned."""
    length = window * persons
    levels = level_table(steps)[index_matrix(kind, steps, length, group, offset_proportion)]
    levels[:, : context_tokens * persons] = CLEAN
    return prune(levels) if do_prune else levels


def ar_matrix(first: np.ndarray, new_flat: int) -> np.ndarray:
    """The matrix of every later AR window (§4.3): from the first row whose first newly generated
    column is no longer pure noise (one row earlier), every column but the last `new_flat` clean."""
    length = first.shape[1]
    col = length - new_flat
    r0 = next((r for r in range(first.shape[0]) if first[r, col] != PURE_NOISE), first.shape[0] - 1)
    # r0 = 0 gives Python's first[-1:], the last row alone.
    out = first[r0 - 1 :].copy() if r0 > 0 else first[-1:].copy()
    out[:, :col] = CLEAN
    return out


def window_levels(row: np.ndarray, persons: int) -> np.ndarray:
    """A matrix row as [T, P] levels."""
    return row.reshape(-1, persons)
