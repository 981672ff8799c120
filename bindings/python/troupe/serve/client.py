"""A client of the gateway: sends actor tokens, receives one acknowledgement per token, and keeps
every token not yet acknowledged so that it can send them again when the gateway asks (`resume`).

    async with StreamClient("ws://127.0.0.1:8765", {"condition": "mirror"}) as stream:
        index = await stream.send(actor_frames)          # float32 [frames_per_token, frame_dim]
        token, reactor_frames = await stream.receive()   # acknowledgements come in token order
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import protocol


class ServerError(RuntimeError):
    """The gateway refused the stream or a message (its `error`)."""


class StreamClient:
    def __init__(self, url: str, options: dict | None = None, stream: str | None = None,
                 local_address: str | None = None):
        self.url = url
        self.local_address = local_address  # the address to connect from (tests: one per client)
        self.options = options or {}
        self.stream = stream  # set to re-attach to a stream after a dropped connection
        self.ws: Any = None
        self.frame_dim = 0
        self.frames_per_token = 0
        self.next_token = 0  # index of the next token `send` numbers
        self.unacked: dict[int, np.ndarray] = {}  # sent, not yet acknowledged
        self.resumes = 0  # times the gateway asked for tokens again

    async def __aenter__(self) -> "StreamClient":
        from websockets.asyncio.client import connect

        extra: dict[str, Any] = {"local_addr": (self.local_address, 0)} if self.local_address else {}
        self.ws = await connect(self.url, max_size=2**24, compression=None, **extra)
        opening = {"stream": self.stream} if self.stream else {"options": self.options}
        await self.ws.send(protocol.encode_control("open", **opening))
        ready = self._control(await self.ws.recv())
        if ready["type"] != "ready":
            raise ServerError(f"expected `ready`, got {ready}")
        self.stream, self.frame_dim, self.frames_per_token = ready["stream"], ready["frame_dim"], ready["frames_per_token"]
        if self.stream is not None and ready["next_token"] != self.next_token:
            await self._resend(ready["next_token"])
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    def _control(self, message: str) -> dict:
        value = protocol.decode_control(message)
        if value["type"] == "error":
            raise ServerError(value.get("message", "error"))
        return value

    async def send(self, frames: np.ndarray) -> int:
        """Sends one token of actor frames; returns its index."""
        index = self.next_token
        frames = np.ascontiguousarray(frames, dtype=np.float32)
        self.unacked[index] = frames
        self.next_token += 1
        await self.ws.send(protocol.encode_token(index, frames))
        return index

    async def _resend(self, start: int) -> None:
        for index in sorted(i for i in self.unacked if i >= start):
            await self.ws.send(protocol.encode_token(index, self.unacked[index]))

    async def receive(self) -> tuple[int, np.ndarray]:
        """The next acknowledgement: a token's index and the reactor frames it produced. A
        `resume` from the gateway is answered here (the tokens from its index sent again)."""
        while True:
            message = await self.ws.recv()
            if isinstance(message, bytes):
                index, frames = protocol.decode_token(message, self.frame_dim)
                self.unacked.pop(index, None)
                return index, frames
            control = self._control(message)
            if control["type"] == "resume":
                self.resumes += 1
                await self._resend(control["next_token"])
            else:
                raise ServerError(f"unexpected message {control}")

    async def close(self) -> None:
        if self.ws is not None:
            try:
                await self.ws.send(protocol.encode_control("close"))
            except Exception:  # already closed
                pass
            await self.ws.close()
            self.ws = None

