"""A serial port (the board's UART over USB, or a pseudo-terminal from ``fcb-sim``) as a Transport, via pyserial.

Reads: one dedicated reader thread per port does the blocking ``read`` and hands each chunk to the event loop
with ``call_soon_threadsafe``. Chosen over ``run_in_executor`` per read because (1) ``close`` can wake the
thread with pyserial's ``cancel_read`` and join it, so closing never hangs on a blocked read and leaves no
executor worker stuck in a read after the task awaiting it was cancelled; (2) the port is drained as soon as
bytes arrive, with one thread hop per chunk and no executor round trip per read; (3) it works the same on
Windows, where the loop cannot watch a COM port handle.

Writes: a write is a few dozen bytes that the OS buffer takes at once, but a peer that stops reading (a stuck
pty) would block it; so writes run in a worker thread (``asyncio.to_thread``) with a ``write_timeout``,
serialised by a lock so frames never interleave.

Every failure (missing, busy, not a serial device, no permission, lost mid-session) becomes a TransportError
with one line naming the port and what to do.
"""

from __future__ import annotations

import asyncio
import errno
import threading

import serial

from term.transports.base import Transport, TransportClosed, TransportError

_CHUNK = 4096


def _open_error(port: str, exc: BaseException) -> TransportError:
    """One line for a failure to open ``port``, from pyserial's exception (its errno where it carries one)."""
    code = getattr(exc, "errno", None)
    text = str(exc)
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
    """``SerialTransport("/dev/ttyUSB0")``: 8N1 at ``baud``, exclusive access, no flow control."""

    def __init__(self, port: str, baud: int = 115200, *, write_timeout: float = 1.0) -> None:
        self.port = port
        self.baud = baud
        self.write_timeout = write_timeout
        self.name = f"serial {port} @ {baud}"
        self._serial: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._queue: asyncio.Queue[bytes | TransportError] = asyncio.Queue()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._closed = False
        self._error: TransportError | None = None
        self._write_lock = asyncio.Lock()
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
        self._thread = threading.Thread(target=self._reader, name=f"serial-reader {self.port}", daemon=True)
        self._thread.start()

    def _open_port(self) -> serial.Serial:
        return serial.Serial(
            self.port,
            self.baud,
            timeout=None,
            write_timeout=self.write_timeout,
            exclusive=True,
        )

    def _reader(self) -> None:
        """The reader thread: block in read, hand every chunk (or the one error) to the loop."""
        ser = self._serial
        assert ser is not None and self._loop is not None
        put = self._queue.put_nowait
        try:
            while not self._closed:
                # Block for the first byte, then take whatever else is already there in one go.
                data = ser.read(1)
                if not data:  # cancel_read() from close()
                    break
                waiting = ser.in_waiting
                if waiting:
                    data += ser.read(min(waiting, _CHUNK))
                self._loop.call_soon_threadsafe(put, data)
        except Exception as exc:  # any failure of the port ends the link with one message
            if not self._closed:
                err = TransportError(f"serial port {self.port} lost: {_reason(exc)}; check the cable and reconnect")
                try:
                    self._loop.call_soon_threadsafe(put, err)
                except RuntimeError:
                    pass  # the loop is already closed: nobody is left to tell

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
                self._error = TransportError(
                    f"serial port {self.port} lost: {_reason(exc)}; check the cable and reconnect"
                )
                raise self._error from None

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
        ser = self._serial
        if ser is not None:
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
