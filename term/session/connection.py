"""The asyncio pump that runs a ``LinkSession`` over a ``Transport``.

Two tasks share one session (single-threaded, so no locking of the session itself):

- the read task awaits the transport, feeds ``session.receive`` and writes ``data_to_send`` in the same step,
  so a heartbeat is answered the moment it arrives, never at the next UI tick;
- the timer task sleeps until ``session.next_deadline()`` (or until woken by a new command or stick value),
  then runs ``poll`` and writes what is due.

A stall of this process (a busy laptop: no CPU for a while) is not the board's silence: the timer wakes at least
every ``TICK_S``, so a gap between two runs of either task longer than that plus ``STARVED_S`` is time the link
could not listen, told to the session (``LinkSession.starved``) before the frames that waited are read.

Events go to the ``on_event`` callback, or, without one, into ``events`` (an asyncio.Queue). A transport that
dies ends the connection with one ``TransportFailed`` event carrying the transport's one-line message; so does
any exception in the pump (a bug, or a front end's reaction that raised): it is logged with its traceback and
named in the event ("link error: OverflowError: ..."), never a silent end. ``stop`` is a clean stop that emits
nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from term.core.link import LinkEvent, LinkSession, LinkStats
from term.core.protocol import Joystick, Op
from term.transports.base import Transport, TransportClosed, TransportError

log = logging.getLogger("term.link")
STARVED_S = 0.05  # a run this late means this process got no CPU meanwhile (the session leaves that time out)
TICK_S = 0.02  # the timer wakes at least this often, so a stall is measured whole, not only past a deadline


@dataclass(frozen=True, slots=True)
class TransportFailed:
    """The transport died; ``message`` is its one clear line. The connection has stopped."""

    message: str


ConnectionEvent = LinkEvent | TransportFailed


class Connection:
    """``Connection(transport, session)``; ``await start()`` (opens the transport), ``await stop()``."""

    def __init__(
        self,
        transport: Transport,
        session: LinkSession,
        clock: Callable[[], float] = time.monotonic,
        on_event: Callable[[ConnectionEvent], None] | None = None,
        gate: Callable[[], bool] | None = None,
    ) -> None:
        """``gate``: asked before every write; False drops what is due (the display's watchdog,
        term/session/link_thread.py: a frozen display stops the heartbeat answers on purpose)."""
        self.transport = transport
        self.session = session
        self.clock = clock
        self.on_event = on_event
        self.events: asyncio.Queue[ConnectionEvent] = asyncio.Queue()
        self.error: TransportError | None = None
        self.crash: Exception | None = None
        self.gate = gate
        self._wake = asyncio.Event()
        self._lock = threading.Lock()  # the session: the pump's thread and the display's both call it
        self._loop: asyncio.AbstractEventLoop | None = None
        self._write_lock = asyncio.Lock()
        self._tasks: list[asyncio.Task[None]] = []
        self._done = asyncio.Event()
        self._running = False
        self._last_run: float | None = None  # when a pump task last ran (the stall meter)

    # --- life cycle -----------------------------------------------------------------------------------------

    async def start(self) -> None:
        """Open the transport, send our Hello, start the pump. Raises TransportError if the open fails."""
        await self.transport.open()
        self._loop = asyncio.get_running_loop()
        self._running = True
        self._done.clear()
        try:
            with self._lock:
                hello = self.session.hello()
                self._last_run = self.clock()
            await self._write(hello)
        except BaseException:
            self._running = False
            await self.transport.close()
            raise
        self._tasks = [
            asyncio.create_task(self._read_loop(), name=f"link read {self.transport.name}"),
            asyncio.create_task(self._timer_loop(), name=f"link timer {self.transport.name}"),
        ]

    async def stop(self) -> None:
        """Stop the pump and close the transport. Idempotent; emits no event."""
        self._running = False
        current = asyncio.current_task()
        tasks = [t for t in self._tasks if t is not current]
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t
        self._tasks = []
        await self.transport.close()
        self._done.set()

    async def wait_closed(self) -> None:
        """Wait until the connection stops; raises its TransportError if the transport died."""
        await self._done.wait()
        if self.crash is not None:
            raise self.crash
        if self.error is not None:
            raise self.error

    async def __aenter__(self) -> Connection:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    @property
    def running(self) -> bool:
        return self._running

    # --- the app's side -------------------------------------------------------------------------------------

    def send_command(self, op: Op, arg: int = 0) -> int:
        """Queue a command (sent at once by the timer task); returns its cmd_id. Any thread may call it."""
        with self._lock:
            cmd_id = self.session.send_command(op, arg, self.clock())
        self._poke()
        return cmd_id

    def set_joystick(self, js: Joystick) -> None:
        """A new stick value (latest wins). Any thread may call it."""
        with self._lock:
            self.session.set_joystick(js)
        self._poke()

    @property
    def stats(self) -> LinkStats:
        with self._lock:
            return self.session.stats_at(self.clock())

    def _poke(self) -> None:
        """Wake the timer task, from its own loop or from another thread."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is loop:
            self._wake.set()
        else:
            loop.call_soon_threadsafe(self._wake.set)

    # --- the pump -------------------------------------------------------------------------------------------

    async def _read_loop(self) -> None:
        session = self.session
        try:
            while True:
                data = await self.transport.read()
                with self._lock:
                    now = self.clock()
                    self._ran(now)  # a stall just ended: said before the frames that waited are read
                    events = session.receive(data, now)
                await self._flush()  # heartbeat ACKs leave now, in this step
                self._deliver(events)
                self._wake.set()  # deadlines may have moved (an Ack removed a retry)
        except TransportClosed as exc:
            if self._running:  # closed under us, not by stop(): the link is gone all the same
                await self._fail(exc)
        except TransportError as exc:
            await self._fail(exc)
        except Exception as exc:  # a bug (e.g. in on_event): the link is lost all the same, and says why
            await self._crashed(exc)

    async def _timer_loop(self) -> None:
        session = self.session
        try:
            while True:
                with self._lock:
                    now = self.clock()
                    self._ran(now)
                    events = session.poll(now)
                await self._flush()
                self._deliver(events)
                with self._lock:
                    delay = session.next_deadline() - self.clock()
                if delay > 0:
                    self._wake.clear()
                    # asyncio.timeout, not wait_for: 3.11's wait_for can swallow the cancel that stop() sends.
                    with contextlib.suppress(TimeoutError):
                        async with asyncio.timeout(min(delay, TICK_S)):
                            await self._wake.wait()
        except TransportClosed as exc:
            if self._running:  # closed under us, not by stop(): the link is gone all the same
                await self._fail(exc)
        except TransportError as exc:
            await self._fail(exc)
        except Exception as exc:  # a bug (e.g. in on_event): the link is lost all the same, and says why
            await self._crashed(exc)

    def _ran(self, now: float) -> None:
        """A pump task runs at ``now`` (the session's lock held). The timer runs at least every TICK_S: a gap
        much longer than that is time this process got no CPU, which the session leaves out of the silence."""
        last = self._last_run
        if last is not None and now - last > TICK_S + STARVED_S:
            self.session.starved(last + TICK_S, now)
        self._last_run = now if last is None else max(last, now)

    async def _flush(self) -> None:
        async with self._write_lock:  # take the bytes and write them as one step, so order is kept
            with self._lock:
                data = self.session.data_to_send(self.clock())
            if data and (self.gate is None or self.gate()):
                await self.transport.write(data)

    async def _write(self, data: bytes) -> None:
        async with self._write_lock:
            await self.transport.write(data)

    def _deliver(self, events: list[ConnectionEvent] | list[LinkEvent]) -> None:
        for ev in events:
            if self.on_event is not None:
                self.on_event(ev)
            else:
                self.events.put_nowait(ev)

    async def _crashed(self, exc: Exception) -> None:
        """An exception in the pump: logged with its traceback, and the end of the link like a dead transport
        (``TransportFailed`` naming it, so the front end says LINK LOST and reconnects); ``wait_closed`` raises it."""
        if self.crash is not None or not self._running:
            return
        self.crash = exc
        log.error("link %s: %s", self.transport.name, crash_text(exc), exc_info=exc)
        await self._fail(TransportError(crash_text(exc)))

    async def _fail(self, exc: TransportError) -> None:
        if self.error is not None or not self._running:
            return
        self.error = exc
        try:
            self._deliver([TransportFailed(str(exc))])
        except Exception as again:  # the front end failed on this too: it is in the log, the link still stops
            log.error("link %s: the front end failed on the link's end", self.transport.name, exc_info=again)
        await self.stop()


def crash_text(exc: BaseException) -> str:
    """One line for a bug in the link path: what it was, for the pilot's LINK LOST and the log."""
    text = " ".join(str(exc).split())[:160]
    return f"link error: {type(exc).__name__}" + (f": {text}" if text else "")
