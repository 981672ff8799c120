"""The wire protocol between a client and the gateway: one WebSocket per stream.

Text messages are JSON objects with a `type`; binary messages carry one token of frames:

    client -> gateway   {"type": "open", "options": {...}}            a new stream
                        {"type": "open", "stream": ID}                 re-attach to a stream after a
                                                                       dropped connection
                        binary: token index (u64 LE) + float32 [frames_per_token, frame_dim]
                        {"type": "close"}
    gateway -> client   {"type": "ready", "stream": ID, "next_token": K, "frame_dim": D,
                         "frames_per_token": F}
                        binary: token index (u64 LE) + float32 [m, frame_dim]   the token's
                                                                       acknowledgement: the reactor
                                                                       frames it produced (m >= 0)
                        {"type": "resume", "next_token": K}            the stream moved: send again
                                                                       every token from K on
                        {"type": "error", "message": "..."}

Exactly once: the gateway takes token K only when K tokens are acknowledged; an earlier index is a
copy (dropped), a later one is refused unless a `resume` asked the client to send again from K.
"""

from __future__ import annotations

import json
import struct
from typing import Any

import numpy as np

TOKEN_HEADER = struct.Struct("<Q")


def encode_token(index: int, frames: np.ndarray) -> bytes:
    """A binary message: the token index, then the frames as little-endian float32."""
    body = np.ascontiguousarray(frames, dtype="<f4")
    return TOKEN_HEADER.pack(index) + body.tobytes()


def decode_token(message: bytes, frame_dim: int) -> tuple[int, np.ndarray]:
    """Index and frames of a binary message; ValueError if it is not whole frames."""
    if len(message) < TOKEN_HEADER.size:
        raise ValueError(f"a token message is at least {TOKEN_HEADER.size} bytes, got {len(message)}")
    (index,) = TOKEN_HEADER.unpack_from(message)
    body = memoryview(message)[TOKEN_HEADER.size:]
    if len(body) % (4 * frame_dim):
        raise ValueError(f"a token's frames are float32 [n, {frame_dim}]: {len(body)} bytes is not whole frames")
    frames = np.frombuffer(body, dtype="<f4").reshape(-1, frame_dim).astype(np.float32, copy=False)
    return index, frames


def encode_control(kind: str, **fields: Any) -> str:
    return json.dumps({"type": kind, **fields})


def decode_control(message: str | bytes) -> dict:
    """A text message as a dict with a string `type`; ValueError otherwise."""
    if not isinstance(message, str):
        raise ValueError("expected a text message (a JSON object), got a binary one")
    try:
        value = json.loads(message)
    except json.JSONDecodeError as e:
        raise ValueError(f"a text message is a JSON object: {e}") from None
    if not isinstance(value, dict) or not isinstance(value.get("type"), str):
        raise ValueError("a text message is a JSON object with a string `type`")
    return value
