"""The real app (Textual's Pilot through ``App.run_test``) on the simulated board served by `fcb-sim serve --pty`
(the path of `term --sim`): ``served()`` yields the app, the pilot and a bounded wait; ``fly_out_of_safe`` takes the
board into MANUAL with the sticks and lift neutral (out of SAFE: the digit keys and Esc fly the craft)."""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from functools import partial
from typing import Any

from term.core.protocol import PARAMS, Joystick, Mode, Op
from term.session.config import Config
from term.session.sim import SimBoard
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from tests.support.waits import until

Until = Callable[..., Any]


@asynccontextmanager
async def served(config: Config | None = None, extra: list[str] | None = None,
                 size: tuple[int, int] = (120, 44)) -> AsyncIterator[tuple[TermApp, Any, Until]]:
    sim = SimBoard(seed=2, extra=extra or [])
    port = sim.start()
    try:
        app = TermApp(SerialTransport(port), joystick=False, config=config)
        async with app.run_test(size=size) as pilot:
            wait = partial(until, pilot)  # the tests' one wait, on this app
            await wait(lambda: len(app.model.params) == len(PARAMS))  # listed when the board said Hello
            yield app, pilot, wait
    finally:
        sim.stop()


async def fly_out_of_safe(app: TermApp, until: Until, mode: Mode = Mode.MANUAL) -> None:
    """The board into ``mode`` (MANUAL by default: no calibration needed) with the sticks at rest."""
    app.set_stick(Joystick(0, 0, 0, 0, 0))
    if mode != Mode.MANUAL:
        app.send(Op.MODE, Mode.CALIBRATION)
        await until(lambda: app.model.mode == Mode.CALIBRATION)
        await until(lambda: app.model.mode == Mode.SAFE)
    app.send(Op.MODE, mode)
    await until(lambda: app.model.mode == mode)


def mode_requests(app: TermApp) -> list[str]:
    """The events that say a mode was requested (a digit or Esc taken as a flight key)."""
    return [e.text for e in app.model.events if e.text.startswith("request ")]
