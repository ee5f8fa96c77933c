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
    """``until(cond[, timeout])`` steps the event loop with ``asyncio.sleep``; ``until(pilot, cond[, timeout])``
    with Textual's ``pilot.pause`` (the app's messages run between the looks). ``what`` (or what it returns, asked
    at the timeout) names the wait in the failure."""
    if callable(first):
        cond: Callable[[], object] = first
        timeout = second if second is not None else timeout
        pause: Callable[[float], Any] = asyncio.sleep
    else:
        cond, pause = second, first.pause
    try:
        async with asyncio.timeout(timeout):
            while not cond():
                await pause(step)
    except TimeoutError:
        if not what:
            raise
        raise AssertionError(f"waited {timeout:g} s for {what() if callable(what) else what}") from None
