"""The one wait of the tests: ``until(cond)``, or ``until(pilot, cond)`` in a Textual app, for a condition that the
code under test makes true by itself (a packet arrives, a screen opens). The bound only ends a test that would hang:
a busy machine is slow, not wrong, so it is generous; nothing here times anything.

A check that something did NOT happen never waits for a while and looks: it sends a marker through the same
ordered link and waits for that (``tests/support/app_rig.py`` ``sent_before_marker``)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

TIMEOUT_S = 30.0


async def until(first: Any, second: Any = None, timeout: float = TIMEOUT_S, *, step: float = 0.005,
                what: str | Callable[[], str] = "") -> None:
    """``until(cond[, timeout])`` or ``until(pilot, cond[, timeout])``: looks at ``cond`` every ``step`` seconds,
    stepping the event loop with ``asyncio.sleep`` between the looks (the app's messages and timers run there); with
    a pilot, once ``cond`` holds, the app's and its screen's queues are drained once (``pilot.pause``), so nothing
    a test caused is still queued when the app shuts down. Not ``pilot.pause`` at every look: it posts a callback
    to the app and to every widget of the screen (24 on the flight screen) and waits for all of them, every 5 ms
    (tests/ui in one process: 118 s of CPU with it, 110 s without), and more for every second a busy machine
    stretches a wait.
    ``what`` (or what it returns, asked at the timeout) names the wait in the failure."""
    pilot = None
    if callable(first):
        cond: Callable[[], object] = first
        timeout = second if second is not None else timeout
    else:
        pilot, cond = first, second
    try:
        async with asyncio.timeout(timeout):
            while not cond():
                await asyncio.sleep(step)
            if pilot is not None:
                await pilot.pause(0)
    except TimeoutError:
        if not what:
            raise
        raise AssertionError(f"waited {timeout:g} s for {what() if callable(what) else what}") from None
