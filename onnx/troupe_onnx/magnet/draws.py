"""Where MAGNet's samplers get their standard normals, in the order of `docs/spec/magnet.md`
§3.5. `SeededDraws` is troupe's portable generator (draw i of a run is Philox normals for token
i of stream `STREAM_MAGNET`, so the Rust runtime regenerates them bit for bit); `TorchDraws`
is `torch.randn` (the official code's generator, for benchmarks); `RecordingDraws` keeps what
it hands out, for goldens."""

from __future__ import annotations

import numpy as np

from troupe_onnx.shared.noise import philox_normals

STREAM_MAGNET = 8  # troupe's Philox stream for MAGNet's draws (other families use 0..4)


class SeededDraws:
    def __init__(self, seed: int):
        self.seed, self.count = seed, 0

    def normal(self, shape: tuple) -> np.ndarray:
        n = int(np.prod(shape))
        out = philox_normals(self.seed, self.count, STREAM_MAGNET, n).reshape(shape)
        self.count += 1
        return out


class TorchDraws:
    def __init__(self, seed: int):
        import torch

        self.generator = torch.Generator().manual_seed(seed)
        self.count = 0

    def normal(self, shape: tuple) -> np.ndarray:
        import torch

        self.count += 1
        return torch.randn(shape, generator=self.generator).numpy()


class RecordingDraws:
    """Hands out another source's draws and keeps their shapes (the call inventory)."""

    def __init__(self, inner):
        self.inner, self.shapes = inner, []

    @property
    def count(self) -> int:
        return len(self.shapes)

    def normal(self, shape: tuple) -> np.ndarray:
        self.shapes.append(tuple(shape))
        return self.inner.normal(shape)
