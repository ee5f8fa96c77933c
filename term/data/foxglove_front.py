"""The door of the live Foxglove server (term/data/foxglove_server.py): a TCP front that holds a flood of
connections without harm to the flight, splicing the rest to the SDK's server bound on loopback.

Why a front: the Foxglove SDK (foxglove-sdk 0.30) accepts every TCP connection and keeps it, upgraded or not: its
accept loop spawns a task per connection, with no cap and no time limit, and ``start_server`` offers neither. A
flood of idle connections costs term a descriptor each until RLIMIT_NOFILE, and then the link's port, the
recording's next file and the SDK's accept loop itself (it ends at the first failed accept) fail with it.

Contract:

- ``Front(host, port)`` binds (host, port) at once (OSError, or the resolver's error, if it cannot; the caller
  names it in one line); ``port`` is the port bound. ``start((uhost, uport))`` serves on a thread of its own with
  an event loop of its own (never the link thread's: its timing is the flight's), splicing to the upstream.
- A connection is *pending* until it has sent a whole HTTP request head (the WebSocket upgrade: at most
  ``max_head`` bytes) and the upstream has answered it. At most ``max_pending`` pending at a time: a new one past
  the cap evicts the oldest that has not sent its head (a client sends its head within milliseconds of
  connecting, an idle flood never does: evicting the oldest lets the client in, refusing the newest would not);
  if all have sent theirs, the new one is refused. Each is dropped ``pending_timeout_s`` after it was accepted.
- Only a whole head is passed upstream: an idle connection never reaches the SDK, so it never costs the SDK a
  task or a descriptor. Connections past the head are *clients*: at most ``max_clients`` (the next head is
  answered ``503``).
- A refused connection is answered ``503`` without waiting (a fresh socket's buffer holds the short line) and
  closed. Refusals are counted by reason (``refused``) and logged summarised: the first of a quiet spell in full,
  the rest as one line per ``SUMMARY_INTERVAL_S`` with the count per reason, so a flood is not a flood of log.
- Spliced both ways with flow control: a client that does not read pauses the reading of its upstream, so the
  socket buffers fill and the SDK drops that client's oldest messages (its own policy), never more memory here.
- ``close()`` stops accepting, closes every connection and joins the thread.

The selector. The loop is ``asyncio.SelectorEventLoop(selectors.DefaultSelector())`` on every platform: epoll on
Linux, kqueue on macOS and the BSDs, select() on Windows. It watches sockets only, which each of them supports
(macOS's trouble, poll() answering POLLNVAL for devices and kqueue watching terminals only on recent releases,
is with the serial port, which the link's thread watches, not this one). epoll and kqueue have no bound on a
descriptor's number, as select() has (FD_SETSIZE, 1024); Windows' select() bounds the count of sockets (512 in
CPython), and the caps keep the count far below it: the listener, ``max_pending`` pending and two a client (its
own and its upstream). A selector loop, not Windows' default proactor, because the pending connections are bare
sockets watched with ``add_reader`` (the proactor has none): accepting, watching and dropping one costs a few
system calls, not an asyncio transport, a task and a protocol, so a flood of them costs term's process little
CPU (and the link's thread little of the interpreter's lock). The caps also bound what term's process holds,
so a flood never starves the link's thread of descriptors (a serial port reopened, the recording's next file).

Beside the front, the SDK's own port is open on loopback (it cannot be given a socket): a process of this machine
could reach it directly. The front guards what term serves to the network and the port it names.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import selectors
import socket
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Callable

log = logging.getLogger("term.foxglove")

# A flood reopens what the door drops (hundreds a second here): a viewer that connected has until this many newer
# connections arrive to send its upgrade, so the cap is its time to speak; 64 sockets are little to hold.
MAX_PENDING = 64
PENDING_TIMEOUT_S = 5.0
MAX_CLIENTS = 16
MAX_HEAD = 16 * 1024  # an upgrade request is a few hundred bytes; a browser's with cookies a few KB
ACCEPT_BATCH = 64  # connections accepted per wake-up
ACCEPT_RETRY_S = 1.0  # out of descriptors (EMFILE): stop accepting this long, do not spin
SWEEP_S = 0.25  # how often the pending connections' deadlines are looked at (one timer, not one a connection)
SUMMARY_INTERVAL_S = 10.0
REFUSAL = b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"

EVICTED = "evicted: too many connections waiting for the handshake"
REFUSED_PENDING = "too many connections in the handshake"
TIMED_OUT = "timed out before the handshake"
TOO_MANY_CLIENTS = "too many clients"
HEAD_TOO_BIG = "request head too large"
UPSTREAM = "the SDK's server did not answer"


class Refusals:
    """Refusals counted by reason and logged summarised (module docstring); ``tick()`` writes the interval's line
    once it is over (the front's sweep calls it)."""

    def __init__(self, what: str, *, interval: float = SUMMARY_INTERVAL_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.what, self.interval, self.clock = what, interval, clock
        self.total: Counter[str] = Counter()  # every refusal since the start, by reason
        self._counts: Counter[str] = Counter()  # this interval's, not yet logged
        self._since: float | None = None  # the interval's start; None: quiet
        self.lines = 0  # log lines written

    def note(self, why: str) -> None:
        self.total[why] += 1
        if self._since is None:
            self._since = self.clock()
            self.lines += 1
            log.warning("%s: a connection refused: %s", self.what, why)
        else:
            self._counts[why] += 1

    def tick(self) -> None:
        if self._since is None or self.clock() - self._since < self.interval:
            return
        if not self._counts:
            self._since = None  # a quiet interval: the next refusal is logged in full
            return
        reasons = ", ".join(f"{n:,} {why}" for why, n in self._counts.most_common())
        self.lines += 1
        log.warning("%s: %s more connections refused in %.0f s (%s)", self.what, f"{sum(self._counts.values()):,}",
                    self.clock() - self._since, reasons)
        self._counts.clear()
        self._since = self.clock()


class _Pending:
    """A connection not yet spliced: its bare socket, the head read so far, its deadline."""

    __slots__ = ("sock", "head", "deadline", "handed")

    def __init__(self, sock: socket.socket, deadline: float) -> None:
        self.sock, self.head, self.deadline, self.handed = sock, bytearray(), deadline, False


class _Side(asyncio.Protocol):
    """One end of a splice: what it reads is written to its peer; its peer's full buffer pauses its reading."""

    def __init__(self, front: Front, splice: _Splice, name: str) -> None:
        self.front, self.splice, self.name = front, splice, name
        self.transport: asyncio.Transport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def data_received(self, data: bytes) -> None:
        self.splice.forward(self, data)

    def connection_lost(self, exc: Exception | None) -> None:
        self.splice.lost(self)

    def pause_writing(self) -> None:
        self.splice.peer(self).pause()

    def resume_writing(self) -> None:
        self.splice.peer(self).resume()

    def pause(self) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.pause_reading()

    def resume(self) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.resume_reading()


class _Splice:
    """A client and its upstream; pending until the upstream's first bytes (its answer to the head)."""

    def __init__(self, front: Front, pending: _Pending) -> None:
        self.front, self.pending = front, pending
        self.down = _Side(front, self, "client")
        self.up = _Side(front, self, "upstream")
        self.answered = False
        self.closed = False

    def peer(self, side: _Side) -> _Side:
        return self.up if side is self.down else self.down

    def forward(self, side: _Side, data: bytes) -> None:
        if side is self.up and not self.answered:
            self.answered = True
            self.front._handshaken(self)
        other = self.peer(side).transport
        if other is not None and not other.is_closing():
            other.write(data)

    def lost(self, side: _Side) -> None:
        other = self.peer(side).transport
        if other is not None:
            other.close()  # (after what it still has to write)
        if not self.closed:
            self.closed = True
            self.front._gone(self)

    def abort(self) -> None:
        for side in (self.down, self.up):
            if side.transport is not None:
                side.transport.abort()
        if not self.closed:
            self.closed = True
            self.front._gone(self)


class Front:
    """The guarding front (module docstring)."""

    def __init__(self, host: str, port: int, *, max_pending: int = MAX_PENDING,
                 pending_timeout_s: float = PENDING_TIMEOUT_S, max_clients: int = MAX_CLIENTS,
                 max_head: int = MAX_HEAD, name: str = "live Foxglove server") -> None:
        self.max_pending, self.pending_timeout_s = max_pending, pending_timeout_s
        self.max_clients, self.max_head = max_clients, max_head
        family, _, _, _, addr = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)[0]
        self._sock = socket.create_server(addr[:2], family=family, backlog=ACCEPT_BATCH)
        self._sock.setblocking(False)
        self.port: int = self._sock.getsockname()[1]
        self.refusals = Refusals(name)
        self.accepted = 0
        self._pending: OrderedDict[socket.socket, _Pending] = OrderedDict()  # oldest first
        self._handshaking: set[_Splice] = set()  # spliced, the upstream's answer not yet back
        self._clients: set[_Splice] = set()
        self._upstream: tuple[str, int] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._closed = False

    # --- figures (read from any thread: about) -------------------------------------------------------------------

    @property
    def pending(self) -> int:
        return len(self._pending) + len(self._handshaking)

    @property
    def clients(self) -> int:
        return len(self._clients)

    @property
    def refused(self) -> Counter[str]:
        return self.refusals.total

    # --- life cycle -------------------------------------------------------------------------------------------------

    def start(self, upstream: tuple[str, int]) -> None:
        """Serve on a thread of its own, splicing to ``upstream``; returns once it accepts."""
        self._upstream = upstream
        loop = self._loop = asyncio.SelectorEventLoop(selectors.DefaultSelector())  # (why: module docstring)
        ready = threading.Event()

        def main() -> None:
            asyncio.set_event_loop(loop)
            loop.add_reader(self._sock.fileno(), self._accept)
            loop.call_later(SWEEP_S, self._sweep)
            loop.call_soon(ready.set)
            try:
                loop.run_forever()
            finally:
                loop.run_until_complete(asyncio.sleep(0))  # (the transports' last callbacks)
                loop.close()

        self._thread = threading.Thread(target=main, name="term foxglove front", daemon=True)
        self._thread.start()
        ready.wait(5.0)

    def close(self, timeout: float = 5.0) -> None:
        if self._closed:
            return
        self._closed = True
        loop, thread = self._loop, self._thread
        if loop is None or thread is None or loop.is_closed():
            self._sock.close()
            return
        with contextlib.suppress(RuntimeError):  # (the loop already gone)
            loop.call_soon_threadsafe(self._shutdown)
        if thread is not threading.current_thread():
            thread.join(timeout)

    def _shutdown(self) -> None:
        loop = self._loop
        assert loop is not None
        loop.remove_reader(self._sock.fileno())
        self._sock.close()
        for p in list(self._pending.values()):
            self._drop(p)
        for s in list(self._handshaking | self._clients):
            s.abort()
        self.refusals.tick()
        loop.stop()

    # --- the pending connections: bare sockets ---------------------------------------------------------------------

    def _accept(self) -> None:
        loop = self._loop
        assert loop is not None
        for _ in range(ACCEPT_BATCH):
            try:
                conn, _ = self._sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:  # out of descriptors or memory: pause, do not spin
                if exc.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    self.refusals.note(f"cannot accept: {exc.strerror}")
                    loop.remove_reader(self._sock.fileno())
                    loop.call_later(ACCEPT_RETRY_S, self._resume)
                return  # (ECONNABORTED and the like: that client is gone)
            self.accepted += 1
            conn.setblocking(False)
            if self.pending >= self.max_pending and not self._evict():
                self._refuse(conn, REFUSED_PENDING)
                continue
            p = self._pending[conn] = _Pending(conn, time.monotonic() + self.pending_timeout_s)
            loop.add_reader(conn.fileno(), self._read_head, p)

    def _resume(self) -> None:
        if not self._closed and self._loop is not None:
            self._loop.add_reader(self._sock.fileno(), self._accept)

    def _evict(self) -> bool:
        """Drop the oldest pending connection that has not sent its whole head; False if there is none."""
        for p in self._pending.values():
            if not p.handed:
                self.refusals.note(EVICTED)
                self._drop(p)
                return True
        return False

    def _read_head(self, p: _Pending) -> None:
        try:
            data = p.sock.recv(4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:  # gone before its head
            self._drop(p)
            return
        p.head += data
        if b"\r\n\r\n" not in p.head:
            if len(p.head) > self.max_head:
                self._drop(p, HEAD_TOO_BIG)
            return
        assert self._loop is not None
        self._loop.remove_reader(p.sock.fileno())
        del self._pending[p.sock]
        if len(self._clients) + len(self._handshaking) >= self.max_clients:
            self._refuse(p.sock, TOO_MANY_CLIENTS)
            return
        p.handed = True
        splice = _Splice(self, p)
        self._handshaking.add(splice)
        self._loop.create_task(self._connect(splice))

    def _drop(self, p: _Pending, why: str | None = None) -> None:
        if self._pending.pop(p.sock, None) is not None and self._loop is not None:
            self._loop.remove_reader(p.sock.fileno())
        if why is not None:
            self._refuse(p.sock, why)
        else:
            p.sock.close()

    def _refuse(self, conn: socket.socket, why: str) -> None:
        self.refusals.note(why)
        with contextlib.suppress(OSError):
            conn.send(REFUSAL)  # a fresh socket's buffer holds it: never waits
        conn.close()

    def _sweep(self) -> None:
        """Drop the pending connections past their deadline (the oldest first: they are in order)."""
        if self._closed or self._loop is None:
            return
        now = time.monotonic()
        while self._pending:
            p = next(iter(self._pending.values()))
            if p.deadline > now:
                break
            self.refusals.note(TIMED_OUT)
            self._drop(p)
        for s in [s for s in self._handshaking if s.pending.deadline <= now]:
            self.refusals.note(TIMED_OUT)
            s.abort()
        self.refusals.tick()
        self._loop.call_later(SWEEP_S, self._sweep)

    # --- the splice ------------------------------------------------------------------------------------------------

    async def _connect(self, splice: _Splice) -> None:
        loop, p = self._loop, splice.pending
        assert loop is not None and self._upstream is not None
        try:  # the upstream first: nothing comes from it before the head, and the client's bytes have a way on
            await loop.create_connection(lambda: splice.up, *self._upstream)
            await loop.connect_accepted_socket(lambda: splice.down, sock=p.sock)
        except OSError:
            self.refusals.note(UPSTREAM)
            splice.abort()
            p.sock.close()
            return
        if splice.closed:  # the client left (or timed out) meanwhile
            splice.abort()
            return
        assert splice.up.transport is not None
        splice.up.transport.write(bytes(p.head))
        p.head.clear()

    def _handshaken(self, splice: _Splice) -> None:
        if splice in self._handshaking:
            self._handshaking.discard(splice)
            self._clients.add(splice)

    def _gone(self, splice: _Splice) -> None:
        self._handshaking.discard(splice)
        self._clients.discard(splice)
