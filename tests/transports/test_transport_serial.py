"""SerialTransport on a real pseudo-terminal (pyserial opens the slave like any serial device), and its errors.

Where real I/O needs waiting, tests wait on a condition with a timeout, never a fixed sleep.
"""

from __future__ import annotations

import asyncio
import fcntl
import os
import struct
import termios
import time

import pytest

from term.core.protocol import Decoder, Encoder, Joystick
from term.transports.base import TransportClosed, TransportError
from term.transports.serial import SerialTransport


async def read_until(t: SerialTransport, n: int, timeout: float = 5.0) -> bytes:
    got = b""
    async with asyncio.timeout(timeout):
        while len(got) < n:
            got += await t.read()
    return got


async def test_bytes_both_ways_over_a_pty(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    t = SerialTransport(path)
    await t.open()
    try:
        assert path in t.name
        await t.write(b"hello board\x00")
        got = b""
        async with asyncio.timeout(5):
            while len(got) < 12:
                got += await asyncio.to_thread(os.read, master, 100)
        assert got == b"hello board\x00"
        payload = bytes(range(256)) * 8  # every byte value, raw: no echo, no CR/LF translation
        os.write(master, payload)
        assert await read_until(t, len(payload)) == payload
    finally:
        await t.close()


async def test_missing_port_is_one_clear_line() -> None:
    t = SerialTransport("/dev/ttyNOSUCHPORT9")
    with pytest.raises(TransportError) as exc:
        await t.open()
    msg = str(exc.value)
    assert msg == "serial port /dev/ttyNOSUCHPORT9 not found: check the cable and the name (ls /dev/tty*)"
    assert exc.value.__cause__ is None and exc.value.__suppress_context__  # no chained traceback


async def test_busy_port_is_refused(pty_pair: tuple[int, str]) -> None:
    _, path = pty_pair
    first = SerialTransport(path)
    await first.open()
    try:
        with pytest.raises(TransportError, match=r"is busy: another program has it open") as exc:
            await SerialTransport(path).open()
        assert "\n" not in str(exc.value)
    finally:
        await first.close()
    again = SerialTransport(path)  # closing released the lock
    await again.open()
    await again.close()


async def test_not_a_serial_device(tmp_path: os.PathLike[str]) -> None:
    plain = os.path.join(tmp_path, "notes.txt")
    with open(plain, "w") as f:
        f.write("not a tty\n")
    for path in (plain, str(tmp_path)):
        with pytest.raises(TransportError, match="is not a serial port") as exc:
            await SerialTransport(path).open()
        assert "\n" not in str(exc.value)


async def test_peer_closing_mid_session_is_a_transport_error(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    t = SerialTransport(path)
    await t.open()
    try:
        os.write(master, b"abc")
        assert await read_until(t, 3) == b"abc"
        reader = asyncio.create_task(t.read())  # blocked in the reader thread when the board goes away
        await asyncio.sleep(0)
        os.close(master)
        with pytest.raises(TransportError, match=f"serial port {path} lost") as exc:
            await asyncio.wait_for(reader, 5.0)
        assert not isinstance(exc.value, TransportClosed) and "\n" not in str(exc.value)
        with pytest.raises(TransportError):  # every later call says the same
            await t.read()
        with pytest.raises(TransportError):
            await t.write(b"x")
    finally:
        await t.close()


async def test_close_is_prompt_with_a_read_pending_and_idempotent(pty_pair: tuple[int, str]) -> None:
    _, path = pty_pair
    t = SerialTransport(path)
    await t.open()
    reader = asyncio.create_task(t.read())
    await asyncio.sleep(0)
    start = time.monotonic()
    await asyncio.wait_for(t.close(), 2.0)  # a hang here fails the test instead of blocking the suite
    await t.close()
    with pytest.raises(TransportClosed):
        await asyncio.wait_for(reader, 2.0)
    assert time.monotonic() - start < 2.0
    with pytest.raises(TransportClosed):
        await t.write(b"x")
    with pytest.raises(TransportClosed):
        await t.read()
    assert t._thread is None  # the reader thread was joined, not left behind


async def test_write_to_a_peer_that_never_reads_times_out_cleanly(pty_pair: tuple[int, str]) -> None:
    _, path = pty_pair
    t = SerialTransport(path, write_timeout=0.2)
    await t.open()
    try:
        with pytest.raises(TransportError, match="not reading") as exc:
            async with asyncio.timeout(10):
                while True:  # fill the pty's buffer: the master side is never read
                    await t.write(b"\x55" * 4096)
        assert "\n" not in str(exc.value)
    finally:
        await asyncio.wait_for(t.close(), 2.0)


async def test_event_loop_stays_free_while_the_port_is_idle(pty_pair: tuple[int, str]) -> None:
    _, path = pty_pair
    t = SerialTransport(path)
    await t.open()
    reader = asyncio.create_task(t.read())
    ticks = 0
    for _ in range(20):  # the loop keeps running other work while a read is pending
        await asyncio.sleep(0)
        ticks += 1
    assert ticks == 20 and not reader.done()
    await t.close()
    with pytest.raises(TransportClosed):
        await reader


# --- hand-overs end at a frame's end; writes from the loop --------------------------------------------------


def unread(path: str) -> int:
    """Bytes the reader thread has not taken from the port yet (the slave side's input queue)."""
    fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]
    finally:
        os.close(fd)


async def taken(path: str) -> None:
    async with asyncio.timeout(5):
        while unread(path):
            await asyncio.sleep(0.001)


async def test_a_frame_split_across_chunks_is_handed_over_whole(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    t = SerialTransport(path, hold=30.0)  # nothing is handed over for lack of time here
    await t.open()
    try:
        enc = Encoder()
        a, b = enc.encode(Joystick(1, 2, 3, 4000, 0)), enc.encode(Joystick(5, 6, 7, 8000, 0))
        os.write(master, a[:6])  # half a frame: the reader takes it, the loop is not woken for it
        await taken(path)
        os.write(master, a[6:] + b[:4])  # the rest of the first frame and the start of the next
        await taken(path)
        assert await asyncio.wait_for(t.read(), 5) == a  # the whole first frame, and only it
        os.write(master, b[4:])
        assert await asyncio.wait_for(t.read(), 5) == b
        got = Decoder().feed(a + b)
        assert [p.lift for p in got] == [4000, 8000]
    finally:
        await t.close()


async def test_bytes_without_a_frame_end_are_handed_over_after_the_hold(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    t = SerialTransport(path, hold=0.05)
    await t.open()
    try:
        os.write(master, b"another protocol")  # no 0x00: not our frames, but the bytes still arrive
        assert await read_until(t, 16) == b"another protocol"
    finally:
        await t.close()
    t = SerialTransport(path, frame_end=None, hold=30.0)  # no framing: every chunk as it comes
    await t.open()
    try:
        os.write(master, b"abc")
        assert await asyncio.wait_for(t.read(), 5) == b"abc"
    finally:
        await t.close()


async def test_a_write_larger_than_the_os_buffer_arrives_whole_and_in_order(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    t = SerialTransport(path)
    await t.open()
    got = bytearray()
    payload = bytes(range(1, 256)) * 1024  # 255 KB: the OS takes part at once, a worker thread the rest

    def drain() -> None:
        while len(got) < len(payload) + 3:
            got.extend(os.read(master, 65536))

    try:
        reader = asyncio.create_task(asyncio.to_thread(drain))
        await asyncio.wait_for(t.write(payload), 10)
        await asyncio.wait_for(t.write(b"end"), 5)  # a small write after it waits its turn
        await asyncio.wait_for(reader, 10)
        assert bytes(got) == payload + b"end"
    finally:
        await t.close()
