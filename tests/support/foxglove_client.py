"""A client of Foxglove's WebSocket protocol (ws-protocol, subprotocol ``foxglove.sdk.v1``), written from the spec
with the ``websockets`` package: a reader the project does not share code with, for tests and bench.foxglove.

It takes the server's ``advertise``, subscribes to the topics asked for (all if none), and keeps every
``MessageData`` frame (opcode 1: subscription id u32, log time u64 ns, payload) with the wall time it arrived.
"""

from __future__ import annotations

import asyncio
import json
import struct
import time
from dataclasses import dataclass, field
from typing import Any

import websockets

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]  # the SDK's name for it, and the older one
MESSAGE_DATA = 1


@dataclass
class Received:
    topic: str
    log_time: int  # ns, the server's stamp
    arrived: int  # ns, this client's wall clock when the frame was read
    payload: bytes

    def json(self) -> Any:
        return json.loads(self.payload)


@dataclass
class Client:
    url: str
    topics: tuple[str, ...] = ()  # subscribe to these (all if empty) as they are advertised
    channels: dict[int, dict[str, Any]] = field(default_factory=dict)
    received: list[Received] = field(default_factory=list)
    server_info: dict[str, Any] = field(default_factory=dict)
    _subs: dict[int, str] = field(default_factory=dict)
    retries: int = 0  # connections tried again (``run``'s tries)

    async def run(self, stop: asyncio.Event, tries: int = 1) -> None:
        """Connect, subscribe and collect until ``stop`` is set. ``tries``: connections to try (as Foxglove's app
        reconnects by itself) while one ends before its handshake, as a door under a flood may end it."""
        for left in range(tries - 1, -1, -1):
            try:
                await self._run(stop)
                return
            except (OSError, websockets.exceptions.InvalidHandshake, websockets.exceptions.ConnectionClosed):
                if left == 0 or self.server_info:
                    raise
                self.retries += 1

    async def _run(self, stop: asyncio.Event) -> None:
        async with websockets.connect(self.url, subprotocols=SUBPROTOCOLS,  # type: ignore[arg-type]
                                      max_size=None) as ws:
            while not stop.is_set():
                try:
                    msg = await asyncio.wait_for(ws.recv(), 0.1)
                except TimeoutError:
                    continue
                if isinstance(msg, bytes):
                    self._data(msg)
                else:
                    await self._control(ws, json.loads(msg))

    def _data(self, msg: bytes) -> None:
        arrived = time.time_ns()
        if msg[0] != MESSAGE_DATA:
            return
        sub, log_time = struct.unpack_from("<IQ", msg, 1)
        self.received.append(Received(self._subs.get(sub, "?"), log_time, arrived, msg[13:]))

    async def _control(self, ws: Any, d: dict[str, Any]) -> None:
        if d.get("op") == "serverInfo":
            self.server_info = d
        elif d.get("op") == "advertise":
            new = []
            for ch in d["channels"]:
                self.channels[ch["id"]] = ch
                if not self.topics or ch["topic"] in self.topics:
                    sub = len(self._subs) + 1
                    self._subs[sub] = ch["topic"]
                    new.append({"id": sub, "channelId": ch["id"]})
            if new:
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))

    def on(self, topic: str) -> list[Received]:
        return [r for r in self.received if r.topic == topic]
