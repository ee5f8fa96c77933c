"""The link's own thread: an asyncio loop apart from the display's, so rendering, a slow widget, a lesson's
expression or a big export never delay reading, heartbeat answers, command retries and stick sends.

- ``LinkThread`` runs one event loop on a daemon thread. The display hands it work with ``call`` (a function,
  ``call_soon_threadsafe``) and ``run`` (a coroutine; the caller awaits its result on its own loop). The
  transports are opened on the link's loop and used only there; ``Connection`` (term/session/connection.py) guards
  its sans-IO session with a lock, so the display may queue a command or a stick value from its own thread.
- ``FrontDoor`` carries things the other way: the link thread's events are queued and handed to the display's
  loop in batches (one wake-up for however many arrived), in the order they happened. The model is only ever
  changed on the display's thread.
- The watchdog (``may_send``): the display's loop calls ``alive()`` ten times a second (``watch``) and on
  every render tick. While it does, the link keeps
  the board fed; once the display has been frozen past ``freeze_s`` (about 1.5 s: the pilot is blind) the link
  stops writing on purpose, so the board's link-loss failsafe takes over instead of flying a craft nobody sees
  (only while ``armed`` says so: the station arms it while the board flies; in SAFE a silence lands nothing and
  would only be a false alarm, e.g. a start-up's first frames on a busy machine).
  When the display is back the link writes again, and ``on_thaw(frozen_s)`` says why it was quiet (the log and
  the events list). Time for the watchdog is the wall clock (``clock``), never a test's fake flight clock.

Why a thread and not a process: the link's work is a few hundred small frames a second; a thread with
``sys.setswitchinterval(0.001)`` gets the GIL within a millisecond of a frame's arrival, and the display reaches
the session without copying the model across a process boundary. ``python -m bench.contention`` measures it.
"""

from __future__ import annotations

import asyncio
import logging
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Coroutine
from typing import Any, TypeVar

from term.transports.base import Transport

T = TypeVar("T")
FREEZE_S = 1.5  # a display frozen this long stops the link's writes: the board fails safe rather than fly blind
log = logging.getLogger("term.link")


class LinkThread:
    """``start()``; ``call(fn, *args)`` / ``await run(coro)`` from the display; ``stop()``; ``alive()`` per tick."""

    def __init__(self, *, freeze_s: float = FREEZE_S, clock: Callable[[], float] = time.monotonic,
                 on_thaw: Callable[[float], None] | None = None, name: str = "term link") -> None:
        self.freeze_s = freeze_s
        self.clock = clock
        self.on_thaw = on_thaw
        self.armed: Callable[[], bool] | None = None  # the watchdog acts only while this says so (flying)
        self.name = name
        self.loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._alive = clock()
        self._frozen_since: float | None = None  # when the watchdog stopped the writes
        self._display: int | None = None  # the display's thread (the last to call alive)

    # --- life cycle -----------------------------------------------------------------------------------------

    def start(self) -> None:
        """Start the thread and its loop (idempotent); returns once the loop runs."""
        if self._thread is not None:
            return
        ready = threading.Event()
        self._alive = self.clock()

        def main() -> None:
            loop = asyncio.new_event_loop()
            self.loop = loop
            loop.call_soon(ready.set)
            try:
                loop.run_forever()
            finally:
                loop.run_until_complete(loop.shutdown_asyncgens())
                loop.close()

        self._thread = threading.Thread(target=main, name=self.name, daemon=True)
        self._thread.start()
        ready.wait()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the loop (after what it is running now) and join the thread."""
        thread, loop = self._thread, self.loop
        if thread is None or loop is None:
            return
        if not loop.is_closed():
            loop.call_soon_threadsafe(loop.stop)
        if thread is not threading.current_thread():
            thread.join(timeout)
        self._thread = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self.loop is not None and not self.loop.is_closed()

    def in_thread(self) -> bool:
        return self._thread is not None and threading.current_thread() is self._thread

    # --- work from the display ------------------------------------------------------------------------------

    def call(self, fn: Callable[..., Any], *args: Any) -> None:
        """Run ``fn(*args)`` on the link's loop (at once if already on it)."""
        if self.in_thread():
            fn(*args)
            return
        assert self.loop is not None, "LinkThread.start() first"
        self.loop.call_soon_threadsafe(fn, *args)

    async def run(self, coro: Coroutine[Any, Any, T]) -> T:
        """Run ``coro`` on the link's loop; await its result from any loop."""
        if self.in_thread():
            return await coro
        assert self.loop is not None, "LinkThread.start() first"
        return await asyncio.wrap_future(asyncio.run_coroutine_threadsafe(coro, self.loop))

    # --- the watchdog ---------------------------------------------------------------------------------------

    def alive(self) -> None:
        """The display is drawing: the link may keep the board fed."""
        self._alive = self.clock()
        self._display = threading.get_ident()

    def watch(self, display: asyncio.AbstractEventLoop, period: float = 0.1) -> None:
        """Call ``alive()`` from the display's loop every ``period`` s: a loop that runs its callbacks is one
        the pilot sees (a render tick may be skipped by a busy loop that is not frozen)."""

        def beat() -> None:
            if self._thread is None:
                return
            self.alive()
            display.call_later(period, beat)

        display.call_soon_threadsafe(beat)

    def frozen_for(self) -> float:
        return self.clock() - self._alive

    def may_send(self) -> bool:
        """False while the display has been frozen past ``freeze_s`` (the link's writes stop on purpose)."""
        frozen = self.frozen_for()
        if frozen > self.freeze_s and (self.armed is None or self.armed()):
            if self._frozen_since is None:
                self._frozen_since = self._alive
                log.warning("display frozen for %.1f s: the link stops answering the board on purpose; the display "
                            "is at:\n%s", frozen, self._where_display_is())
            return False
        if self._frozen_since is not None:
            lasted = self.clock() - self._frozen_since
            self._frozen_since = None
            log.warning("display back after %.1f s: the link answers the board again", lasted)
            if self.on_thaw is not None:
                self.on_thaw(lasted)
        return True


    def _where_display_is(self) -> str:
        """The display thread's innermost frames: what froze it, for the log."""
        frame = sys._current_frames().get(self._display) if self._display is not None else None
        if frame is None:
            return "  (not known)"
        return "".join(traceback.format_stack(frame, limit=8))


class FrontDoor:
    """Hands calls from other threads to one asyncio loop (the display's) in batches, in order."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.thread = threading.current_thread()
        self._queue: deque[tuple[Callable[..., Any], tuple[Any, ...]]] = deque()
        self._lock = threading.Lock()
        self._scheduled = False

    def here(self) -> bool:
        return threading.current_thread() is self.thread

    def post(self, fn: Callable[..., Any], *args: Any) -> None:
        """``fn(*args)`` on the display's loop: at once if this is its thread, else with the next batch."""
        if self.here():
            fn(*args)
            return
        with self._lock:
            self._queue.append((fn, args))
            if self._scheduled:
                return
            self._scheduled = True
        try:
            self.loop.call_soon_threadsafe(self._drain)
        except RuntimeError:  # the display's loop is closed: the app has ended, nobody to tell
            pass

    def _drain(self) -> None:
        with self._lock:
            batch, self._queue = self._queue, deque()
            self._scheduled = False
        for fn, args in batch:
            try:
                fn(*args)
            except Exception:  # one front-end reaction that fails must not drop the rest of the batch
                log.exception("the display failed on an event from the link")


class PostedTap:
    """A recorder's byte tap (``received``/``sent``) called on the link thread, written on the display's thread
    (``post``, e.g. ``Station.post``): the recording is not thread-safe, and its writes must not delay the link.
    The time is taken when the bytes passed, so the recording's timing is the link's."""

    def __init__(self, recorder: Any, post: Callable[..., None]) -> None:
        self.recorder = recorder
        self.post = post

    def received(self, link: str, data: bytes, now: float) -> None:
        self.post(self.recorder.received, link, data, now)

    def sent(self, link: str, data: bytes, now: float) -> None:
        self.post(self.recorder.sent, link, data, now)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.recorder, name)


def _chain(transport: object | None) -> list[object]:
    """``transport`` and what it wraps (taps and fault injectors keep theirs in ``inner``)."""
    out = []
    t = transport
    while t is not None:
        out.append(t)
        t = getattr(t, "__dict__", {}).get("inner")
    return out


def post_taps(transport: object | None, post: Callable[..., None]) -> None:
    """Every recording tap in ``transport``'s chain (its ``sinks``: the recording) writes through ``post`` (the
    display's thread) from now on; a sink that says ``thread_safe`` (the live server: it never blocks) is
    called on the link's thread as the bytes pass, so what it serves does not wait for the display."""
    for t in _chain(transport):
        sinks = t.__dict__.get("sinks")
        if isinstance(sinks, tuple):
            posted = tuple(s if isinstance(s, PostedTap) or getattr(s, "thread_safe", False) else PostedTap(s, post)
                           for s in sinks)
            t.sinks = posted  # type: ignore[attr-defined]


def movable(transport: Transport | None) -> bool:
    """True if ``transport`` (through its taps and fault injectors) may live on the link's thread: the pipe under
    them says so (``Transport.movable``: serial and BLE may; a loopback pair shares asyncio queues with a peer on
    the caller's loop and may not)."""
    return transport is not None and transport.innermost.movable


def is_open(transport: Transport | None) -> bool:
    """Whether ``transport`` (through its taps) is open already."""
    return transport is not None and transport.innermost.is_open
