"""`fcb-sim serve --tcp`: the board's UART on a loopback TCP port for pyserial's socket:// (fcb_sim/hosts/tcp_link.py).
A pyserial client gets the board's frames and flies it; one client at a time (a further connection is closed at
once and the first flies on); a connection flood and a descriptor select() cannot watch are refused without harm;
the command line's refusals are one line."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable

import pytest
import serial

from fcb_sim.errors import UsageError
from fcb_sim.hosts.serve import ThreadedServer, make_board
from fcb_sim.hosts.tcp_link import SELECT_LIMIT, parse_address
from term.core.protocol import Command, Decoder, Encoder, Mode, Op, Status


def wait_for(cond: Callable[[], bool], timeout: float = 10.0) -> None:
    """Wait for ``cond``; the bound only ends a test that would hang."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def frames(port: serial.SerialBase, want: Callable[[object], bool], timeout: float = 10.0) -> list[object]:
    """Packets read from ``port`` until one passes ``want``."""
    dec = Decoder()
    got: list[object] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        got += dec.feed(port.read(256))
        if any(want(p) for p in got):
            return got
    raise AssertionError(f"no such packet in {len(got)}")


def test_a_pyserial_socket_client_flies_the_board_over_tcp() -> None:
    board = make_board(seed=1)
    served = ThreadedServer(board, link="tcp")
    url = served.start()
    try:
        assert url.startswith("socket://127.0.0.1:")
        port = serial.serial_for_url(url, timeout=0.2)
        frames(port, lambda p: isinstance(p, Status))  # the board's telemetry, through the same codec
        port.write(Encoder().encode(Command(1, Op.MODE, Mode.MANUAL)))
        wait_for(lambda: board.mode == Mode.MANUAL)
        port.close()
        wait_for(lambda: served.server.client is None)  # gone: the cable is out, the board's link timer runs
    finally:
        served.stop()


def test_one_client_at_a_time_and_a_flood_costs_the_flight_nothing() -> None:
    board = make_board(seed=1)
    served = ThreadedServer(board, link="tcp")
    url = served.start()
    host, port_text = url.removeprefix("socket://").rsplit(":", 1)
    try:
        first = serial.serial_for_url(url, timeout=0.2)
        frames(first, lambda p: isinstance(p, Status))
        second = socket.create_connection((host, int(port_text)), timeout=5)
        assert second.recv(64) == b""  # closed at once, never served
        second.close()
        flood = [socket.create_connection((host, int(port_text)), timeout=5) for _ in range(200)]
        wait_for(lambda: served.server.refused >= 201)
        for s in flood:
            s.close()
        frames(first, lambda p: isinstance(p, Status))  # the first client flies on
        first.write(Encoder().encode(Command(1, Op.MODE, Mode.MANUAL)))
        wait_for(lambda: board.mode == Mode.MANUAL)
        first.close()
    finally:
        served.stop()
    assert served.error is None


@pytest.mark.skipif(sys.platform == "win32", reason="select()'s FD_SETSIZE limit is POSIX's")
def test_a_connection_select_cannot_watch_is_refused_and_the_board_keeps_sending() -> None:
    import resource

    soft, _hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < SELECT_LIMIT + 64:
        pytest.skip(f"the descriptor limit {soft} is under FD_SETSIZE")
    board = make_board(seed=1)
    served = ThreadedServer(board, link="tcp")
    url = served.start()
    host, port_text = url.removeprefix("socket://").rsplit(":", 1)
    filler: list[int] = []
    try:
        while not filler or filler[-1] < SELECT_LIMIT + 8:  # the next descriptors are past what select() watches
            filler.append(os.open(os.devnull, os.O_RDONLY))
        late = socket.create_connection((host, int(port_text)), timeout=5)
        assert late.recv(64) == b""  # its accepted descriptor would be >= FD_SETSIZE: closed at once
        late.close()
        assert served.server.refused == 1 and served.error is None
        for fd in filler:
            os.close(fd)
        filler.clear()
        client = serial.serial_for_url(url, timeout=0.2)
        frames(client, lambda p: isinstance(p, Status))  # the loop never saw it: the board serves on
        client.close()
    finally:
        for fd in filler:
            os.close(fd)
        served.stop()
    assert served.error is None


@pytest.mark.parametrize("text, host, port", [("5760", "127.0.0.1", 5760), ("0.0.0.0:1", "0.0.0.0", 1),
                                              ("[::1]:9", "::1", 9)])
def test_the_address(text: str, host: str, port: int) -> None:
    assert parse_address(text) == (host, port)


@pytest.mark.parametrize("argv, words", [
    (["serve", "--tcp", "0.0.0.0:0"], "--tcp 0.0.0.0:0 listens beyond this computer"),
    (["serve", "--tcp", "nope"], "--tcp 'nope': give [HOST:]PORT"),
    (["serve", "--tcp", "0", "--pty"], "say where to serve the board: --pty"),
    (["serve"], "say where to serve the board: --pty"),
    (["serve", "--pty", "--tcp-public"], "--tcp-public needs --tcp"),
])
def test_serve_refuses_in_one_line(argv: list[str], words: str) -> None:
    out = subprocess.run([sys.executable, "-m", "fcb_sim", *argv], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and out.stderr.startswith("fcb-sim: ") and words in out.stderr, out.stderr
    assert out.stderr.count("\n") == 1


def test_serve_tcp_prints_its_url_first_and_a_bad_one_is_usage() -> None:
    with pytest.raises(UsageError):
        parse_address("70000")
    proc = subprocess.Popen([sys.executable, "-m", "fcb_sim", "serve", "--tcp", "127.0.0.1:0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline().strip()
        assert line.startswith("tcp: socket://127.0.0.1:")
        port = serial.serial_for_url(line.split()[1], timeout=0.2)
        frames(port, lambda p: isinstance(p, Status))
        port.close()
    finally:
        proc.terminate()
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0 and out.startswith("served ") and "Traceback" not in err
