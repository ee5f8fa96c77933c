"""term's serial transport over pyserial's URL ports, flying the real simulated board: ``socket://`` to
`fcb-sim serve --tcp` (as term --sim over TCP does), and ``rfc2217://`` through an RFC 2217 server (pyserial's own
PortManager, as ser2net's telnet mode) in front of the board's pseudo-terminal. The same transport and codec as a
cable: the board's frames arrive whole and decode, a command reaches the board, closing is prompt, and a server that
is not there is one line."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
from collections.abc import Callable, Iterator

import pytest
import serial
import serial.rfc2217

from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.core.protocol import Command, Decoder, Encoder, Mode, Op, Status
from term.session.sim import pty_missing
from term.transports.base import TransportError
from term.transports.serial import SerialTransport


async def fly_to_manual(transport: SerialTransport, board_mode: Callable[[], Mode]) -> None:
    """Read until the board's Status decodes, then send MODE MANUAL and wait for the board to take it."""
    dec = Decoder()
    async with asyncio.timeout(15):
        while not any(isinstance(p, Status) for p in dec.feed(await transport.read())):
            pass
        await transport.write(Encoder().encode(Command(1, Op.MODE, Mode.MANUAL)))
        while board_mode() != Mode.MANUAL:
            await asyncio.sleep(0.02)


async def test_socket_url_flies_the_board_served_on_tcp() -> None:
    board = make_board(seed=1)
    served = ThreadedServer(board, link="tcp")
    url = served.start()
    transport = SerialTransport(url)
    try:
        await transport.open()
        await fly_to_manual(transport, lambda: board.mode)
    finally:
        async with asyncio.timeout(5):  # prompt: the reader is woken by the socket's shutdown
            await transport.close()
        served.stop()


class PtyPort(serial.Serial):
    """A pty as the server's serial port: it has no modem lines, so the client's RTS and DTR settings are ignored."""

    def _update_rts_state(self) -> None:
        with contextlib.suppress(OSError):
            super()._update_rts_state()

    def _update_dtr_state(self) -> None:
        with contextlib.suppress(OSError):
            super()._update_dtr_state()

    def _update_break_state(self) -> None:
        with contextlib.suppress(OSError):
            super()._update_break_state()

    @property
    def cts(self) -> bool:  # (and no modem status lines: the RFC 2217 client asks for them)
        return False

    @property
    def dsr(self) -> bool:
        return False

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return False


@contextlib.contextmanager
def rfc2217_server(device: str) -> Iterator[str]:
    """An RFC 2217 server for one client in front of ``device`` (pyserial's PortManager, as its example server)."""
    port = PtyPort(device, timeout=0.05)
    listener = socket.create_server(("127.0.0.1", 0))
    alive = threading.Event()
    alive.set()

    class Net:
        def __init__(self, conn: socket.socket) -> None:
            self.conn = conn
            self.lock = threading.Lock()

        def write(self, data: bytes) -> None:
            with self.lock:
                self.conn.sendall(data)

    def serve() -> None:
        conn, _ = listener.accept()
        net = Net(conn)
        manager = serial.rfc2217.PortManager(port, net)

        def to_network() -> None:
            while alive.is_set():
                with contextlib.suppress(OSError, TypeError, serial.SerialException):  # (closed under it at the end)
                    data = port.read(port.in_waiting or 1)
                    if data:
                        net.write(b"".join(manager.escape(data)))

        threading.Thread(target=to_network, daemon=True).start()
        while alive.is_set():
            try:
                data = conn.recv(1024)
            except OSError:
                break
            if not data:
                break
            with contextlib.suppress(OSError, serial.SerialException):
                port.write(b"".join(manager.filter(data)))
        conn.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"rfc2217://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        alive.clear()
        listener.close()
        thread.join(5)
        port.close()


@pytest.mark.skipif(pty_missing() is not None, reason="the board behind the RFC 2217 server is on a pty")
@pytest.mark.filterwarnings("ignore:set(Daemon|Name)\\(\\) is deprecated:DeprecationWarning")  # (pyserial 3.5's own)
async def test_rfc2217_url_flies_the_board_behind_a_serial_server() -> None:
    board = make_board(seed=1)
    served = ThreadedServer(board)
    path = served.start()
    try:
        with rfc2217_server(path) as url:
            transport = SerialTransport(url)
            await transport.open()
            try:
                await fly_to_manual(transport, lambda: board.mode)
            finally:
                async with asyncio.timeout(5):
                    await transport.close()
    finally:
        served.stop()


async def test_a_server_that_is_not_there_is_one_line() -> None:
    with socket.create_server(("127.0.0.1", 0)) as s:
        port = s.getsockname()[1]  # closed again at once: nothing listens there
    transport = SerialTransport(f"socket://127.0.0.1:{port}")
    with pytest.raises(TransportError) as err:
        await transport.open()
    text = str(err.value)
    assert text.startswith(f"cannot reach socket://127.0.0.1:{port}: ") and "\n" not in text
    assert "fcb-sim serve --tcp" in text
