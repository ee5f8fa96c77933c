"""The live Foxglove server under a flood of connections (issue 36): its door (term/data/foxglove_front.py) holds
more idle connections than select() could watch while a ``--sim`` flight runs, and a real client still gets its
messages; the door's caps and time limit, each on its own."""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from term.core.protocol import Mode
from tests.support.waits import until

foxglove = pytest.importorskip("foxglove", reason="the foxglove extra (foxglove-sdk) is not installed")

FLOOD = 1100  # past FD_SETSIZE (1024): more than a select() loop could watch


def open_fds() -> int | None:
    with contextlib.suppress(OSError):
        return len(os.listdir("/proc/self/fd"))
    return None


@pytest.mark.skipif(sys.platform == "win32", reason="the flood process keeps its sockets with POSIX calls")
async def test_a_flood_of_idle_connections_beside_a_flight_costs_neither_the_flight_nor_a_client(
        tmp_path: Path) -> None:
    """1,100 idle connections, kept open by a process beside the flight (those the door drops are opened again):
    the door holds at most its cap of them, the process under test holds no descriptor for the rest, a client
    connected before goes on getting the attitudes, a client that connects during the flood gets in, and the link
    sees no LINK LOST."""
    from term.core.events import CABLE
    from term.data.foxglove_front import EVICTED
    from term.data.foxglove_server import LiveServer
    from term.data.recording import RecordingTransport
    from term.session.sim import SimBoard
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp
    from tests.support.foxglove_client import Client

    sim = SimBoard(seed=4, radio=False)
    port = sim.start()
    live = flood = None
    try:
        live = LiveServer("127.0.0.1", 0, t0=time.monotonic(), start_ns=time.time_ns())
        front = live.front
        cable = RecordingTransport(SerialTransport(port), live, CABLE, time.monotonic)
        app = TermApp(cable, joystick=False, live=live, log_directory=tmp_path / "logs")
        before, during = Client(live.url, ("/cable/rx/Attitude",)), Client(live.url, ("/cable/rx/Attitude",))
        stop = asyncio.Event()
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model
            await until(pilot, lambda: m.mode == Mode.SAFE and m.link is not None)
            first = asyncio.create_task(before.run(stop))
            await until(pilot, lambda: len(before.received) > 10)
            fds = open_fds()
            flood = subprocess.Popen([sys.executable, "-m", "tests.support.idle_flood", "127.0.0.1", str(live.port),
                                      str(FLOOD)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                     cwd=Path(__file__).resolve().parents[2])
            assert flood.stdout is not None
            assert flood.stdout.readline().startswith(f"open {FLOOD}")
            # The door has taken (and dropped) all but its cap of them, and holds no more than its cap.
            await until(pilot, lambda: front.refused[EVICTED] >= FLOOD - front.max_pending, 30.0)
            assert front.pending <= front.max_pending
            if fds is not None:
                held = open_fds()
                assert held is not None and held <= fds + front.max_pending + 8, (fds, held)
            got = len(before.received)
            second = asyncio.create_task(during.run(stop, tries=5))  # the flood goes on: the door evicts idle ones
            await until(pilot, lambda: len(during.received) > 10 and len(before.received) > got + 50, 20.0)
            assert front.clients == 2
            assert m.link is not None and not [e.text for e in m.events if "LINK LOST" in e.text]
            # A flood is a few lines of log, not a line a connection.
            assert front.refusals.lines <= 3, front.refusals.lines
            stop.set()
            await asyncio.gather(first, second)
            app.exit()
    finally:
        if flood is not None:
            with contextlib.suppress(Exception):
                flood.communicate("", timeout=10)
        if live is not None:
            live.close()
        sim.stop()


def _idle(port: int) -> socket.socket:
    return socket.create_connection(("127.0.0.1", port), timeout=5.0)


def _closed_within(sock: socket.socket, seconds: float) -> bytes | None:
    """What the server sent before it closed ``sock`` (None if it did not close it within ``seconds``)."""
    sock.settimeout(seconds)
    got = b""
    try:
        while chunk := sock.recv(4096):
            got += chunk
    except TimeoutError:
        return None
    except ConnectionResetError:
        pass
    return got


async def test_the_doors_time_limit_and_caps_each_hold() -> None:
    """An idle connection is dropped after the time limit; past the cap on waiting connections the oldest idle one
    goes; a request head too large is refused; a client past the cap on clients is answered 503."""
    import websockets

    from term.data.foxglove_front import EVICTED, HEAD_TOO_BIG, TIMED_OUT, TOO_MANY_CLIENTS
    from term.data.foxglove_server import LiveServer
    from tests.support.foxglove_client import SUBPROTOCOLS

    live = LiveServer("127.0.0.1", 0, t0=0.0, start_ns=0,
                      guard={"max_pending": 2, "pending_timeout_s": 0.5, "max_clients": 1, "max_head": 2048})
    front = live.front
    try:
        idle = _idle(live.port)
        assert _closed_within(idle, 10.0) == b""  # (dropped after 0.5 s: a bounded wait, the time not held)
        assert front.refused[TIMED_OUT] == 1
        idle.close()
        a, b, c = _idle(live.port), _idle(live.port), _idle(live.port)
        assert _closed_within(a, 10.0) == b""  # the oldest, when the third came
        assert front.refused[EVICTED] == 1
        for s in (a, b, c):
            s.close()
        big = _idle(live.port)
        big.sendall(b"GET / HTTP/1.1\r\nX: " + b"x" * 4096)
        assert (_closed_within(big, 10.0) or b"").startswith(b"HTTP/1.1 503")
        assert front.refused[HEAD_TOO_BIG] == 1
        big.close()
        async with websockets.connect(live.url, subprotocols=SUBPROTOCOLS) as ws:  # type: ignore[arg-type]
            assert "serverInfo" in await asyncio.wait_for(ws.recv(), 10.0)
            with pytest.raises(websockets.exceptions.InvalidStatus, match="503"):
                async with websockets.connect(live.url, subprotocols=SUBPROTOCOLS):  # type: ignore[arg-type]
                    pass
            assert front.refused[TOO_MANY_CLIENTS] == 1
    finally:
        live.close()
