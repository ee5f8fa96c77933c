"""The real app with the simulator's instructor channel, as `term --sim` wires it: the board served in real time in
this process (fcb_sim.hosts.serve's ThreadedServer: a test can read the world) with its instructor on a local TCP
port, and term's SerialTransport, InstructorClient and TermApp (copied from tests/test_lesson_app.py's rig)."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any

from fcb_sim.hosts.instructor import Instructor, InstructorServer
from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.lessons.instructor import InstructorClient
from term.transports.serial import SerialTransport
from term.ui.app import TermApp


@contextlib.asynccontextmanager
async def sim_app(seed: int = 3, size: tuple[int, int] = (120, 44),
                  **app_kw: object) -> AsyncIterator[tuple[TermApp, Any, Any]]:
    """The board served in real time with its instructor channel, and the app connected to both."""
    board = make_board(seed=seed)
    served = ThreadedServer(board)
    port = served.start()
    inst = Instructor(board)
    server = InstructorServer(inst)
    loop = served._loop
    assert loop is not None
    address = asyncio.run_coroutine_threadsafe(server.start("tcp-server:127.0.0.1:0"), loop).result(5)
    served.server.cable_open = lambda: inst.cable_open(board.now / 1e6)
    client = InstructorClient(address)
    await client.open()
    app = TermApp(SerialTransport(port), instructor=client, **{"joystick": False, **app_kw})  # type: ignore[arg-type]
    try:
        async with app.run_test(size=size) as pilot:
            yield app, pilot, board
    finally:
        await client.close()
        asyncio.run_coroutine_threadsafe(server.close(), loop).result(5)
        served.stop()


