"""A serial port (the board's UART over USB, or a pseudo-terminal from ``fcb-sim``) as a Transport, via pyserial.

A port may be one of pyserial's URLs too (``socket://HOST:PORT``, ``rfc2217://HOST:PORT``, ``loop://``): a board
behind a serial-over-network server, or ``fcb-sim serve --tcp`` where there are no pseudo-terminals. The same
codec and the same reader run over them; only the waiting differs (below, "URL ports").

Reads: one dedicated reader thread per port does the blocking ``read`` and hands the bytes to the event loop
with ``call_soon_threadsafe``. Chosen over ``run_in_executor`` per read because (1) ``close`` can wake the
thread with pyserial's ``cancel_read`` and join it, so closing never hangs on a blocked read and leaves no
executor worker stuck in a read after the task awaiting it was cancelled; (2) the port is drained as soon as
bytes arrive, with one thread hop per hand-over and no executor round trip per read; (3) it works the same on
Windows, where the loop cannot watch a COM port handle.

Hand-overs end at a frame's end where they can (``frame_end``, the protocol's 0x00 delimiter; None: every chunk
as it comes). The board's UART sends a frame as its bytes leave the wire, so about half the chunks a pty or a USB
adapter delivers hold no frame end at all: the link can do nothing with them but wait for the rest. The reader
keeps the bytes after the last frame end until more arrive and hands them over with the chunk that completes
their frame, so every frame reaches the loop at the moment its last byte is read, as before, with half the
wake-ups (at full telemetry about 140 instead of 310 a second: term's link costs a few % of a core less). Bytes
that are not followed by a frame end within ``hold`` seconds (another protocol, line noise) are handed over then.
Holding needs ``select`` on the port (POSIX); elsewhere every chunk goes at once.

Writes: a write is a few dozen bytes that the OS buffer takes at once. On POSIX pyserial's port is non-blocking,
so the loop writes what the OS takes directly (no thread hop: a joystick frame leaves about 0.1-0.3 ms sooner);
whatever does not fit (a peer that stops reading, a stuck pty) is written by a worker thread
(``asyncio.to_thread``) with a ``write_timeout``, so the loop never blocks. A lock serialises writes so frames
never interleave.

URL ports: ``socket://`` has no ``cancel_read`` and answers ``in_waiting`` with 0 or 1, so its reader waits with
``select`` on the socket (which Windows has for sockets too) and reads what is there in one go (timeout 0); closing
shuts the socket, which wakes it; its writes go from the loop as a pty's do (the socket is non-blocking), with
TCP_NODELAY (Nagle's algorithm would hold a frame until the previous one's ACK). Other URL handlers (rfc2217://)
read one byte with a short timeout and then what is waiting, so a close is seen within ``URL_POLL_S``; rfc2217://
has no write timeout, and its writes go through the worker thread (pyserial's own write).

Every failure (missing, busy, not a serial device, no permission, lost mid-session) becomes a TransportError
with one line naming the port and what to do.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import os
import select
import socket
import threading

import serial

from term.core.protocol import BAUD_RATE
from term.transports.base import Transport, TransportClosed, TransportError

_CHUNK = 4096
URL_POLL_S = 0.1  # a URL port without a socket to wait on (rfc2217://) reads with this timeout


def is_url(port: str) -> bool:
    """pyserial's URL ports (socket://, rfc2217://, loop://, spy://): not a device path (a COM name has no ://)."""
    return "://" in port


def _open_error(port: str, exc: BaseException) -> TransportError:
    """One line for a failure to open ``port``, from pyserial's exception (its errno where it carries one)."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    if is_url(port):  # no cable, no dialout group: the network's words
        first = text.splitlines()[0] if text else type(exc).__name__
        return TransportError(f"cannot reach {port}: {first.removeprefix(f'Could not open port {port}: ')} (is the "
                              "board's server running there, e.g. fcb-sim serve --tcp?)")
    if code == errno.ENOENT or "No such file" in text:
        return TransportError(f"serial port {port} not found: check the cable and the name (ls /dev/tty*)")
    if code in (errno.EAGAIN, errno.EBUSY) or "exclusively lock" in text:
        return TransportError(f"serial port {port} is busy: another program has it open; close that first")
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return TransportError(
            f"no permission to open serial port {port}: add yourself to the 'dialout' group and log in again"
        )
    if code in (errno.EISDIR, errno.ENOTTY) or "Inappropriate ioctl" in text or "Is a directory" in text:
        return TransportError(f"{port} is not a serial port: give the board's device, e.g. /dev/ttyUSB0")
    first = text.splitlines()[0] if text else type(exc).__name__
    return TransportError(f"cannot open serial port {port}: {first}")


class SerialTransport(Transport):
    """``SerialTransport("/dev/ttyUSB0")``: 8N1 at ``baud``, exclusive access, no flow control. ``frame_end`` and
    ``hold``: reads end at a frame end where they can (module docstring)."""

    movable = True  # pyserial's port and the reader thread work with whichever loop opens them

    def __init__(self, port: str, baud: int = BAUD_RATE, *, write_timeout: float = 1.0,
                 frame_end: bytes | None = b"\x00", hold: float = 0.01) -> None:
        self.port = self.address = port
        self.baud = baud
        self.write_timeout = write_timeout
        self.frame_end = frame_end
        self.hold = hold
        self.name = f"serial {port} @ {baud}"
        self._serial: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._queue: asyncio.Queue[bytes | TransportError] = asyncio.Queue()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._closed = False
        self._error: TransportError | None = None
        self._write_lock = asyncio.Lock()
        self._fd: int | None = None  # the port's non-blocking descriptor (POSIX): small writes go from the loop
        self._sock: socket.socket | None = None  # a socket:// port's socket (non-blocking): the same, with send
        self.url = is_url(port)
        self._os_write_lock = threading.Lock()  # also orders a write whose awaiting task was cancelled

    async def open(self) -> None:
        if self._serial is not None:
            return
        self._loop = asyncio.get_running_loop()
        self._queue = asyncio.Queue()
        self._error = None
        try:
            # Opening configures termios: quick, but a device can stall it, so it runs off the loop too.
            self._serial = await asyncio.to_thread(self._open_port)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise _open_error(self.port, exc) from None
        self._closed = False
        self._fd = None if self.url else _nonblocking_fd(self._serial)
        self._sock = _socket_of(self._serial)
        if self._sock is not None:  # a frame leaves when it is written (Nagle would hold it for the last one's ACK)
            with contextlib.suppress(OSError):
                self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        target = self._url_reader if self.url else self._reader
        self._thread = threading.Thread(target=target, name=f"serial-reader {self.port}", daemon=True)
        self._thread.start()

    @property
    def is_open(self) -> bool:
        return self._serial is not None

    def _open_port(self) -> serial.Serial:
        if self.url:  # (the timeout: module docstring, "URL ports")
            # rfc2217:// has no write timeout (it refuses one only after connecting, leaving that connection open)
            rfc2217 = self.port.lower().startswith("rfc2217://")
            ser = serial.serial_for_url(self.port, self.baud, timeout=0,
                                        write_timeout=None if rfc2217 else self.write_timeout)
            if _socket_of(ser) is None:
                ser.timeout = URL_POLL_S
            return ser
        return serial.Serial(
            self.port,
            self.baud,
            timeout=None,
            write_timeout=self.write_timeout,
            exclusive=True,
        )

    def _reader(self) -> None:
        """The reader thread: block in read, hand the bytes (or the one error) to the loop, up to the last frame
        end where there is one."""
        ser = self._serial
        assert ser is not None and self._loop is not None
        put = self._queue.put_nowait
        end = self.frame_end
        fd = self._fd if end else None  # holding waits on the port with select (POSIX)
        tail = b""  # bytes after the last frame end, waiting for the rest of their frame
        try:
            while not self._closed:
                if tail and fd is not None:
                    ready, _, _ = select.select([fd], [], [], self.hold)
                    if not ready:  # the rest did not come: hand over what there is
                        self._loop.call_soon_threadsafe(put, tail)
                        tail = b""
                        continue
                # Block for the first byte, then take whatever else is already there in one go.
                data = ser.read(1)
                if not data:  # cancel_read() from close()
                    break
                waiting = ser.in_waiting
                if waiting:
                    data += ser.read(min(waiting, _CHUNK))
                if fd is not None:
                    data = tail + data
                    i = data.rfind(end)
                    cut = i + len(end) if i >= 0 else 0
                    if cut == 0 and len(data) < _CHUNK:
                        tail = data  # not one whole frame yet: no wake-up for the loop
                        continue
                    if 0 < cut < len(data):
                        data, tail = data[:cut], data[cut:]
                    else:
                        tail = b""
                self._loop.call_soon_threadsafe(put, data)
        except Exception as exc:  # any failure of the port ends the link with one message
            if not self._closed:
                err = TransportError(self._lost(exc))
                try:
                    self._loop.call_soon_threadsafe(put, err)
                except RuntimeError:
                    pass  # the loop is already closed: nobody is left to tell

    def _url_reader(self) -> None:
        """The reader thread of a URL port (module docstring): wait for bytes, take what is there, hand it over up
        to the last frame end as ``_reader`` does."""
        ser = self._serial
        assert ser is not None and self._loop is not None
        put = self._queue.put_nowait
        sock = _socket_of(ser)
        end = self.frame_end
        tail = b""
        try:
            while not self._closed:
                if sock is not None:
                    ready, _, _ = select.select([sock], [], [], self.hold if tail and end else None)
                    data = ser.read(_CHUNK) if ready else b""  # timeout 0: what is there (b"" at EOF raises)
                else:  # one byte with URL_POLL_S's timeout (read(_CHUNK) would wait for all of them), then the rest
                    data = ser.read(1)
                    waiting = ser.in_waiting if data else 0
                    if waiting:
                        data += ser.read(min(waiting, _CHUNK))
                if not data:
                    if tail:  # the rest did not come: hand over what there is
                        self._loop.call_soon_threadsafe(put, tail)
                        tail = b""
                    continue
                if end:
                    data = tail + data
                    cut = data.rfind(end) + len(end) if end in data else 0
                    data, tail = data[:cut], data[cut:]
                    if not data and len(tail) < _CHUNK:
                        continue
                    if not data:
                        data, tail = tail, b""
                self._loop.call_soon_threadsafe(put, data)
        except Exception as exc:  # any failure of the port ends the link with one message
            if not self._closed:
                err = TransportError(self._lost(exc))
                with contextlib.suppress(RuntimeError):  # the loop is already closed: nobody is left to tell
                    self._loop.call_soon_threadsafe(put, err)

    async def read(self) -> bytes:
        if self._error is not None:
            raise self._error
        if self._closed or self._serial is None:
            raise TransportClosed(f"{self.name} is closed")
        item = await self._queue.get()
        if isinstance(item, TransportError):
            self._error = item
            raise item
        return item

    async def write(self, data: bytes) -> None:
        if self._error is not None:
            raise self._error
        if self._closed or self._serial is None:
            raise TransportClosed(f"{self.name} is closed")
        async with self._write_lock:
            if self._fd is not None or self._sock is not None:
                data = self._write_now(data)
                if not data:
                    return  # all of it taken at once, from the loop (the usual case)
            try:
                await asyncio.to_thread(self._write_blocking, data)
            except serial.SerialTimeoutException:
                self._error = TransportError(
                    f"serial port {self.port}: write timed out after {self.write_timeout} s: "
                    "the other end is not reading"
                )
                raise self._error from None
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                if self._closed:
                    raise TransportClosed(f"{self.name} is closed") from None
                self._error = TransportError(self._lost(exc))
                raise self._error from None

    def _lost(self, exc: BaseException) -> str:
        """The one line for a port that died in use: a cable's, or a network server's."""
        if self.url:
            return f"{self.port} lost: {_reason(exc)}; is the board's server still running?"
        return f"serial port {self.port} lost: {_reason(exc)}; check the cable and reconnect"

    def _write_now(self, data: bytes) -> bytes:
        """Write what the OS takes at once from the loop's own thread (the port is non-blocking); returns the
        rest, for the worker thread. Skipped while a worker still writes (a cancelled write's thread)."""
        if not self._os_write_lock.acquire(blocking=False):
            return data
        try:
            n = self._sock.send(data) if self._sock is not None else os.write(self._fd, data)  # type: ignore[arg-type]
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError as exc:
            if self._closed:
                raise TransportClosed(f"{self.name} is closed") from None
            self._error = TransportError(self._lost(exc))
            raise self._error from None
        finally:
            self._os_write_lock.release()
        return data[n:]

    def _write_blocking(self, data: bytes) -> None:
        with self._os_write_lock:
            ser = self._serial
            if ser is None or not ser.is_open:
                raise serial.SerialException("port closed")
            ser.write(data)

    async def close(self) -> None:
        if self._closed and self._serial is None:
            return
        self._closed = True
        self._fd = None
        self._sock = None
        ser = self._serial
        if ser is not None and self.url:  # no cancel_read: closing the port wakes the reader (pyserial's socket
            with self._os_write_lock:  # close also pauses 0.3 s for "quick reconnects": off the loop)
                with contextlib.suppress(OSError, serial.SerialException):
                    await asyncio.to_thread(ser.close)
        elif ser is not None:
            try:
                ser.cancel_read()
                ser.cancel_write()
            except (OSError, serial.SerialException):
                pass
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            await asyncio.to_thread(thread.join, 1.0)
        self._thread = None
        if ser is not None:
            with self._os_write_lock:
                try:
                    ser.close()
                except (OSError, serial.SerialException):
                    pass
        self._serial = None
        # Wake a reader waiting on the queue: it sees the stop as TransportClosed.
        self._queue.put_nowait(TransportClosed(f"{self.name} is closed"))


def _reason(exc: BaseException) -> str:
    """The gist of a pyserial/OS error on a live port, as a short phrase."""
    text = str(exc)
    if (isinstance(exc, OSError) and exc.errno == errno.EIO) or "Input/output error" in text:
        return "input/output error (the device went away)"
    if "returned no data" in text:
        return "the device disconnected"
    return text.splitlines()[0] if text else type(exc).__name__


def _nonblocking_fd(ser: serial.Serial) -> int | None:
    """The port's file descriptor if it is a non-blocking one (pyserial's POSIX ports are), else None."""
    fd = getattr(ser, "fd", None)
    if not isinstance(fd, int):
        return None
    try:
        import fcntl

        return fd if fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_NONBLOCK else None
    except (ImportError, OSError):
        return None


def _socket_of(ser: serial.SerialBase) -> socket.socket | None:
    """The socket under a socket:// port (pyserial keeps it as ``_socket``), or None: rfc2217:// has one too, but
    its own thread reads it (into a queue), so only ``read`` with a timeout can wait for its bytes."""
    if not str(ser.port or "").startswith("socket://"):
        return None
    sock = getattr(ser, "_socket", None)
    return sock if isinstance(sock, socket.socket) else None
