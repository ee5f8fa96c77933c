"""The link panel names the board it talks to, as the board's Hello said: id, firmware and protocol version, in
its bottom border (the panel's rows are all taken by the two links), whole at the smallest screen too. Through the
app (Pilot) over a real pty to the real board (fcb_sim's Board served in real time on a thread)."""

from __future__ import annotations

import asyncio

import pytest

from fcb_sim.board.board import BOARD_VERSION, Board, BoardConfig
from fcb_sim.hosts.serve import ThreadedServer
from term.core.protocol import PROTOCOL_VERSION
from term.transports.serial import SerialTransport
from term.ui.app import TermApp

VERSION = f"fw {BOARD_VERSION[0]}.{BOARD_VERSION[1]} · protocol v{PROTOCOL_VERSION}"


@pytest.mark.parametrize(("size", "shown"), [((160, 50), f"board 7 · {VERSION}"), ((80, 24), f"board 7 · {VERSION}")])
async def test_the_link_panel_shows_the_boards_version(size: tuple[int, int], shown: str) -> None:
    server = ThreadedServer(Board(BoardConfig(seed=1, board_id=7)))
    port = server.start()
    try:
        app = TermApp(SerialTransport(port), joystick=False)
        async with app.run_test(size=size) as pilot:
            async with asyncio.timeout(10.0):
                while app.model.hello is None:
                    await pilot.pause(0.02)
            app.render_now()
            await pilot.pause(0.05)
            assert str(app.screen.query_one("#link").border_subtitle) == shown
            assert shown in app.export_screenshot().replace("&#160;", " ")  # drawn whole, not cut off
    finally:
        server.stop()


async def test_no_board_no_version() -> None:
    app = TermApp(joystick=False)  # nothing connected: no Hello, so nothing is made up
    async with app.run_test(size=(160, 50)) as pilot:
        app.render_now()
        await pilot.pause(0.05)
        assert not app.screen.query_one("#link").border_subtitle
