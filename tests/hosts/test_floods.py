"""Every server of the simulator holds a flood without harm to the flight (issue 36): more idle connections than
select() can watch, to the instructor and the BLE HCI ports of a served board, and the board keeps sending over its
pty; a descriptor past select()'s bound is refused before the loop would watch it (hosts/listeners.py)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import resource
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest
import serial

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.hosts.instructor import MAX_PENDING, Instructor, InstructorServer
from fcb_sim.hosts.listeners import FD_RANGE, TOO_MANY, fd_limit
from fcb_sim.hosts.serve import event_loop
from fcb_sim.world.physics import World
from term.core.protocol import PROTOCOL_VERSION, Decoder, Encoder, Heartbeat, HeartbeatAck, Hello
from term.lessons.instructor import parse_address

FLOOD = 1100  # idle connections to each port: more than select() can watch (FD_SETSIZE 1024)


@contextlib.contextmanager
def descriptors(n: int) -> Iterator[None]:
    """This process may hold ``n`` descriptors (the soft RLIMIT_NOFILE raised toward the hard one, then put back)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != resource.RLIM_INFINITY and hard < n:
        pytest.skip(f"the hard descriptor limit {hard} is below the {n} the flood needs")
    if soft != resource.RLIM_INFINITY and soft < n:
        resource.setrlimit(resource.RLIMIT_NOFILE, (n, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


class Pilot:
    """Heartbeats answered over the pty, the board's counted."""

    def __init__(self, path: str) -> None:
        self.port = serial.Serial(path, 115200, timeout=0)
        self.enc, self.dec = Encoder(), Decoder()
        self.heartbeats = 0
        self.port.write(self.enc.encode(Hello(PROTOCOL_VERSION, 0, 0, 1, 0)))

    def poll(self) -> None:
        for pkt in self.dec.feed(self.port.read(8192)):
            if type(pkt) is Heartbeat:
                self.heartbeats += 1
                self.port.write(self.enc.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))

    def more(self, n: int, within: float) -> bool:
        """True once ``n`` more heartbeats have come (bounded wait)."""
        goal, end = self.heartbeats + n, time.monotonic() + within
        while time.monotonic() < end:
            self.poll()
            if self.heartbeats >= goal:
                return True
            time.sleep(0.02)
        return False


def _flood(host: str, port: int, n: int, pilot: Pilot) -> list[socket.socket]:
    socks = []
    for i in range(n):
        s = socket.socket()
        s.setblocking(False)
        s.connect_ex((host, port))
        socks.append(s)
        if i % 50 == 0:
            pilot.poll()  # the pilot goes on flying meanwhile
    return socks


def test_idle_floods_on_the_instructor_and_hci_ports_cost_the_board_nothing() -> None:
    with descriptors(2 * FLOOD + 300):
        proc = subprocess.Popen(
            [sys.executable, "-m", "fcb_sim.cli", "serve", "--pty", "--link-timeout", "5",
             "--instructor", "tcp-server:127.0.0.1:0", "--ble-hci", "tcp-server:127.0.0.1:0"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
        socks: list[socket.socket] = []
        try:
            assert proc.stdout is not None
            lines = [proc.stdout.readline() for _ in range(3)]
            path = lines[0].split()[1]
            hci = next(ln for ln in lines if ln.startswith("ble:")).split()[-1]  # tcp-client:HOST:PORT
            address = next(ln for ln in lines if ln.startswith("instructor:")).split()[1]
            ihost, iport, token = parse_address(address)
            _, hhost, hport = hci.split(":")
            pilot = Pilot(path)
            assert pilot.more(3, 10.0), "no heartbeat before the flood"
            socks += _flood(ihost, iport, FLOOD, pilot)
            socks += _flood(hhost, int(hport), FLOOD, pilot)
            assert pilot.more(10, 10.0), "the board stopped sending during the flood"
            fds = len(os.listdir(f"/proc/{proc.pid}/fd")) if os.path.isdir(f"/proc/{proc.pid}/fd") else 0
            assert fds < 200, f"the simulator holds {fds} descriptors"
            assert proc.poll() is None
            for s in socks:
                s.close()
            socks.clear()
            # the instructor answers a real client again: the flood's connections went without a word, which is
            # no wrong token (they once made 127.0.0.1 wait 12.8 s, tests/hosts/test_logins.py)
            deadline = time.monotonic() + 20.0
            hello = None
            while hello is None and time.monotonic() < deadline:
                with socket.create_connection((ihost, iport), timeout=5) as c:
                    c.sendall(json.dumps({"kind": "auth", "token": token}).encode() + b"\n")
                    first = json.loads(c.makefile().readline() or "{}")
                    hello = first if first.get("kind") == "hello" else None
                pilot.poll()
            assert hello is not None
            assert pilot.more(5, 10.0)
        finally:
            for s in socks:
                s.close()
            proc.terminate()
            out, err = proc.communicate(timeout=20)
        assert proc.returncode == 0, err[-2000:]
        assert "filedescriptor out of range" not in err and "Traceback" not in err, err[-2000:]
        assert err.count("refused") < 20, err[-2000:]  # summarised: one line per interval, not one per client


def test_a_descriptor_past_selects_bound_is_refused_before_the_loop_watches_it() -> None:
    """With the process's low descriptors taken, the next accepted one is past what select() watches: the door
    closes it before asyncio registers it, and the loop (on select(), as serve runs) goes on."""

    async def main() -> tuple[int, dict[str, int], bool]:
        limit = fd_limit()
        assert limit is not None  # serve's loop runs on select()
        server = InstructorServer(Instructor(Board(BoardConfig(seed=2), world=World(2))))
        host, port, _ = parse_address(await server.start("tcp-server:127.0.0.1:0"))
        filler = []
        try:
            while True:  # take every descriptor below the bound
                fd = os.open(os.devnull, os.O_RDONLY)
                filler.append(fd)
                if fd >= limit:
                    break
            reader, writer = await asyncio.open_connection(host, port)
            async with asyncio.timeout(5):
                said = await reader.read()  # to the end: closed at once, after the error line
            closed = json.loads(said)["why"] == FD_RANGE
            writer.close()
            ticks = 0
            for _ in range(5):  # the loop goes on selecting
                await asyncio.sleep(0.01)
                ticks += 1
            return ticks, dict(server.door.refusals.counts) | {"refused": server.refused}, closed
        finally:
            for fd in filler:
                os.close(fd)
            await server.close()

    with descriptors(1400), asyncio.Runner(loop_factory=event_loop) as runner:
        ticks, counts, closed = runner.run(main())
    assert ticks == 5 and closed and counts["refused"] == 1


async def test_more_than_max_pending_waiting_for_the_token_are_refused_at_once() -> None:
    server = InstructorServer(Instructor(Board(BoardConfig(seed=2), world=World(2))))
    host, port, token = parse_address(await server.start("tcp-server:127.0.0.1:0"))
    held = []
    try:
        for _ in range(MAX_PENDING):
            held.append(await asyncio.open_connection(host, port))
        async with asyncio.timeout(5):
            while server.door.pending < MAX_PENDING:
                await asyncio.sleep(0.01)
        reader, writer = await asyncio.open_connection(host, port)
        async with asyncio.timeout(5):
            line = await reader.readline()
            assert json.loads(line)["why"] == TOO_MANY
            assert await reader.read() == b""
        writer.close()
        assert server.refused == 1
    finally:
        for _, w in held:
            w.close()
        await server.close()
    assert FD_RANGE not in server.door.refusals.counts


async def test_hci_hosts_waiting_for_the_radio_are_refused_past_the_cap() -> None:
    from bumble.link import LocalLink

    from fcb_sim.hosts.radio import MAX_WAITING_HOSTS, HciTcpServer

    hci = HciTcpServer(LocalLink(), name="phone-side")
    await hci.start("127.0.0.1", 0)
    conns = []
    try:
        for _ in range(1 + MAX_WAITING_HOSTS):
            conns.append(await asyncio.open_connection("127.0.0.1", hci.port))
        async with asyncio.timeout(5):
            while hci.hosts_waiting < MAX_WAITING_HOSTS:
                await asyncio.sleep(0.01)
        reader, writer = await asyncio.open_connection("127.0.0.1", hci.port)
        async with asyncio.timeout(5):
            assert await reader.read() == b""  # refused at once
        writer.close()
        assert hci.hosts_served == 1 and hci.hosts_waiting == MAX_WAITING_HOSTS and hci.door.refused == 1
        conns.pop(0)[1].close()  # the first host goes: the oldest waiting one gets the radio
        async with asyncio.timeout(5):
            while hci.hosts_served < 2:
                await asyncio.sleep(0.01)
        assert hci.hosts_waiting == MAX_WAITING_HOSTS - 1
    finally:
        for _, w in conns:
            w.close()
        await hci.close()
