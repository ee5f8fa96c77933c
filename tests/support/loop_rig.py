"""The app on a loopback link with the scripted board (tests/conftest.py) at the other end, on the test's loop:
``flying(scripted_board)`` gives (app, pilot, board, peer); ``peer.write(raw)`` puts any bytes on the board's side
of the wire (text between frames, damaged frames); ``until`` waits on a condition with a bound."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

from term.transports.base import TransportClosed, TransportError
from term.transports.loopback import loopback_pair
from term.ui.app import TermApp
from tests.support.waits import until


class LoopBoard:
    """Runs a ScriptedBoard on the board's end of a loopback pair (reads, replies, heartbeats)."""

    def __init__(self, transport: Any, board: Any, clock: Callable[[], float]) -> None:
        self.t, self.board, self.clock = transport, board, clock
        self.tasks: list[asyncio.Task[None]] = []

    async def start(self) -> None:
        await self.t.open()
        self.tasks = [asyncio.create_task(self._read()), asyncio.create_task(self._tick())]

    async def _read(self) -> None:
        while True:
            try:
                data = await self.t.read()
                reply = self.board.receive(data, self.clock())
                if reply:
                    await self.t.write(reply)
            except TransportClosed:
                return
            except TransportError:
                await asyncio.sleep(0.01)

    async def _tick(self) -> None:
        while True:
            out = self.board.tick(self.clock())
            if out:
                with contextlib.suppress(TransportError):
                    await self.t.write(out)
            await asyncio.sleep(max(0.001, self.board.next_deadline() - self.clock()))

    async def send(self, *pkts: object) -> None:
        await self.t.write(self.board.encoder.encode_many(pkts))

    async def write(self, raw: bytes) -> None:
        await self.t.write(raw)

    async def stop(self) -> None:
        for t in self.tasks:
            t.cancel()
        for t in self.tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await t


@contextlib.asynccontextmanager
async def flying(scripted_board: Any, size: tuple[int, int] = (120, 44), link_timeout: float = 3.0,
                 **board_kw: Any) -> AsyncIterator[tuple[Any, Any, Any, LoopBoard]]:
    pair = loopback_pair()
    board = scripted_board(start=time.monotonic(), **board_kw)
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    app = TermApp(pair.a, joystick=False, session_options={"link_timeout": link_timeout})
    try:
        async with app.run_test(size=size) as pilot:
            await until(pilot, lambda: board.hellos)
            yield app, pilot, board, peer
    finally:
        await peer.stop()
