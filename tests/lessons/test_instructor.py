"""The simulator's instructor channel: situations set on the real board and world (fcb_sim/hosts/instructor.py), the
truth as the terminal parses it (term/lessons/instructor.py), and both ends over a real TCP socket, from the child
board that `term --sim` starts to a serial client that sees the instructor cut the cable."""

from __future__ import annotations

import asyncio
import json
import math
import time

import pytest
import serial

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.hosts.instructor import Instructor, InstructorServer
from fcb_sim.world.physics import World
from term.core.link import LinkSession
from term.core.protocol import INSTRUCTOR_TRUTH, INSTRUCTOR_VERSION, Joystick, Mode, Op
from term.lessons.instructor import Hello, InstructorClient, Refused, Truth, check_situation, parse_line
from term.session.sim import SimBoard


def flying_board(seed: int = 1) -> tuple[Board, LinkSession]:
    """A board hovering in FULL at about 1 m after 6 s (lift stick on the true height, as the scenarios fly)."""
    board = Board(BoardConfig(seed=seed), world=World(seed))
    s = LinkSession(0.0)
    board.uart_receive(s.hello())
    base = 15000.0
    for k in range(1, 3001):
        t = k * 0.002
        if k == 100:
            s.send_command(Op.MODE, Mode.CALIBRATION, t)
        elif k == 700:
            s.send_command(Op.MODE, Mode.FULL, t)
        if k > 800 and k % 10 == 0:
            tr = board.world.truth
            base += 20 * (1.0 - tr.h)
            s.set_joystick(Joystick(0, 0, 0, max(0, min(32767, int(base + 4000 * (1.0 - tr.h) + 3000 * tr.vd))), 0))
        board.advance(k * 2000)
        s.receive(board.uart_transmit(), t)
        s.poll(t)
        board.uart_receive(s.data_to_send(t))
    return board, s


def test_every_truth_field_reaches_the_terminal_as_the_world_has_it() -> None:
    board, _ = flying_board()
    inst = Instructor(board)
    now = board.now / 1e6
    obj = inst.truth(now)
    assert set(obj) - {"kind"} == set(INSTRUCTOR_TRUTH)
    t = parse_line(inst.truth_line(now))
    assert isinstance(t, Truth)
    w = board.world.truth
    assert board.mode == Mode.FULL and 0.5 < w.h < 1.5 and not t.on_ground
    assert (t.n, t.e, t.h) == pytest.approx((w.n, w.e, w.h), abs=1e-4)
    assert (t.phi, t.theta, t.psi) == pytest.approx((w.phi, w.theta, w.psi), abs=1e-5)
    assert t.vz == pytest.approx(-w.vd, abs=1e-4) and t.soc == pytest.approx(w.soc, abs=1e-4)
    assert t.tilt_deg == pytest.approx(math.degrees(math.acos(math.cos(w.phi) * math.cos(w.theta))), abs=1e-3)


def test_reset_only_on_the_floor_in_safe_and_it_puts_the_craft_back_on_the_pad() -> None:
    board, s = flying_board()
    inst = Instructor(board)
    now = board.now / 1e6
    assert inst.apply({"do": "reset"}, now) == "reset: only with the craft on the floor in SAFE (land, then 0)"
    w = board.world
    w.n, w.e, w.d, w.on_ground = 2.5, -1.0, 0.0, True  # as if it had landed over there
    w.qw, w.qx, w.qy, w.qz = math.cos(0.5), 0.0, 0.0, math.sin(0.5)  # facing 57°
    board.modes.mode = Mode.SAFE
    inst.apply({"do": "wind", "n": -2.0, "gust": 1.0}, now)
    inst.apply({"do": "motor", "motor": 3, "level": 100}, now)
    inst.apply({"do": "battery", "soc": 0.2, "drain": 0.1}, now)
    inst.apply({"do": "cable", "cuts": [[1.0, 2.0]]}, now)
    assert inst.apply({"do": "reset", "soc": 0.7}, now) is None
    tr = w.truth
    assert (tr.n, tr.e, tr.h, tr.psi) == (0.0, 0.0, 0.0, 0.0) and tr.on_ground
    assert w.wind_mean == (0.0, 0.0, 0.0) and w.gust_std == 0.0 and w.stuck == [None] * 4
    assert w.soc == 0.7 and inst.drain == 0.0 and inst.cable_open(now + 1.5)


def test_situations_change_the_world_and_the_cable_on_the_board_clock() -> None:
    board, _ = flying_board()
    inst = Instructor(board)
    now = board.now / 1e6
    assert inst.apply({"do": "wind", "n": -1.5, "e": 0.5, "gust": 0.6}, now) is None
    assert board.world.wind_mean == (-1.5, 0.5, 0.0) and board.world.gust_std == 0.6
    assert inst.apply({"do": "motor", "motor": 2, "level": 380}, now) is None
    assert board.world.stuck[1] == 380
    assert inst.apply({"do": "motor", "motor": 2, "level": -1}, now) is None and board.world.stuck[1] is None
    soc = board.world.soc
    inst.apply({"do": "battery", "drain": 0.1}, now)
    for k in range(1, 11):
        inst.tick(now + 0.1 * k)
    assert board.world.soc == pytest.approx(soc - 0.1, abs=1e-9)  # the failing cell's 0.1 per second, for 1 s
    inst.apply({"do": "cable", "cuts": [[0.0, 0.3], [1.0, 0.5]]}, now)
    open_at = [inst.cable_open(now + dt) for dt in (0.1, 0.35, 1.2, 1.6)]
    assert open_at == [False, True, False, True]
    inst.apply({"do": "cable", "cuts": []}, now + 0.5)
    assert inst.cable_open(now + 1.2)  # cleared: the cable is fine from then
    assert "no radio" in (inst.apply({"do": "radio", "cut": 2.0}, now) or "")


@pytest.mark.parametrize("cmd, why", [
    ({"do": "earthquake"}, "unknown situation 'earthquake'"),
    ({"do": "wind", "speed": 3}, "wind: unknown argument speed"),
    ({"do": "wind", "n": float("nan")}, "n must be a number"),
    ({"do": "wind", "n": 1e9}, "n must be a number from -15 to 15"),
    ({"do": "battery", "soc": "full"}, "soc must be a number"),
    ({"do": "motor", "motor": 7, "level": 100}, "motor must be a whole number from 1 to 4"),
    ({"do": "motor", "motor": True}, "motor must be a whole number"),
    ({"do": "cable", "cuts": [[0, -1]]}, "each cut is"),
    ({"do": "cable", "cuts": "always"}, "cuts is a list"),
    ({"do": "radio", "cut": 1e6}, "cut must be a number from 0.1 to 60"),
    ({}, "unknown situation None"),
])
def test_bad_situations_are_one_line_never_an_exception(cmd: dict, why: str) -> None:
    inst = Instructor(Board(BoardConfig(seed=1)))
    said = inst.apply(cmd, 0.0)
    assert why in (said or "")
    assert check_situation(cmd) == said  # the same check at both ends: a lesson file is refused at load


@pytest.mark.parametrize("line", [
    b"", b"\xff\xfe", b"[]", b"null", b'{"kind": "truth"}', b'{"kind": "truth", "t": "now"}',
    b'{"kind": "truth", "t": NaN}', b"x" * 100000, b'{"kind": "hello"}', b'{"kind": "gossip"}', b"[" * 3000,
    b'{"kind": "truth", "t": ' + b"9" * 5000 + b"}",
])
def test_garbage_from_the_simulator_is_skipped(line: bytes) -> None:
    assert parse_line(line) is None


def test_a_truth_with_a_wrong_type_is_skipped_and_errors_and_hello_are_read() -> None:
    good = {"kind": "truth", **{k: 0.0 for k in INSTRUCTOR_TRUTH}, "on_ground": True, "cable": True,
            "landings": 0, "crashes": 0, "contact": "", "touches": 0, "touched": ""}
    assert isinstance(parse_line(json.dumps(good).encode()), Truth)
    for field, bad in (("on_ground", 1), ("landings", 1.5), ("crashes", True), ("h", float("inf")), ("n", "0"),
                       ("touches", 1.5), ("touched", "floor")):
        assert parse_line(json.dumps({**good, field: bad}).encode()) is None, field
    assert parse_line(b'{"kind": "error", "do": "wind", "why": "no"}') == Refused("wind", "no")
    assert parse_line(b'{"kind": "hello", "version": 1, "hz": 50}') == Hello(1, 50.0)


async def test_the_channel_over_tcp_truth_out_situations_in_refusals_back() -> None:
    board = Board(BoardConfig(seed=2), world=World(2))
    server = InstructorServer(Instructor(board))
    address = await server.start("tcp-server:127.0.0.1:0")
    refused: list[Refused] = []
    truths: list[Truth] = []
    client = InstructorClient(address, on_truth=truths.append, on_refused=refused.append)
    try:
        await client.open()
        async with asyncio.timeout(5):
            while len(truths) < 3:
                await asyncio.sleep(0.01)
        assert client.version == INSTRUCTOR_VERSION and truths[-1].on_ground and truths[-1].h == 0.0
        assert client.send({"do": "wind", "n": -1.0, "gust": 0.3}) is None
        assert client.send({"do": "wind", "speed": 1}) is not None  # caught here, never sent
        client._writer.write(b'{"do": "motor", "motor": 9}\nnot json\n')  # what a broken client might send
        async with asyncio.timeout(5):
            while len(refused) < 2 or board.world.wind_mean[0] != -1.0:
                await asyncio.sleep(0.01)
        assert refused[0].verb == "motor" and "from 1 to 4" in refused[0].why
        assert refused[1].why == "not a JSON line"
        assert board.world.wind_mean == (-1.0, 0.0, 0.0) and board.world.gust_std == 0.3
    finally:
        await client.close()
        await server.close()


def test_term_sim_child_prints_the_channel_and_a_cable_cut_silences_the_pty() -> None:
    """`fcb-sim serve --instructor` as `term --sim` starts it: the third line is the address; a cable cut of 0.6 s
    leaves the serial port silent for that long (the board's heartbeats stop arriving), then it talks again."""
    sim = SimBoard(seed=4, instructor=True)
    port = sim.start()
    try:
        assert sim.instructor_address.startswith("tcp-client:127.0.0.1:")

        async def cut() -> list[Truth]:
            got: list[Truth] = []
            client = InstructorClient(sim.instructor_address, on_truth=got.append)
            await client.open()
            async with asyncio.timeout(5):
                while not got:
                    await asyncio.sleep(0.01)
            assert client.send({"do": "cable", "cuts": [[0.0, 0.6]]}) is None
            await asyncio.sleep(0.05)
            await client.close()
            return got

        with serial.Serial(port, 115200, timeout=0.05) as ser:
            ser.reset_input_buffer()
            before = ser.read(4096)
            assert before  # heartbeats and the boot Hello: the board talks
            truths = asyncio.run(cut())
            assert truths[0].cable
            ser.reset_input_buffer()
            t0 = time.monotonic()
            quiet = ser.read(4096)  # within the cut
            assert time.monotonic() - t0 < 0.3 and quiet == b""
            time.sleep(0.7)
            ser.reset_input_buffer()
            assert ser.read(4096)  # the cut is over
    finally:
        sim.stop()


def test_after_a_crash_the_reset_puts_the_boards_attitude_level_on_the_pad() -> None:
    """Issue 22: after lesson 7's reset the attitude read roll +46.3° pitch +4.5° on the pad for over 60 s (the
    flight core keeps the angles of its last flight-mode step in SAFE; the reset starts them level, as the craft)."""
    board, s = flying_board()
    inst = Instructor(board)
    t = board.now / 1e6
    inst.apply({"do": "motor", "motor": 2, "level": 0}, t)  # a dead motor: it flips and crashes

    def run(seconds: float) -> None:
        nonlocal t
        for _ in range(round(seconds / 0.002)):
            t += 0.002
            board.advance(round(t * 1e6))
            s.receive(board.uart_transmit(), t)
            s.poll(t)
            board.uart_receive(s.data_to_send(t))

    for _ in range(40):
        run(0.5)
        if board.mode == Mode.SAFE and board.world.on_ground:
            break
    assert board.world.crashes and board.mode == Mode.SAFE
    assert inst.apply({"do": "reset"}, t) is None
    run(0.5)
    phi, theta, _ = board.core.attitude_centideg()
    assert abs(phi) < 200 and abs(theta) < 200, (phi, theta)  # within 2° of level
