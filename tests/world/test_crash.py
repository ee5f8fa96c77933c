"""Issue 10.2 and 10.4: heights the simulator can reach fit their encoding (or are recognisable as clipped), and
crashes are events: the world detects the impact, the board reports it (Status flag, Event with the speed) and
stays in SAFE until the pilot acknowledges it; PANIC comes down safely from any height the world allows."""

from __future__ import annotations

from typing import Any

import pytest

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.modes import ModeConfig, ModeMachine
from fcb_sim.lab.scenarios import panic_high
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World
from term.core.protocol import (
    Command,
    Decoder,
    Encoder,
    Event,
    EventCode,
    Flag,
    Heartbeat,
    HeartbeatAck,
    Height,
    Joystick,
    Mode,
    Nak,
    Op,
    field_limits,
    saturated,
    scaled,
)


def test_the_height_encoding_covers_the_sky_and_shows_its_limit() -> None:
    lo, hi = field_limits(Height, "height")
    assert lo * 0.01 <= -P.CEILING_M and hi * 0.01 >= P.CEILING_M  # the world's whole sky fits
    at_100 = Height(100_000, 10_000, 0, -2350, 1100, 2500)
    assert scaled(at_100, "height") == pytest.approx(100.0) and not saturated(at_100, "height")
    assert scaled(at_100, "vz") == pytest.approx(-23.5)
    assert saturated(Height(0, 32767, 0, 0, 0, 0), "height") and saturated(Height(0, 0, 0, -32768, 0, 0), "vz")


def test_the_world_stops_a_climb_at_its_ceiling_and_records_crashes() -> None:
    w = World(1, height=P.CEILING_M - 5.0, airborne=True)
    w.set_motors(1000, 1000, 1000, 1000)
    w.advance_to(5.0)
    assert -w.d == pytest.approx(P.CEILING_M) and [c.where for c in w.crashes] == ["ceiling"]
    assert w.crashes[0].speed > P.CRASH_SPEED_M_S
    w.set_motors(0, 0, 0, 0)
    w.advance_to(40.0)
    assert w.on_ground and w.crashes[-1].where == "ground" and w.crashes[-1].speed > 10.0


def test_a_soft_landing_is_not_a_crash() -> None:
    w = World(2, height=0.05, airborne=True)
    w.set_motors(380, 380, 380, 380)
    w.advance_to(3.0)
    assert w.on_ground and w.landings and not w.crashes


def test_the_mode_machine_latches_a_crash_until_it_is_acknowledged() -> None:
    m = ModeMachine(ModeConfig())
    assert m.request(Mode.MANUAL, 0.0) == Nak.OK
    m.crash(1.0, 12_500)
    assert m.mode == Mode.SAFE and m.crashed and m.changes[-1].reason == "crash"
    assert (EventCode.CRASH, 12_500, 1.0) in m.events
    assert m.request(Mode.MANUAL, 2.0) == Nak.CRASHED
    assert m.request(Mode.CALIBRATION, 2.0) == Nak.CRASHED
    assert m.acknowledge_crash() == Nak.OK and not m.crashed
    assert m.request(Mode.MANUAL, 3.0) == Nak.OK
    assert m.acknowledge_crash() == Nak.NOT_IN_SAFE


class Pilot:
    """The least terminal over the board's bytes: sticks at 50 Hz, heartbeats answered, packets kept."""

    def __init__(self, board: Board) -> None:
        self.b, self.enc, self.dec = board, Encoder(), Decoder()
        self.got: list[Any] = []
        self.js = Joystick(0, 0, 0, 0, 0)
        self.cmd_id = 0

    def run(self, seconds: float) -> None:
        end = self.b.now + int(seconds * 1e6)
        while self.b.now < end:
            self.b.uart_receive(self.enc.encode(self.js))
            self.b.advance(self.b.now + 20_000)
            for pkt in self.dec.feed(self.b.uart_transmit()):
                self.got.append(pkt)
                if type(pkt) is Heartbeat:
                    self.b.uart_receive(self.enc.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))

    def command(self, op: int, arg: int = 0) -> int:
        self.cmd_id += 1
        self.b.uart_receive(self.enc.encode(Command(self.cmd_id, int(op), arg)))
        self.run(0.1)
        return next(p.status for p in reversed(self.got) if type(p).__name__ == "Ack" and p.cmd_id == self.cmd_id)


def test_the_board_reports_a_crash_and_stays_in_safe_until_it_is_acknowledged() -> None:
    board = Board(BoardConfig(seed=3))
    pc = Pilot(board)
    pc.run(0.3)
    assert pc.command(Op.MODE, Mode.MANUAL) == Nak.OK
    pc.js = Joystick(0, 0, 0, 20000, 0)  # a climb for 1.5 s (to about 4 m), then no lift: down again, hard
    pc.run(1.5)
    pc.js = Joystick(0, 0, 0, 0, 0)
    pc.run(4.0)
    crashes = [p for p in pc.got if type(p) is Event and p.code == EventCode.CRASH]
    assert len(crashes) == 1 and crashes[0].arg > 5_000  # mm/s: faster than 5 m/s
    assert board.mode == Mode.SAFE and board.ae == (0, 0, 0, 0)
    assert board.status().flags & Flag.CRASHED
    assert pc.command(Op.MODE, Mode.MANUAL) == Nak.CRASHED
    assert pc.command(Op.ACK_CRASH) == Nak.OK
    assert not board.status().flags & Flag.CRASHED
    assert pc.command(Op.MODE, Mode.MANUAL) == Nak.OK


@pytest.mark.parametrize("height", [1.0, 100.0])
def test_panic_comes_down_gently_from_any_height(height: float) -> None:
    """Issue 10.4: PANIC at about 100 m held a level for 3.5 s, cut the motors and hit the ground at 23.5 m/s.
    Now it descends at a bounded rate until it senses the ground (from the ceiling too: docs/modes.md)."""
    m = panic_high(5, 0.0, height)
    assert m["landed"] and m["motors_off"] and m["crashes"] == 0
    assert m["landing_speed_m_s"] < P.CRASH_SPEED_M_S / 1.5
    assert m["descent_s"] < height / 0.9 + 5.0  # at least 1 m/s all the way: no hovering about


def test_the_boards_panic_lands_and_ends_in_safe_without_a_crash() -> None:
    board = Board(BoardConfig(seed=6))
    pc = Pilot(board)
    pc.run(0.3)
    assert pc.command(Op.MODE, Mode.MANUAL) == Nak.OK
    pc.js = Joystick(0, 0, 0, 20000, 0)  # climb to about 4 m, the stick still up
    pc.run(1.5)
    assert -board.world.d > 2.0
    assert pc.command(Op.MODE, Mode.PANIC) == Nak.OK
    pc.run(12.0)  # 1 m/s down from about 5 m, the ground sensed, the motors ramped off
    assert board.mode == Mode.SAFE and board.ae == (0, 0, 0, 0) and board.world.on_ground
    assert not board.world.crashes and board.world.landings[-1][1] < P.CRASH_SPEED_M_S
    assert not any(type(p) is Event and p.code == EventCode.CRASH for p in pc.got)
