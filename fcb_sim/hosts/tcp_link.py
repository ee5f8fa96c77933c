"""`fcb-sim serve --tcp [HOST:]PORT`: the board's UART on a TCP port, for pyserial's ``socket://`` URL handler, where
there are no pseudo-terminals (Windows) or on request. ``TcpLink`` is the byte link; fcb_sim/hosts/serve.py's
``TcpServer`` runs the board over it. term flies it with the same serial transport and codec as a
pty or a USB cable (``term --serial socket://127.0.0.1:PORT``; ``term --sim`` takes this link by itself there).

The contract:
- Loopback only, unless ``public`` (``--tcp-public``): the board obeys whoever connects, and there is no login.
- One client at a time, as a UART has one PC: a further connection is accepted and closed at once (counted in
  ``refused``), never queued and never read, so a flood of connections costs the flight a few accept() calls.
- No descriptor the event loop's select() cannot watch is ever registered: a connection whose descriptor is at or
  above FD_SETSIZE is refused like a second client (serve uses select() on purpose: fcb_sim/hosts/serve.py,
  ``event_loop``). When accept() itself fails (no descriptors left), the listener rests for ``ACCEPT_REST_S``
  instead of waking the loop for the same pending connection without end.
- A client that leaves is the cable unplugged: what the board sends meanwhile is gone, as on a real UART; the
  next client starts with nothing stale (the unsent bytes are dropped when it connects).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import ipaddress
import logging
import socket
import sys
from collections.abc import Callable

from fcb_sim.errors import UsageError

log = logging.getLogger(__name__)

SELECT_LIMIT = 1024  # FD_SETSIZE of select() on Linux and macOS (Windows counts sockets, not their numbers)
ACCEPT_REST_S = 0.5  # accept() failed for want of descriptors: the listener is not watched for this long


def parse_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (an IPv6 host in brackets) as (host, port); the host defaults to 127.0.0.1. UsageError."""
    host, sep, port_text = text.rpartition(":")
    host = host.strip("[]") if sep else "127.0.0.1"
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535 or not host:
        raise UsageError(f"--tcp {text!r}: give [HOST:]PORT, e.g. 127.0.0.1:5760 (port 0: a free one)")
    return host, port


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class TcpLink:
    """The listening port and its one client (module docstring); ``path`` is the ``socket://`` URL a client opens.
    ``start(loop, on_readable, on_connect)`` watches it on the loop: ``on_readable`` when the client sent bytes
    (read them with ``recv``), ``on_connect`` when a new client arrived."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, public: bool = False,
                 read_bytes: int = 4096) -> None:
        if not public and not is_loopback(host):
            raise UsageError(f"--tcp {host}:{port} listens beyond this computer, and whoever connects flies the "
                             "board: add --tcp-public to mean it, or use 127.0.0.1")
        try:
            family = socket.AF_INET6 if ":" in host else socket.AF_INET
            # backlog: a burst of connections waits in the kernel to be closed, not dropped into SYN retries
            self.listener = socket.create_server((host, port), family=family, backlog=64)
        except OSError as exc:
            raise UsageError(f"--tcp {host}:{port}: cannot listen there: {exc.strerror or exc}") from None
        self.listener.setblocking(False)
        bound = self.listener.getsockname()
        shown = f"[{bound[0]}]" if ":" in bound[0] else bound[0]
        self.path = f"socket://{shown}:{bound[1]}"
        self.public = public
        self.read_bytes = read_bytes
        self.closed = False
        self.client: socket.socket | None = None
        self.clients = 0  # connections served
        self.refused = 0  # connections closed at once (a second client, a descriptor select() cannot watch)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._resting: asyncio.TimerHandle | None = None
        self._on_readable: Callable[[], None] = lambda: None
        self._on_connect: Callable[[], None] = lambda: None

    def start(self, loop: asyncio.AbstractEventLoop, on_readable: Callable[[], None],
              on_connect: Callable[[], None]) -> None:
        self._loop = loop
        self._on_readable, self._on_connect = on_readable, on_connect
        loop.add_reader(self.listener, self._on_accept)

    def stop(self, loop: asyncio.AbstractEventLoop) -> None:
        if self._resting is not None:
            self._resting.cancel()
            self._resting = None
        with contextlib.suppress(ValueError, OSError):
            loop.remove_reader(self.listener)
        self._drop_client()

    def _on_accept(self) -> None:
        while True:
            try:
                conn, peer = self.listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    self._rest()
                return
            if self.client is not None or (sys.platform != "win32" and conn.fileno() >= SELECT_LIMIT):
                self.refused += 1
                conn.close()
                continue
            conn.setblocking(False)
            with contextlib.suppress(OSError):
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # a frame leaves when it is written
            self.client = conn
            self.clients += 1
            self._on_connect()
            assert self._loop is not None
            self._loop.add_reader(conn, self._on_readable)
            log.info("TCP client %s connected", peer)

    def _rest(self) -> None:
        """No descriptor for accept(): stop watching the listener for a while (it would wake the loop at once)."""
        loop = self._loop
        if loop is None or self._resting is not None:
            return
        loop.remove_reader(self.listener)

        def again() -> None:
            self._resting = None
            if not self.closed:
                loop.add_reader(self.listener, self._on_accept)

        self._resting = loop.call_later(ACCEPT_REST_S, again)

    def _drop_client(self) -> None:
        conn, self.client = self.client, None
        if conn is None:
            return
        if self._loop is not None:
            with contextlib.suppress(ValueError, OSError):
                self._loop.remove_reader(conn)
        with contextlib.suppress(OSError):
            conn.close()
        log.info("TCP client gone")

    def recv(self) -> bytes | None:
        conn = self.client
        if conn is None:
            return None
        try:
            data = conn.recv(self.read_bytes)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            data = b""
        if not data:  # the client left: the cable is out
            self._drop_client()
            return None
        return data

    def send(self, data: bytes | bytearray) -> int:
        conn = self.client
        if conn is None:
            return len(data)  # nobody there: the bytes are gone, as on a real unplugged UART
        try:
            return conn.send(data)
        except (BlockingIOError, InterruptedError):
            return 0
        except OSError:
            self._drop_client()
            return len(data)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self._loop is not None and not self._loop.is_closed():
            with contextlib.suppress(Exception):
                self.stop(self._loop)
        self._drop_client()
        with contextlib.suppress(OSError):
            self.listener.close()
