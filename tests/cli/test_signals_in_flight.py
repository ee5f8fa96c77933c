"""Signals in flight take the Ctrl+Q path (issue 34): SIGTERM, SIGHUP and SIGINT while the motors run send PANIC to
the board first, then term quits, with 128 + the signal's number (SIGINT: 130). The real app (Textual's Pilot),
term's SerialTransport and the simulated board served in real time on a pseudo-terminal, in this process so the
test reads the board's own mode; the signal is a real one, sent to this process with term's handlers in place."""

from __future__ import annotations

import asyncio
import os
import signal
import sys
from collections.abc import Callable

import pytest

from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.cli import signals as cli
from term.core.protocol import Mode
from term.transports.serial import SerialTransport
from term.ui.app import TermApp

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="sends POSIX signals")


async def until(pilot: object, cond: Callable[[], bool], timeout: float = 20.0) -> None:
    async with asyncio.timeout(timeout):
        while not cond():
            await pilot.pause(0.05)  # type: ignore[attr-defined]


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP", "SIGINT"])
async def test_a_signal_in_flight_sends_panic_first_then_quits(name: str) -> None:
    signum = getattr(signal, name)
    board = make_board(seed=2)
    served = ThreadedServer(board)
    port = served.start()
    app = TermApp(SerialTransport(port), joystick=False)
    try:
        with cli._terminate_on_signals():
            async with app.run_test(size=(120, 40)) as pilot:
                cli._running[:] = [(app, asyncio.get_running_loop())]
                await until(pilot, lambda: app.model.mode == Mode.SAFE and board.mode == Mode.SAFE)
                await pilot.press("2")  # MANUAL: the motors are the pilot's
                await until(pilot, lambda: board.mode == Mode.MANUAL and app.model.mode == Mode.MANUAL)
                os.kill(os.getpid(), signum)
                await until(pilot, lambda: not app.is_running)
                assert board.mode == Mode.PANIC, f"{name}: the board is in {board.mode.name}, not PANIC"
    finally:
        cli._running.clear()
        served.stop()
    assert app.return_code == 128 + signum  # SIGINT: 130
    assert app.exit_message is not None and app.exit_message.startswith("PANIC sent before quitting")
