"""The MAVLink endpoint's socket (term/data/mavlink.py): the address a user gives, the socket to the ground station
and the thread that reads it. Bytes only: no MAVLink here.

- ``parse_address("[udp:|tcp:]HOST:PORT", public)``: (kind, host, port); ``MavlinkError`` (one line) if malformed,
  or if HOST is not this machine (loopback) and not ``public``.
- ``GroundSocket``: UDP sends to HOST:PORT from a port of its own and, connected, reads only that peer's datagrams
  (a datagram never blocks: one the kernel cannot take is dropped); TCP connects to a ground station listening
  there, again every second while it is gone, writes what the socket takes and keeps a bounded rest
  (``BACKLOG_MAX``) for the thread to finish, dropping whole writes beyond it. ``write(data)`` from any thread,
  never blocks, says whether it went. ``start(on_data, on_tick)``: the thread ``term mavlink`` calls
  ``on_data(bytes)`` for what arrives and ``on_tick(now)`` at least every ``TICK_S``; ``close()`` ends it.
"""

from __future__ import annotations

import contextlib
import ipaddress
import logging
import select
import socket
import threading
import time
from collections.abc import Callable

log = logging.getLogger("term.mavlink")
TICK_S = 0.05  # the thread's timers run at least this often
BACKLOG_MAX = 64 * 1024  # TCP bytes the socket did not take yet; whole writes beyond it are dropped
RECONNECT_S = 1.0  # TCP: a ground station that is not there is tried again this often


class MavlinkError(ValueError):
    """The endpoint cannot start; the message is one line."""


def parse_address(text: str, public: bool = False) -> tuple[str, str, int]:
    """``[udp:|tcp:]HOST:PORT`` (or PORT alone: loopback) to (kind, host, port) (module docstring)."""
    shown = repr(text[:40]) + (f"... ({len(text)} characters)" if len(text) > 40 else "")
    kind, _, rest = text.partition(":") if text.split(":", 1)[0] in ("udp", "tcp") else ("udp", "", text)
    host, sep, port_text = rest.rpartition(":")
    host = host.strip("[]") if sep else "127.0.0.1"
    try:
        port = int(port_text)
    except ValueError:
        raise MavlinkError(f"--mavlink takes [udp:|tcp:]HOST:PORT, e.g. 127.0.0.1:14550; got {shown}") from None
    if not 0 < port <= 65535 or not host:
        raise MavlinkError(f"--mavlink: a host and a port 1..65535, e.g. udp:127.0.0.1:14550; got {shown}")
    if not public and not _loopback(host):
        raise MavlinkError(f"--mavlink {shown}: not this machine; the flight leaves it only with --mavlink-public")
    return kind, host, port


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a name: it may be anywhere


class GroundSocket:
    """One ground station's socket and its reading thread (module docstring)."""

    def __init__(self, kind: str, host: str, port: int, clock: Callable[[], float] = time.monotonic) -> None:
        self.kind, self.host, self.port = kind, host, port
        self.clock = clock
        self._lock = threading.Lock()  # writes from any thread
        self._sock: socket.socket | None = None
        self._backlog = bytearray()  # TCP: what the socket did not take yet
        self._closed = False
        self._thread: threading.Thread | None = None
        try:
            info = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM if kind == "udp" else socket.SOCK_STREAM)[0]
        except OSError as exc:
            raise MavlinkError(f"--mavlink {host}: {exc.strerror or exc}") from None
        self._family, self._addr = info[0], info[4]
        if kind == "udp":
            s = socket.socket(self._family, socket.SOCK_DGRAM)
            s.setblocking(False)
            try:
                s.connect(self._addr)  # only this peer's datagrams are read
            except OSError as exc:
                s.close()
                raise MavlinkError(f"--mavlink {self.url}: {exc.strerror or exc}") from None
            self._sock = s
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.kind}:{host}:{self.port}"

    @property
    def connected(self) -> bool:
        return self._sock is not None

    def write(self, data: bytes) -> bool:
        """UDP: one datagram; TCP: what the socket takes now, the rest kept (bounded). Never blocks."""
        with self._lock:
            s = self._sock
            if s is None or self._closed:
                return False
            try:
                if self.kind == "udp":
                    s.send(data)
                    return True
                if self._backlog:
                    return self._keep(data)
                n = s.send(data)
                if n < len(data):
                    self._backlog += data[n:]
                    self._wake()
                return True
            except BlockingIOError:
                return self.kind == "tcp" and self._keep(data)
            except ConnectionRefusedError:  # UDP: nobody listens there (yet)
                return False
            except OSError:
                if self.kind == "tcp":
                    self._drop()
                return False

    def _keep(self, data: bytes) -> bool:
        if len(self._backlog) + len(data) > BACKLOG_MAX:
            return False
        self._backlog += data
        self._wake()
        return True

    def _drop(self) -> None:
        """(Under the lock.) The TCP connection is gone: closed here, tried again by the thread."""
        s, self._sock = self._sock, None
        self._backlog.clear()
        if s is not None:
            with contextlib.suppress(OSError):
                s.close()

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")

    # --- the thread -------------------------------------------------------------------------------------------

    def start(self, on_data: Callable[[bytes], None], on_tick: Callable[[float], None]) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, args=(on_data, on_tick), name="term mavlink",
                                            daemon=True)
            self._thread.start()

    def close(self) -> None:
        self._closed = True
        self._wake()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        with self._lock:
            if self._sock is not None:
                self._sock.close()
                self._sock = None
        for s in (self._wake_r, self._wake_w):
            s.close()

    def _run(self, on_data: Callable[[bytes], None], on_tick: Callable[[float], None]) -> None:
        while not self._closed:
            if self.kind == "tcp" and self._sock is None:
                self._connect()
                if self._sock is None:
                    self._wait(RECONNECT_S)
                    continue
            try:
                on_tick(self.clock())
            except Exception:  # a timer's failure costs that tick, never the thread
                log.exception("MAVLink: a timer failed")
            s = self._sock
            try:
                readable, writable, _ = select.select([r for r in (s, self._wake_r) if r is not None],
                                                      [s] if s is not None and self._backlog else [], [], TICK_S)
            except (OSError, ValueError):  # closed under us
                if self._closed:
                    return
                with self._lock:
                    self._drop() if self.kind == "tcp" else None
                self._wait(0.1)
                continue
            if self._wake_r in readable:
                with contextlib.suppress(OSError):
                    self._wake_r.recv(4096)
            if s is not None and s in writable:
                self._flush()
            if s is not None and s in readable:
                data = self._read(s)
                if data:
                    on_data(data)

    def _connect(self) -> None:
        s = socket.socket(self._family, socket.SOCK_STREAM)
        s.settimeout(1.0)
        try:
            s.connect(self._addr)
        except OSError:
            s.close()
            return
        s.setblocking(False)
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._lock:
            self._backlog.clear()
            self._sock = s
        log.info("MAVLink: connected to %s", self.url)

    def _wait(self, seconds: float) -> None:
        with contextlib.suppress(OSError, ValueError):
            select.select([self._wake_r], [], [], seconds)

    def _flush(self) -> None:
        with self._lock:
            s = self._sock
            if s is None or not self._backlog:
                return
            try:
                n = s.send(self._backlog)
                del self._backlog[:n]
            except BlockingIOError:
                pass
            except OSError:
                self._drop()

    def _read(self, s: socket.socket) -> bytes:
        try:
            data = s.recv(65536)
        except (BlockingIOError, ConnectionRefusedError):
            return b""
        except OSError:
            data = b""
        if not data and self.kind == "tcp":  # closed by the ground station (or broken): connect again
            with self._lock:
                self._drop()
        return data
