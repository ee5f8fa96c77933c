"""Signals in flight take the Ctrl+Q path (issue 34): SIGTERM, SIGHUP and SIGINT while the motors run send PANIC to
the board first, then term quits, with 128 + the signal's number (SIGINT: 130). The real app (Textual's Pilot),
term's SerialTransport and the simulated board served in real time on a pseudo-terminal, in this process so the
test reads the board's own mode; the signal is a real one, sent to this process with term's handlers in place."""

from __future__ import annotations

import asyncio
import contextvars
import os
import signal
import sys

import pytest

from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.cli import signals as cli
from term.core.protocol import Mode
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from tests.support.waits import until

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="sends POSIX signals")


@pytest.fixture(autouse=True)
def _no_forced_end(monkeypatch: pytest.MonkeyPatch) -> object:
    """The watchdog that ends a hung exit would end pytest too: here it only says it was needed (a failure)."""
    forced: list[int] = []
    monkeypatch.setattr(cli, "_end_now", forced.append)
    yield
    assert not forced, f"the orderly exit hung: the watchdog ended term with {forced}"


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


class _Kernel32:
    """A stand-in for Windows' kernel32: SetConsoleCtrlHandler keeps the routine the system would call."""

    def __init__(self) -> None:
        self.routines: list[object] = []
        kernel = self

        class Setter:
            argtypes: object = None
            restype: object = None

            def __call__(self, routine: object, add: bool) -> int:
                if add:
                    kernel.routines.append(routine)
                else:
                    kernel.routines.remove(routine)
                return 1

        self.SetConsoleCtrlHandler = Setter()


async def test_the_console_window_closed_in_flight_sends_panic_first() -> None:
    """Windows' CTRL_CLOSE_EVENT (the console window closed), as the system calls the handler: on its own thread,
    which it holds until the orderly exit is done. Ctrl+C's event is left to the next handler (Python's)."""
    import threading

    board = make_board(seed=2)
    served = ThreadedServer(board)
    port = served.start()
    app = TermApp(SerialTransport(port), joystick=False)
    kernel32 = _Kernel32()
    answers: list[int] = []
    try:
        with cli._terminate_on_signals():
            console = cli._ConsoleHandler(kernel32)
            assert console.installed and kernel32.routines == [console.routine]
            async with app.run_test(size=(120, 40)) as pilot:
                cli._running[:] = [(app, asyncio.get_running_loop())]
                await until(pilot, lambda: app.model.mode == Mode.SAFE and board.mode == Mode.SAFE)
                await pilot.press("2")
                await until(pilot, lambda: board.mode == Mode.MANUAL and app.model.mode == Mode.MANUAL)
                assert console.routine(0) == 0  # CTRL_C_EVENT: not ours
                system = threading.Thread(target=lambda: answers.append(console.routine(2)))  # CTRL_CLOSE_EVENT
                system.start()
                await until(pilot, lambda: not app.is_running)
                assert board.mode == Mode.PANIC
            console.remove()
    finally:
        cli._running.clear()
        served.stop()
    system.join(10)
    assert answers == [1] and kernel32.routines == []
    assert app.return_code == 129 and app.exit_message.startswith("PANIC sent before quitting")


async def test_the_terminal_hung_up_in_flight_sends_panic_first() -> None:
    """The watcher (no SIGHUP reached term) sees the terminal hang up while the motors run: PANIC first, then 129."""
    if not hasattr(os, "openpty"):
        pytest.skip("needs a pseudo-terminal for a terminal to hang up")
    master, slave = os.openpty()
    board = make_board(seed=2)
    served = ThreadedServer(board)
    port = served.start()
    app = TermApp(SerialTransport(port), joystick=False)
    try:
        with cli._terminate_on_signals(), open(slave, closefd=False) as terminal:
            async with app.run_test(size=(120, 40)) as pilot:
                cli._running[:] = [(app, asyncio.get_running_loop())]
                # (in a context of its own, as term/cli/main.py starts it before the app runs: not the app's)
                watcher = asyncio.create_task(cli._exit_on_hangup(terminal, period=0.05), context=contextvars.Context())
                await until(pilot, lambda: app.model.mode == Mode.SAFE and board.mode == Mode.SAFE)
                await pilot.press("2")
                await until(pilot, lambda: board.mode == Mode.MANUAL and app.model.mode == Mode.MANUAL)
                os.close(master)  # the terminal goes away
                master = -1
                await until(pilot, lambda: not app.is_running)
                assert board.mode == Mode.PANIC and watcher.done()
    finally:
        cli._running.clear()
        served.stop()
        os.close(slave)
        if master >= 0:
            os.close(master)
    assert app.return_code == 129 and app.exit_message.startswith("PANIC sent before quitting")
