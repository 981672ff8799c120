"""What one stream and one client may cost a service: the operator's limits (docs/SERVING.md).

A gateway serves many tenants on shared workers, so a client must not be able to buy more than
its share with valid but heavy options (`steps`, `cfg`, `capacity`), with many streams, or by
never reading. `Limits` holds the operator's bounds; the gateway checks the static ones when a
stream opens (refused with a message naming the limit, nothing reaches a worker) and the worker
enforces the compute budget on every token it measures.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any


@dataclass(frozen=True)
class Limits:
    """The bounds a service applies to its clients. `None` lifts a bound.

    The defaults suit the demo model on one-CPU workers; set them for your model and machines
    (`python -m troupe.serve --help` lists the flags).
    """

    max_steps: int | None = 8
    """Solver steps per token a stream may ask for (`steps`); a token costs about that many
    network calls."""
    max_cfg: float | None = 10.0
    """Largest classifier-free guidance scale (`cfg`) a stream may ask for."""
    max_capacity: int | None = 4096
    """Most tokens a stream's context cache may keep (`capacity`): memory and attention time."""
    token_budget_ms: float | None = 50.0
    """Compute one token may take on its worker for a stream that chose its own `steps` or
    `cfg`, measured on every step. Such a stream over it for `budget_strikes` tokens in a row is
    ended with an error naming the budget. (Streams on the model's own settings are not charged:
    their cost is the model's, which the operator chose.)"""
    budget_strikes: int = 3
    """Tokens in a row over `token_budget_ms` before a stream is ended (one slow token, a page
    of cache growing, is not a fault)."""
    max_streams_per_worker: int | None = 256
    """Streams one worker holds; a new stream is refused when every worker is full."""
    max_streams_per_client: int | None = 32
    """Streams one client (one remote address, or `Gateway.client_of`) may hold at once."""
    slow_reader_s: float | None = 5.0
    """Seconds an acknowledgement may wait for a client that does not read before the
    connection is dropped (its stream is detached and expires as a dropped connection's does)."""
    idle_s: float | None = 120.0
    """Seconds a connection may send nothing before it is closed."""

    @classmethod
    def unlimited(cls) -> "Limits":
        """No bound at all: what the gateway did before it had limits (for measurements)."""
        return cls(max_steps=None, max_cfg=None, max_capacity=None, token_budget_ms=None,
                   max_streams_per_worker=None, max_streams_per_client=None, slow_reader_s=None, idle_s=None)

    def with_(self, **changes: Any) -> "Limits":
        """A copy with some bounds changed."""
        return replace(self, **changes)

    def check_open(self, options: dict) -> None:
        """Refuses stream options beyond the static bounds (ValueError naming the limit)."""
        steps, cfg, capacity = options.get("steps"), options.get("cfg"), options.get("capacity")
        if self.max_steps is not None and steps is not None and steps > self.max_steps:
            raise ValueError(f"steps {steps} is above this service's limit of {self.max_steps}")
        if self.max_cfg is not None and cfg is not None and abs(cfg) > self.max_cfg:
            raise ValueError(f"cfg {cfg} is above this service's limit of {self.max_cfg}")
        if self.max_capacity is not None and capacity is not None and capacity > self.max_capacity:
            raise ValueError(f"capacity {capacity} is above this service's limit of {self.max_capacity}")


class BudgetExceeded(RuntimeError):
    """A stream's tokens took more compute than the service's per-token budget, several in a
    row; the stream is ended."""


def one_line(error: BaseException) -> str:
    """An error as one line: its last line (a Ray error carries the remote traceback before
    it), or its type when it has no text."""
    text = str(error).strip()
    return text.splitlines()[-1] if text else type(error).__name__
