"""Failed instructor logins are limited per address (a delay that doubles) and their log lines summarised, one line
per interval with a count (issue 36); the clock is injected."""

from __future__ import annotations

import asyncio
import json
import logging

import pytest

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.hosts.instructor import Instructor, InstructorServer
from fcb_sim.hosts.listeners import LoginThrottle, RefusalLog
from fcb_sim.world.physics import World
from term.lessons.instructor import parse_address


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def test_the_delay_doubles_per_failure_up_to_its_cap_and_a_success_or_quiet_forgets() -> None:
    clock = Clock()
    th = LoginThrottle(base_s=0.1, max_s=30.0, forget_s=600.0, clock=clock)
    assert th.wait("a") == 0.0
    waits = []
    for _ in range(12):
        th.failed("a")
        waits.append(th.wait("a"))
        clock.t += waits[-1]  # it tries again as soon as it may
    assert waits[:5] == pytest.approx([0.1, 0.2, 0.4, 0.8, 1.6])
    assert max(waits) == 30.0 and waits[-1] == 30.0
    assert th.wait("b") == 0.0  # per address
    th.succeeded("a")
    assert th.wait("a") == 0.0
    th.failed("a")
    clock.t += 600.0
    assert th.wait("a") == 0.0 and len(th) == 0


def test_a_flood_of_addresses_costs_bounded_memory() -> None:
    th = LoginThrottle(max_addresses=100, clock=Clock())
    for i in range(10_000):
        th.failed(f"10.0.{i // 256}.{i % 256}")
    assert len(th) == 100 and th.wait("10.0.39.15") > 0  # the newest are kept


def test_refusals_are_one_line_per_interval_with_a_count(caplog: pytest.LogCaptureFixture) -> None:
    clock = Clock()
    log = logging.getLogger("test.refusals")
    summary = RefusalLog(log, "instructor", interval=10.0, clock=clock)
    with caplog.at_level(logging.WARNING, logger="test.refusals"):
        for i in range(3000):  # 3,000 wrong tokens in 3 s
            clock.t += 0.001
            summary.note("wrong token" if i % 3 else "too many connections waiting")
        assert len(caplog.records) == 1 and "a client refused" in caplog.records[0].getMessage()
        clock.t += 10.0
        summary.note("wrong token")  # the interval is over: its line, then counting goes on
        summary.flush()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3, lines
    assert "2,999 more clients refused" in lines[1] and "2,000 wrong token" in lines[1]
    assert "999 too many connections waiting" in lines[1]
    assert "1 more clients refused" in lines[2]
    summary.flush()  # nothing counted: a quiet spell begins, no line
    assert len(caplog.records) == 3 and summary.lines == 3


async def _try(host: str, port: int, token: str) -> dict:
    reader, writer = await asyncio.open_connection(host, port)
    try:
        writer.write(json.dumps({"kind": "auth", "token": token}).encode() + b"\n")
        async with asyncio.timeout(5):
            return json.loads(await reader.readline())
    finally:
        writer.close()


async def test_a_wrong_token_makes_the_address_wait_before_its_next_is_looked_at() -> None:
    clock = Clock()
    server = InstructorServer(Instructor(Board(BoardConfig(seed=2), world=World(2))), clock=clock)
    host, port, token = parse_address(await server.start("tcp-server:127.0.0.1:0"))
    try:
        assert "token" in (await _try(host, port, "0" * 32))["why"]
        got = await _try(host, port, token)  # the right one, but too soon: not even looked at
        assert got["kind"] == "error" and "try again in 0.1 s" in got["why"]
        clock.t += 0.1
        assert "token" in (await _try(host, port, "1" * 32))["why"]  # a second wrong one: 0.2 s
        clock.t += 0.15
        assert "try again in 0.1 s" in (await _try(host, port, token))["why"]
        clock.t += 0.06
        assert (await _try(host, port, token))["kind"] == "hello"
        assert server.throttle.wait(host) == 0.0  # a success forgets the failures
        assert server.refused == 4
    finally:
        await server.close()


async def test_a_client_that_goes_without_a_word_is_no_wrong_token() -> None:
    """A connection closed before it sent a line guessed nothing: a port scan or a flood of idle connections on
    loopback must not make term's own instructor client wait (it shares the address 127.0.0.1)."""
    clock = Clock()
    server = InstructorServer(Instructor(Board(BoardConfig(seed=2), world=World(2))), clock=clock)
    host, port, token = parse_address(await server.start("tcp-server:127.0.0.1:0"))
    try:
        for _ in range(10):
            reader, writer = await asyncio.open_connection(host, port)
            writer.close()
            async with asyncio.timeout(5):
                await reader.read()  # the server has seen the end and closed its side
        assert server.throttle.wait(host) == 0.0
        assert (await _try(host, port, token))["kind"] == "hello"
        reader, writer = await asyncio.open_connection(host, port)  # half a line, then the end: a wrong token
        writer.write(b'{"kind": "auth", "tok')
        writer.write_eof()
        async with asyncio.timeout(5):
            assert b"token" in await reader.readline()
        writer.close()
        assert server.throttle.wait(host) > 0.0
    finally:
        await server.close()
