"""The door every listening server of the simulator passes its connections through: a flood costs the flight nothing.

The policy (DESIGN.md, "Platforms and the outside world"), for the instructor (hosts/instructor.py) and the BLE HCI
server (hosts/radio.py):

- at most ``max_pending`` connections that have not authenticated (a token not yet given, an HCI host waiting for
  the radio) at a time; the next one is refused at once;
- each of them is dropped after ``pending_timeout_s`` (``authenticated(transport)`` stops that clock);
- never a descriptor the event loop's selector cannot watch (below);
- refusals are counted (``refused``) and logged summarised: the first of a quiet spell in full, the rest as one line
  per ``SUMMARY_INTERVAL_S`` with a count per reason (``RefusalLog``), so a flood is not also a flood of log.

The selector. ``fcb-sim serve`` runs its loop on ``select()`` on every platform on purpose (hosts/serve.py,
``event_loop``): its timeouts have microsecond resolution, and the board's tasks are due every 2.5 ms (epoll rounds
every timeout up to a whole millisecond). The others do not fit either: macOS's poll() answers POLLNVAL for devices
(the pty master is one) and its kqueue watches terminals only on recent releases. select() cannot watch a
descriptor numbered FD_SETSIZE (1024 on Linux, macOS and the BSDs) or more: one registered kills the loop
(``ValueError: filedescriptor out of range in select()``), and with it the flight. The numbers are the lowest free
ones, so a server that holds few connections never gets there; a process that holds many for another reason
(or a soft RLIMIT_NOFILE above 1024 with a burst of connections accepted at once) could. So ``Door.admit`` refuses
a connection whose descriptor is at or past the limit before asyncio registers it (``connection_made`` runs before
the transport's own ``add_reader``; a transport closed there is never registered), without writing to it (a write
that waits would register it for writing); ``GuardedServer`` refuses it on the bare socket, before any
transport. On Windows select() limits the count of sockets (512 in CPython), not their numbers; the caps above
keep the count small there. A loop on epoll, kqueue or poll has no such limit (``fd_limit`` None).

``guarded(factory, door)`` wraps an asyncio protocol factory for ``loop.create_server``: the door admits or refuses
in ``connection_made``, and releases in ``connection_lost``; the wrapped protocol sees only admitted connections.
``GuardedServer.start(host, port, factory, door)`` is the cheaper way in under a flood: its own accept loop refuses
a connection past the cap or the descriptor bound on the bare socket (a refusal line sent without waiting, then
closed), before asyncio makes a transport, a task and a protocol of it (a few µs instead of some hundred), and
passes the rest to ``loop.connect_accepted_socket`` behind the same door.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import selectors
import socket
import sys
import time
from collections import Counter, OrderedDict
from collections.abc import Callable

FD_SETSIZE = 1024  # select()'s bound on a descriptor's number (glibc, macOS, the BSDs)
FD_RESERVE = 16  # descriptors kept below the bound for the loop's own needs (a reconnecting pty client, a log file)
SUMMARY_INTERVAL_S = 10.0

TOO_MANY = "too many connections waiting"
TIMED_OUT = "timed out before authenticating"
FD_RANGE = "descriptor past what select() can watch"


def fd_limit(loop: asyncio.AbstractEventLoop | None = None) -> int | None:
    """The first descriptor number ``loop``'s selector cannot watch (less a reserve), or None if it has no bound."""
    loop = loop or asyncio.get_running_loop()
    selector = getattr(loop, "_selector", None)
    if isinstance(selector, selectors.SelectSelector) and sys.platform != "win32":
        return FD_SETSIZE - FD_RESERVE
    return None


class RefusalLog:
    """Refusals logged summarised: the first after a quiet interval in full, then one line per ``interval`` with the
    count per reason (``flush`` writes it; ``note`` calls it once the interval is over, and ``Door`` schedules it)."""

    def __init__(self, log: logging.Logger, what: str, *, interval: float = SUMMARY_INTERVAL_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.log = log
        self.what = what
        self.interval = interval
        self.clock = clock
        self.counts: Counter[str] = Counter()
        self._since: float | None = None  # start of the interval being counted; None: quiet
        self.lines = 0  # lines written (tests, the soak bench)

    def note(self, why: str) -> bool:
        """Count one refusal; True if it opened an interval (the caller may schedule ``flush``)."""
        now = self.clock()
        if self._since is not None and now - self._since >= self.interval:
            self.flush()
        if self._since is None:
            self._since = now
            self.lines += 1
            self.log.warning("%s: a client refused: %s", self.what, why)
            return True
        self.counts[why] += 1
        return False

    def flush(self) -> None:
        """The interval's line (if anything was counted), and a quiet spell begins."""
        if self.counts:
            total = sum(self.counts.values())
            reasons = ", ".join(f"{n:,} {why}" for why, n in self.counts.most_common())
            start = self._since if self._since is not None else self.clock()
            self.lines += 1
            self.log.warning("%s: %s more clients refused in %.0f s (%s)", self.what, f"{total:,}",
                             max(self.clock() - start, 0.0), reasons)
            self.counts.clear()
            self._since = self.clock()  # the count goes on: a flood is one line per interval
        else:
            self._since = None


class Door:
    """The admission policy of one listening server (module docstring)."""

    def __init__(self, name: str, log: logging.Logger, *, max_pending: int = 8, pending_timeout_s: float = 10.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self.max_pending = max_pending
        self.pending_timeout_s = pending_timeout_s
        self.refusals = RefusalLog(log, name, clock=clock)
        self.refused = 0
        self._pending: dict[asyncio.BaseTransport, asyncio.TimerHandle | None] = {}
        self._flush: asyncio.TimerHandle | None = None

    @property
    def pending(self) -> int:
        return len(self._pending)

    def admit(self, transport: asyncio.BaseTransport) -> str | None:
        """None: ``transport`` is in, pending (its clock runs); else why not (the caller aborts it)."""
        sock = transport.get_extra_info("socket")
        limit = fd_limit()
        if limit is not None and sock is not None and sock.fileno() >= limit:
            return FD_RANGE
        if len(self._pending) >= self.max_pending:
            return TOO_MANY
        loop = asyncio.get_running_loop()
        self._pending[transport] = loop.call_later(self.pending_timeout_s, self._expire, transport)
        return None

    def authenticated(self, transport: asyncio.BaseTransport) -> None:
        """``transport`` gave what the server asks for (or got the radio): its clock stops, its slot is free."""
        handle = self._pending.pop(transport, None)
        if handle is not None:
            handle.cancel()

    def release(self, transport: asyncio.BaseTransport) -> None:
        self.authenticated(transport)

    def refuse(self, why: str) -> None:
        """Count and log (summarised) one refusal."""
        self.refused += 1
        if self.refusals.note(why) and self._flush is None:
            with contextlib.suppress(RuntimeError):  # no running loop (a test's own door): flush() by hand
                loop = asyncio.get_running_loop()
                self._flush = loop.call_later(self.refusals.interval, self._flush_now)

    def _flush_now(self) -> None:
        self._flush = None
        r = self.refusals
        left = r.interval - (r.clock() - r._since) if r._since is not None else 0.0
        if left > 0.05:  # a refusal already wrote this interval's line (``note``): the next at the new one's end
            self._flush = asyncio.get_running_loop().call_later(left, self._flush_now)
            return
        r.flush()
        if r._since is not None:  # the interval goes on: the next line at its end
            self._flush = asyncio.get_running_loop().call_later(r.interval, self._flush_now)

    def _expire(self, transport: asyncio.BaseTransport) -> None:
        if self._pending.pop(transport, None) is not None:
            self.refuse(TIMED_OUT)
            transport.abort()  # type: ignore[attr-defined]

    def close(self) -> None:
        for handle in self._pending.values():
            if handle is not None:
                handle.cancel()
        self._pending.clear()
        if self._flush is not None:
            self._flush.cancel()
            self._flush = None
        self.refusals.flush()


class _Guarded(asyncio.Protocol):
    """A protocol behind a door: the wrapped one is made only for an admitted connection."""

    def __init__(self, door: Door, factory: Callable[[], asyncio.Protocol],
                 refusal: Callable[[str], bytes | None] | None) -> None:
        self._door = door
        self._factory = factory
        self._refusal = refusal
        self._inner: asyncio.Protocol | None = None
        self._transport: asyncio.BaseTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        why = self._door.admit(transport)
        if why is not None:
            self._door.refuse(why)
            line = self._refusal(why) if self._refusal is not None and why != FD_RANGE else None
            if line:  # a descriptor below the limit: a short line fits the socket's buffer
                transport.write(line)  # type: ignore[attr-defined]
                transport.close()
            else:
                transport.abort()  # type: ignore[attr-defined]
            return
        self._transport = transport
        self._inner = self._factory()
        self._inner.connection_made(transport)

    def data_received(self, data: bytes) -> None:
        if self._inner is not None:
            self._inner.data_received(data)

    def eof_received(self) -> bool | None:
        return self._inner.eof_received() if self._inner is not None else None

    def connection_lost(self, exc: Exception | None) -> None:
        if self._transport is not None:
            self._door.release(self._transport)
        if self._inner is not None:
            self._inner.connection_lost(exc)

    def pause_writing(self) -> None:
        if self._inner is not None:
            self._inner.pause_writing()

    def resume_writing(self) -> None:
        if self._inner is not None:
            self._inner.resume_writing()


def guarded(factory: Callable[[], asyncio.Protocol], door: Door, *,
            refusal: Callable[[str], bytes | None] | None = None) -> Callable[[], asyncio.Protocol]:
    """A protocol factory for ``loop.create_server`` whose connections pass ``door`` first. ``refusal(why)``: the
    bytes a refused client is sent before it is closed (never for a descriptor past the selector's bound)."""
    return lambda: _Guarded(door, factory, refusal)


class LoginThrottle:
    """Failed logins limited per address: after the n-th failure in a row an address waits ``base_s * 2**(n-1)``
    seconds (at most ``max_s``) before its next token is looked at; a success forgets it, and so does
    ``forget_s`` without a failure. At most ``max_addresses`` are remembered (the oldest failure goes first), so an
    attacker with many addresses costs bounded memory. The 128-bit token makes guessing hopeless anyway: this keeps a
    guessing loop from costing the simulator CPU and log."""

    def __init__(self, *, base_s: float = 0.1, max_s: float = 30.0, forget_s: float = 600.0,
                 max_addresses: int = 4096, clock: Callable[[], float] = time.monotonic) -> None:
        self.base_s = base_s
        self.max_s = max_s
        self.forget_s = forget_s
        self.max_addresses = max_addresses
        self.clock = clock
        self._failures: OrderedDict[str, tuple[int, float]] = OrderedDict()  # address -> (failures, last failure)

    def wait(self, address: str) -> float:
        """Seconds ``address`` must still wait before a login of its is looked at (0: now)."""
        entry = self._failures.get(address)
        if entry is None:
            return 0.0
        n, last = entry
        now = self.clock()
        if now - last >= self.forget_s:
            del self._failures[address]
            return 0.0
        return max(0.0, last + self.delay(n) - now)

    def delay(self, failures: int) -> float:
        return 0.0 if failures <= 0 else min(self.max_s, self.base_s * 2.0 ** min(failures - 1, 64))

    def failed(self, address: str) -> None:
        n = self._failures.pop(address, (0, 0.0))[0]
        self._failures[address] = (n + 1, self.clock())  # moved to the end: the newest
        while len(self._failures) > self.max_addresses:
            self._failures.popitem(last=False)

    def succeeded(self, address: str) -> None:
        self._failures.pop(address, None)

    def __len__(self) -> int:
        return len(self._failures)


ACCEPT_BATCH = 100  # connections accepted per wake-up (asyncio's backlog default)
ACCEPT_RETRY_S = 1.0  # out of descriptors (EMFILE): stop accepting this long, as asyncio does


class GuardedServer:
    """A listening TCP socket whose connections pass ``door`` before asyncio makes anything of them (module
    docstring). ``sockets``, ``close()`` and ``wait_closed()`` as an ``asyncio.Server``'s."""

    def __init__(self, sock: socket.socket, factory: Callable[[], asyncio.Protocol], door: Door,
                 refusal: Callable[[str], bytes | None] | None) -> None:
        self._sock = sock
        self._factory = guarded(factory, door, refusal=refusal)
        self._door = door
        self._refusal = refusal
        self._loop = asyncio.get_running_loop()
        self._connecting: set[asyncio.Task[None]] = set()
        self._closed = False
        self._loop.add_reader(sock.fileno(), self._accept)

    @classmethod
    async def start(cls, host: str, port: int, factory: Callable[[], asyncio.Protocol], door: Door, *,
                    refusal: Callable[[str], bytes | None] | None = None) -> GuardedServer:
        """Listen on (host, port) (the first address ``host`` resolves to); OSError if it cannot."""
        loop = asyncio.get_running_loop()
        infos = await loop.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        family, _, _, _, addr = infos[0]
        sock = socket.create_server(addr[:2], family=family, backlog=ACCEPT_BATCH)
        sock.setblocking(False)
        return cls(sock, factory, door, refusal)

    @property
    def sockets(self) -> list[socket.socket]:
        return [] if self._closed else [self._sock]

    def _accept(self) -> None:
        door, limit = self._door, fd_limit(self._loop)
        for _ in range(ACCEPT_BATCH):
            try:
                conn, _ = self._sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:  # out of descriptors or memory: pause, do not spin
                if exc.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    door.refuse(f"cannot accept: {exc.strerror}")
                    self._loop.remove_reader(self._sock.fileno())
                    self._loop.call_later(ACCEPT_RETRY_S, self._resume)
                return  # (ECONNABORTED and the like: that client is gone)
            why = None
            if limit is not None and conn.fileno() >= limit:
                why = FD_RANGE
            elif door.pending + len(self._connecting) >= door.max_pending:
                why = TOO_MANY
            if why is not None:
                door.refuse(why)
                line = self._refusal(why) if self._refusal is not None else None
                if line:
                    with contextlib.suppress(OSError):
                        conn.setblocking(False)
                        conn.send(line)  # a fresh socket's buffer holds a line: never waits, never registered
                conn.close()
                continue
            conn.setblocking(False)
            task = self._loop.create_task(self._connect(conn))
            self._connecting.add(task)
            task.add_done_callback(self._connecting.discard)

    async def _connect(self, conn: socket.socket) -> None:
        try:
            await self._loop.connect_accepted_socket(self._factory, sock=conn)
        except OSError:
            conn.close()

    def _resume(self) -> None:
        if not self._closed:
            self._loop.add_reader(self._sock.fileno(), self._accept)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._loop.remove_reader(self._sock.fileno())
        self._sock.close()
        for task in self._connecting:
            task.cancel()

    async def wait_closed(self) -> None:
        for task in list(self._connecting):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
