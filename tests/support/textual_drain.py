"""Textual's Pilot, waiting on the app's messages instead of on an idle processor.

``Pilot.press`` and ``Pilot.pause()`` call ``textual._wait.wait_for_idle``, which sleeps in 20 ms steps until a step
costs the process under 1 ms of CPU, or a full second has passed. Term is never that idle in a test: its link's
timer wakes every 20 ms and the board beside it ticks, so every key pressed cost up to two seconds of waiting
(0.8 s on average in the safety-key walk: 28 of its 40 s) and proved nothing more than the queues below do.

``drained`` waits until the app and every widget of its screen have handled what was queued when it looked, three
times over: a key goes from the app to the screen to the focused widget, and may post one more message from there.
What a test then checks it still waits for (``tests/support/waits.py``); this only stops the pilot sleeping."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
import textual.app
import textual.pilot
from textual._context import active_app
from textual.pilot import Pilot

HOPS = 3  # app -> screen -> focused widget, and what that widget posts


async def drained(min_sleep: float = 0.0, max_sleep: float = 1.0) -> None:
    """In place of ``wait_for_idle(min_sleep, max_sleep)``: the active app's queues handled (module docstring)."""
    try:
        app = active_app.get()
    except LookupError:  # (no app: nothing queued to wait for)
        await asyncio.sleep(0)
        return
    pilot = Pilot(app)
    for _ in range(HOPS):
        await asyncio.sleep(0)
        if not app.is_running:
            return
        await pilot._wait_for_screen()  # (its own bound: 30 s, then WaitForScreenTimeout)


@contextmanager
def pilot_waits_on_queues() -> Iterator[None]:
    """Textual's two callers of ``wait_for_idle`` given ``drained`` for the duration. A Textual that renamed either
    fails here, loudly, rather than bringing the idle waits back unseen."""
    for module in (textual.app, textual.pilot):
        assert hasattr(module, "wait_for_idle"), f"{module.__name__} no longer calls wait_for_idle: see {__name__}"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(textual.app, "wait_for_idle", drained)
        mp.setattr(textual.pilot, "wait_for_idle", drained)
        yield
