"""term flies the C board: TermApp over term's own serial transport on the pseudo-terminal `fcb-sim serve --pty
--board c` serves (the C board in fcb_sim's physics, in real time). Calibrate, MANUAL, lift trims and the SAFE
refusal with the board's reason, FULL, HEIGHT, PANIC walking back to SAFE, the parameters read back."""

from __future__ import annotations

import asyncio
import shutil

import pytest

from fcb_sim.serve import ThreadedServer, make_board
from term.core.protocol import NAK_TEXT, PROTOCOL_VERSION, Mode, Nak, Role
from term.transports.serial import SerialTransport
from term.ui.app import TermApp

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make: the C board's tests are skipped")


async def test_term_flies_the_c_board_in_the_simulator() -> None:
    served = ThreadedServer(make_board(seed=3, board="c"))
    path = served.start()
    try:
        app = TermApp(SerialTransport(path), joystick=False)
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            async def until(cond, timeout: float = 15.0) -> None:  # noqa: ANN001
                async with asyncio.timeout(timeout):
                    while not cond():
                        await pilot.pause(0.02)

            def texts() -> list[str]:
                return [e.text for e in m.events]

            def naks() -> list[str]:
                return [e.text for e in m.events if e.source == "nak"]

            await until(lambda: m.hello is not None and m.mode == Mode.SAFE)
            assert (m.hello.protocol, m.hello.role, m.hello.major) == (PROTOCOL_VERSION, Role.BOARD, 0)
            app.simulate_key("3")
            await until(lambda: any("CALIBRATION → SAFE" in t for t in texts()))
            app.simulate_key("2")
            await until(lambda: m.mode == Mode.MANUAL)
            for _ in range(3):
                app.simulate_key("a")
            await pilot.pause(0.3)
            app.simulate_key("0")  # the lift trim is not zero: refused, with the board's reason
            await until(lambda: naks())
            assert naks()[-1] == f"NAK mode SAFE: {NAK_TEXT[Nak.LIFT_NOT_ZERO]}"
            for _ in range(3):
                app.simulate_key("z")
            await pilot.pause(0.3)
            app.simulate_key("0")
            await until(lambda: m.mode == Mode.SAFE)
            app.simulate_key("5")
            await until(lambda: m.mode == Mode.FULL)
            app.simulate_key("7")
            await until(lambda: m.mode == Mode.HEIGHT)
            app.simulate_key("1")
            await until(lambda: any("→ PANIC" in t for t in texts()))
            await until(lambda: any("PANIC → SAFE" in t for t in texts()) and m.mode == Mode.SAFE)
            assert len(naks()) == 1
            assert not [e for e in m.events if e.source == "link" and e.severity == "error"]
    finally:
        served.stop()
