"""The motor test screen through Textual's Pilot: against the real boards (`fcb-sim serve --pty`, the Python board
and the C board) a motor turns in the motors panel after "props off?", the board's qb_log line is on the console,
any key stops it, and (on the Python board: both boards' limit is tests/board/test_motortest.py's) it stops by itself;
against the scripted board on a loopback link: refused out of SAFE, stopped on leaving the screen and on link loss,
the pilot's keys spent on the screen, not on the craft."""

from __future__ import annotations

import asyncio
import shutil

import pytest

from term.core.protocol import Attitude, Mode, Op, motor_test_arg
from term.session.sim import SimBoard
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from term.ui.screens.confirm import ConfirmScreen
from term.ui.screens.motortest import DEFAULT_LEVEL, LEVEL_STEP, MotorTestScreen
from term.ui.widgets.motors import MotorBars
from tests.support.app_rig import flying
from tests.support.waits import until


def _sent(board) -> list[tuple[int, int]]:  # noqa: ANN001
    return [(c.op, c.arg) for c in board.executed if c.op == Op.MOTOR_TEST]


async def _open(app, pilot) -> None:  # noqa: ANN001
    await pilot.press("ctrl+o")
    await until(pilot, lambda: isinstance(app.screen, ConfirmScreen))
    await pilot.click("#yes")
    await until(pilot, lambda: isinstance(app.screen, MotorTestScreen))


async def _safe(app, pilot, peer) -> None:  # noqa: ANN001
    await peer.send(Attitude(int(Mode.SAFE), 0, 0, 0, 0, 0, 0))
    await until(pilot, lambda: app.model.mode == Mode.SAFE)


@pytest.mark.parametrize("board", ["python", "c"])
async def test_a_motor_spins_on_the_real_board_and_any_key_stops_it(board: str) -> None:
    extra = []
    if board == "c":
        if shutil.which("cc") is None or shutil.which("make") is None:
            pytest.skip("no C compiler")
        from fcb_sim.hosts.cboard import library_path

        library_path()
        extra = ["--board", "c"]
    sim = SimBoard(seed=3, extra=extra)
    path = sim.start()
    try:
        app = TermApp(SerialTransport(path), joystick=False)
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model
            await until(pilot, lambda: m.hello is not None and m.mode == Mode.SAFE, 30)
            await _open(app, pilot)
            app.simulate_key("2")
            app.simulate_key("plus")
            await pilot.pause(0.05)
            app.simulate_key("enter")
            level = DEFAULT_LEVEL + LEVEL_STEP
            await until(pilot, lambda: m.motion is not None and m.motion.ae2 == level, 10)
            assert (m.motion.ae1, m.motion.ae3, m.motion.ae4) == (0, 0, 0) and m.mode == Mode.SAFE
            bars = app.screen.query_one(MotorBars)
            await until(pilot, lambda: f"{level:4d}" in str(bars.render()))  # the motors panel shows it
            await until(pilot, lambda: any(line.text == f"motor test: mask 2 at {level} for 3000 ms"
                                           for _, line in m.console), 10)  # the board's qb_log, on the console
            app.simulate_key("x")  # any key
            await until(pilot, lambda: m.motion.ae2 == 0, 10)
            await until(pilot, lambda: any(e.text.endswith("motor test ended: stopped") for e in m.events), 10)
            assert not app.motortest.running and isinstance(app.screen, MotorTestScreen)
            if board == "c":
                return  # the C board's own 3 s limit: tests/board/test_motortest.py, on the simulated clock
            app.simulate_key("enter")  # again: it stops by itself (what the screen makes of the board's own stop)
            await until(pilot, lambda: m.motion.ae2 == level, 10)
            await until(pilot, lambda: any(e.text.endswith("motor test ended: time up") for e in m.events), 10)
            await until(pilot, lambda: m.motion.ae2 == 0 and not app.motortest.running, 10)
    finally:
        sim.stop()


async def test_refused_out_of_safe(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await peer.send(Attitude(int(Mode.MANUAL), 0, 0, 0, 0, 0, 0))
        await until(pilot, lambda: app.model.mode == Mode.MANUAL)
        await pilot.press("ctrl+o")
        assert not isinstance(app.screen, (ConfirmScreen, MotorTestScreen))
        assert any("motor test: only in SAFE" in e.text for e in app.model.events)


async def test_cancel_at_props_off_sends_nothing(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await _safe(app, pilot, peer)
        await pilot.press("ctrl+o")
        await until(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.click("#no")
        await until(pilot, lambda: not isinstance(app.screen, ConfirmScreen))
        assert not isinstance(app.screen, MotorTestScreen) and not _sent(board)


async def test_keys_on_the_screen_are_its_own_and_any_key_stops(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await _safe(app, pilot, peer)
        await _open(app, pilot)
        await pilot.press("a", "minus", "enter")
        want = (int(Op.MOTOR_TEST), motor_test_arg(0xF, DEFAULT_LEVEL - LEVEL_STEP))
        await until(pilot, lambda: want in _sent(board))
        assert app.motortest.running
        await pilot.press("3")  # a mode key elsewhere: here it stops the test, and is spent on that
        await until(pilot, lambda: (int(Op.MOTOR_TEST), 0) in _sent(board))
        assert not app.motortest.running
        assert all(c.op == Op.MOTOR_TEST for c in board.executed if c.op not in (Op.PARAM_LIST,)), board.executed


async def test_leaving_the_screen_stops_it(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await _safe(app, pilot, peer)
        await _open(app, pilot)
        await pilot.press("enter")
        await until(pilot, lambda: app.motortest.running and _sent(board))
        app.show_screen("flight")  # not by a key (the phone, the palette): the screen goes, the test with it
        await until(pilot, lambda: (int(Op.MOTOR_TEST), 0) in _sent(board))
        assert not app.motortest.running
        assert any("left the motor test screen" in e.text for e in app.model.events)


async def test_link_loss_ends_it_here(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, link_timeout=0.5) as (app, pilot, board, peer):
        await _safe(app, pilot, peer)
        await _open(app, pilot)
        await pilot.press("enter")
        await until(pilot, lambda: app.motortest.running and _sent(board))
        board.silent = True  # the board (or the cable) went quiet
        await until(pilot, lambda: not app.motortest.running)
        assert "link lost" in app.motortest.last_end
        await asyncio.sleep(0)


async def test_a_refusal_by_the_board_ends_it_here(scripted_board) -> None:  # noqa: ANN001
    from term.core.protocol import Nak

    nak = lambda c: Nak.LIFT_NOT_ZERO if c.op == Op.MOTOR_TEST else Nak.OK  # noqa: E731
    async with flying(scripted_board, nak=nak) as (app, pilot, board, peer):
        await _safe(app, pilot, peer)
        await _open(app, pilot)
        await pilot.press("enter")
        await until(pilot, lambda: _sent(board))
        await until(pilot, lambda: not app.motortest.running)
        assert "lift not at zero" in app.motortest.last_end
