"""The instructor channel is the simulator's and the terminal's alone (issue 23): a random token the child prints
for term (in the address, ``tcp-client:HOST:PORT#TOKEN``), loopback only unless ``--instructor-public``, one client
at a time, outages that add up to a bound per attempt, every malformed line answered in one line (never a
traceback), and a clean exit on SIGTERM and SIGINT."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.errors import UsageError
from fcb_sim.hosts.instructor import MAX_OUTAGE_S, Instructor, InstructorServer
from fcb_sim.world.physics import World
from term.lessons.instructor import InstructorClient, parse_address


async def _server() -> tuple[InstructorServer, str]:
    server = InstructorServer(Instructor(Board(BoardConfig(seed=2), world=World(2))))
    return server, await server.start("tcp-server:127.0.0.1:0")


async def _raw(address: str) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
    host, port, _ = parse_address(address)
    return await asyncio.open_connection(host, port)


async def _lines(reader: asyncio.StreamReader, n: int = 1) -> list[dict]:
    out = []
    async with asyncio.timeout(5):
        while len(out) < n:
            line = await reader.readline()
            if not line:
                break
            out.append(json.loads(line))
    return out


async def test_a_client_without_the_token_gets_nothing_and_changes_nothing() -> None:
    server, address = await _server()
    assert "#" in address and len(address.rsplit("#", 1)[1]) >= 32
    try:
        reader, writer = await _raw(address)
        writer.write(b'{"do": "wind", "n": 5}\n')
        got = await _lines(reader, 2)
        assert got and got[0]["kind"] == "error" and "token" in got[0]["why"]
        assert all(g["kind"] != "truth" for g in got)
        assert await reader.read() == b""  # dropped
        assert server.instructor.board.world.wind_mean == (0.0, 0.0, 0.0)
        reader, writer = await _raw(address)
        writer.write(b'{"kind": "auth", "token": "00000000000000000000000000000000"}\n')
        got = await _lines(reader, 1)
        assert got[0]["kind"] == "error" and "token" in got[0]["why"]
    finally:
        await server.close()


async def test_one_client_at_a_time_the_second_is_refused() -> None:
    server, address = await _server()
    first = InstructorClient(address)
    try:
        await first.open()
        async with asyncio.timeout(5):
            while first.truth is None:
                await asyncio.sleep(0.01)
        second = InstructorClient(address)
        lost: list[str] = []
        second.on_lost = lost.append
        await second.open()
        async with asyncio.timeout(5):
            while not lost:
                await asyncio.sleep(0.01)
        assert "another" in lost[0] or "closed" in lost[0]
        assert second.truth is None
        n = first.samples
        await asyncio.sleep(0.1)
        assert first.up and first.samples > n  # the first keeps its channel
    finally:
        await first.close()
        await server.close()


@pytest.mark.parametrize("line", [
    b'{"do": "wind", "n": ' + b"9" * 400 + b"}", b'{"do": "wind", "n": -' + b"9" * 400 + b"}",
    b'{"do": "cable", "cuts": [[' + b"9" * 400 + b", 1]]}", b'{"do": "motor", "motor": ' + b"9" * 400 + b"}",
    b"[" * 2000 + b"]" * 2000, b'{"do": ' + b"[" * 2000 + b"]" * 2000 + b"}", b'{"do": "wind", "n": 1e999}',
    b'{"do": "battery", "soc": NaN}', b"\xff\xfe", b'{"do": "radio", "cut": Infinity}', b'"wind"',
], ids=lambda b: b[:24].decode(errors="replace"))
async def test_malformed_lines_are_answered_never_a_traceback(line: bytes,
                                                               caplog: pytest.LogCaptureFixture) -> None:
    server, address = await _server()
    refused: list = []
    client = InstructorClient(address, on_refused=refused.append)
    try:
        await client.open()
        client._writer.write(line + b"\n")
        async with asyncio.timeout(5):
            while not refused:
                await asyncio.sleep(0.01)
        assert "\n" not in refused[0].why and len(refused[0].why) < 300
        client._writer.write(b'{"do": "wind", "n": 1}\n')  # still connected, still obeyed
        async with asyncio.timeout(5):
            while server.instructor.board.world.wind_mean[0] != 1.0:
                await asyncio.sleep(0.01)
    finally:
        await client.close()
        await server.close()
    assert not [r for r in caplog.records if r.exc_info]


def test_outages_add_up_to_a_bound_per_attempt() -> None:
    inst = Instructor(Board(BoardConfig(seed=1)))
    accepted = 0.0
    for k in range(60):  # 60 chained 60 s cuts were an hour's outage
        if inst.apply({"do": "cable", "cuts": [[k * 60.0, 60.0]]}, 0.0) is None:
            accepted += 60.0
    assert accepted <= MAX_OUTAGE_S
    why = inst.apply({"do": "cable", "cuts": [[0, 10], [10, 10]] * 10}, 0.0)
    assert why is not None and "outage" in why
    assert inst.apply({"do": "reset"}, 0.0) is None  # a new attempt
    assert inst.apply({"do": "cable", "cuts": [[0.0, 30.0]]}, 0.0) is None


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.sampled_from(["do", "n", "e", "gust", "soc", "drain", "motor", "level", "cuts", "cut",
                                        "x"]),
                       st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                                    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=3), c,
                                                                                         max_size=2),
                                    max_leaves=8)))
def test_any_command_is_done_or_refused_in_one_line(cmd: dict) -> None:
    if "do" not in cmd or not isinstance(cmd["do"], str):
        cmd = cmd | {"do": "wind"}
    inst = Instructor(Board(BoardConfig(seed=1)))
    why = inst.apply(cmd, 0.0)
    assert why is None or ("\n" not in why and len(why) < 300)


def test_a_public_address_needs_the_flag() -> None:
    async def go(public: bool) -> str:
        server = InstructorServer(Instructor(Board(BoardConfig(seed=1))))
        try:
            return await server.start("tcp-server:0.0.0.0:0", public=public)
        finally:
            await server.close()

    with pytest.raises(UsageError, match="--instructor-public"):
        asyncio.run(go(False))
    assert asyncio.run(go(True)).startswith("tcp-client:")


def _serve(*extra: str) -> tuple[subprocess.Popen[bytes], list[str]]:
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from fcb_sim.cli import main; sys.exit(main())",
                             "serve", "--pty", *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    lines = []
    assert proc.stdout is not None
    for _ in range(2 if "--instructor" in extra else 1):
        lines.append(proc.stdout.readline().decode())
    return proc, lines


def test_public_without_the_flag_is_refused_and_with_it_warned() -> None:
    proc, _ = _serve("--instructor", "tcp-server:0.0.0.0:0")
    out, err = proc.communicate(timeout=20)
    assert proc.returncode != 0 and b"--instructor-public" in err and b"Traceback" not in err
    proc, lines = _serve("--instructor", "tcp-server:0.0.0.0:0", "--instructor-public")
    try:
        assert lines[1].startswith("instructor: tcp-client:")
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    assert b"warning" in err.lower() and b"every" in err.lower() and proc.returncode == 0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_serve_ends_cleanly_on_a_signal_with_a_client_connected(sig: signal.Signals) -> None:
    proc, lines = _serve("--instructor", "tcp-server:127.0.0.1:0")
    try:
        host, port, _ = parse_address(lines[1].split()[1])
        with socket.create_connection((host, port), timeout=5):
            time.sleep(0.3)
            proc.send_signal(sig)
            out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0 and b"Traceback" not in err and b"CancelledError" not in err, err[-2000:]
    assert b"served" in out
