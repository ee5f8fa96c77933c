"""term flies the C board: TermApp over term's own serial transport on the pseudo-terminal `fcb-sim serve --pty
--board c` serves in its own process (the C board in fcb_sim's physics, in real time), as `term --sim --board c`
starts it. Calibrate, MANUAL, lift trims and the SAFE refusal with the board's reason, FULL, HEIGHT, PANIC walking
back to SAFE; the flight logged and its log downloaded (F2, F3, F5), the task profile (F6). On a starved machine the
pilot presses a key again when nothing happened, as a pilot would."""

from __future__ import annotations

import asyncio
import csv
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from fcb_sim.hosts.cboard import library_path
from term.core.protocol import LIFT_ZERO, NAK_TEXT, PROTOCOL_VERSION, Mode, Nak, Role
from term.session.sim import SimBoard
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from tests.support.waits import until

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make: the C board's tests are skipped")


async def test_term_flies_the_c_board_in_the_simulator(tmp_path: Path) -> None:
    library_path()  # built here, not inside the simulator's start-up time
    sim = SimBoard(seed=3, extra=["--board", "c"])
    path = sim.start()
    try:
        app = TermApp(SerialTransport(path), joystick=False, log_directory=tmp_path)
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            def texts() -> list[str]:
                return [e.text for e in m.events]

            async def until_said(cond: Callable[[], bool], timeout: float = 30.0) -> None:
                """until, naming the events when it times out (what the C board said, or did not)."""
                try:
                    await until(pilot, cond, timeout)
                except TimeoutError:
                    raise AssertionError(f"waited {timeout} s; the events: {texts()}") from None

            def naks() -> list[str]:
                return [e.text for e in m.events if e.source == "nak"]

            async def press(key: str, cond) -> None:  # noqa: ANN001
                """A pilot's key press, again while nothing happens (a starved machine: term gave the command
                up as the link stalled)."""
                for _ in range(6):
                    app.simulate_key(key)
                    try:
                        async with asyncio.timeout(5.0):
                            while not cond():
                                await pilot.pause(0.02)
                        return
                    except TimeoutError:
                        continue
                raise AssertionError(f"key {key}: nothing happened; the events: {texts()}")

            await until_said(lambda: m.hello is not None and m.mode == Mode.SAFE)
            await press("f2", lambda: m.status is not None and m.status.log_fill > 0)  # the whole flight logged
            assert (m.hello.protocol, m.hello.role, m.hello.major) == (PROTOCOL_VERSION, Role.BOARD, 0)
            await press("3", lambda: any("CALIBRATION → SAFE" in t for t in texts()))
            await press("2", lambda: m.mode == Mode.MANUAL)
            # two steps of lift trim (1 % each): more than what counts as zero lift (LIFT_ZERO)
            await press("a", lambda: m.status is not None and m.status.trim_lift > 0)
            await press("a", lambda: m.status is not None and m.status.trim_lift > LIFT_ZERO)
            lift_nak = f"NAK mode SAFE: {NAK_TEXT[Nak.LIFT_NOT_ZERO]}"
            await press("0", lambda: lift_nak in naks())  # the lift trim is not zero: refused, with the reason
            await press("z", lambda: m.status is not None and 0 < m.status.trim_lift <= LIFT_ZERO)
            await press("z", lambda: m.status is not None and m.status.trim_lift == 0)
            await press("0", lambda: m.mode == Mode.SAFE)
            await press("5", lambda: m.mode == Mode.FULL)
            await press("7", lambda: m.mode == Mode.HEIGHT)
            await press("1", lambda: any("→ PANIC" in t for t in texts()))
            await until_said(lambda: any("PANIC → SAFE" in t for t in texts()) and m.mode == Mode.SAFE)
            assert set(naks()) == {lift_nak}
            assert sum("→ PANIC" in t for t in texts()) == 1, texts()  # key 1's: no failsafe PANIC on the way
            app.simulate_key("f3")
            await pilot.pause(0.3)
            await press("f5", lambda: m.download is not None or m.download_note.startswith("log saved"))
            await until(pilot, lambda: m.download_note.startswith(("log saved", "log download")), 60.0)
            assert m.download_note.startswith("log saved"), m.download_note
            (saved,) = tmp_path.glob("quadrupel-log-*.csv")
            with saved.open() as f:
                rows = list(csv.reader(f))
            modes = {int(r[2]) for r in rows[1:]}
            assert rows[0][:3] == ["segment", "t_us", "mode"] and len(rows) > 500  # about 5 s of flight
            assert {Mode.SAFE, Mode.MANUAL, Mode.FULL, Mode.HEIGHT, Mode.PANIC} <= modes
            await press("f6", lambda: len(m.profiles) == 7)  # the profile: every task, its period the board's
            assert 4900 < m.profiles[2].period_us < 5100 and m.profiles[5].period_us > 90_000
    finally:
        sim.stop()
