"""Issue 37's safety finding: the C board's gain keys had no upper limit (P2 +100,000 presses read 501111, P1
+1,000,000 read 50000.4, yaw P +1e9 wrapped to -2.1e7 and PARAM_GET then answered -2147483648; in FULL with lift two
such commands flipped the craft). Every parameter write is now kept to the generated table on both boards: the
finding's bursts give the table's ends, and the in-flight case is flown."""

from __future__ import annotations

import math
import shutil
from typing import Any

import pytest

from fcb_sim.board.board import Board
from fcb_sim.board.parts import BoardConfig
from fcb_sim.world.physics import World
from term.core.protocol import PARAMS, Ack, Command, Decoder, Joystick, Mode, Op, Param, encode

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make: the C board's tests are skipped")

BOARDS = ("python", "c")


def _board(kind: str, world: World | None = None) -> Any:
    from fcb_sim.hosts.cboard import CBoard

    cfg = BoardConfig(seed=7)
    return Board(cfg, world=world) if kind == "python" else CBoard(cfg, world=world)


class Desk:
    """Commands to a board over its UART, each answered before the next (the Ack's status and value)."""

    def __init__(self, board: Any) -> None:
        self.board, self.dec, self.cmd_id = board, Decoder(), 0

    def __call__(self, op: Op, arg: int) -> tuple[int, int]:
        self.cmd_id = self.cmd_id % 255 + 1
        self.board.uart_receive(encode(Command(self.cmd_id, op, arg)))
        end = self.board.now + 200_000
        while self.board.now < end:
            self.board.advance(self.board.now + 5_000)
            for pkt in self.dec.feed(self.board.uart_transmit()):
                if type(pkt) is Ack and pkt.cmd_id == self.cmd_id:
                    return pkt.status, pkt.value
        raise AssertionError(f"no Ack to {op.name} {arg}")

    def get(self, param: Param) -> int:
        status, value = self(Op.PARAM_GET, int(param))
        assert status == 0
        return value


def _hi(param: Param) -> int:
    return PARAMS[param].raw_range[1]


@pytest.mark.parametrize("kind", BOARDS)
def test_the_findings_gain_bursts_give_the_tables_limits(kind: str) -> None:
    desk = Desk(_board(kind))
    desk.board.advance(100_000)
    assert desk(Op.GAIN_P2, 100_000) == (0, 1_000_000)  # 1000.00 (it read 501111)
    assert desk.get(Param.P2) == _hi(Param.P2)
    assert desk(Op.GAIN_P1, 1_000_000) == (0, 10_000)  # 10.0 (it read 50000.4)
    assert desk.get(Param.P1) == _hi(Param.P1)
    assert desk(Op.GAIN_YAW_P, 1_000_000_000) == (0, 5_000_000)  # 5000 (it wrapped to -2.1e7)
    assert desk.get(Param.YAW_P) == _hi(Param.YAW_P)  # (it read -2147483648)
    assert desk(Op.GAIN_HEIGHT_D, 2**31 - 1) == (0, 5_000_000)
    for op, param in ((Op.GAIN_P2, Param.P2), (Op.GAIN_YAW_P, Param.YAW_P), (Op.GAIN_HEIGHT_P, Param.HEIGHT_P)):
        assert desk(op, -(2**31)) == (0, 0)
        assert desk.get(param) == 0
    desk(Op.SET_PARAM, (int(Param.P2) << 24) | 11_100)  # back to 111, then 200 presses of the P2 key (it read 1111)
    for _ in range(200):
        status, _ = desk(Op.GAIN_P2, 1)
        assert status == 0
    assert desk.get(Param.P2) == _hi(Param.P2)


def _fly_with_gain_bursts(kind: str) -> dict[str, Any]:
    """FULL at 1 m by the lift stick; at 3 s P2 +100,000 presses and yaw P +1e9 (the finding's two commands)."""
    from fcb_sim.hosts.cboard import _pilot_lift

    world = World(7)
    board = _board(kind, world)
    dec = Decoder()
    acks: list[Ack] = []
    worst_tilt, modes = 0.0, set()
    for t in range(20_000, 6_000_001, 20_000):
        board.advance(t)
        acks += [p for p in dec.feed(board.uart_transmit()) if type(p) is Ack]
        if t == 200_000:
            board.uart_receive(encode(Command(1, Op.MODE, int(Mode.CALIBRATION))))
        elif t == 1_500_000:
            board.uart_receive(encode(Command(2, Op.MODE, int(Mode.FULL))))
        elif t == 3_000_000:
            board.uart_receive(encode(Command(3, Op.GAIN_P2, 100_000)))
            board.uart_receive(encode(Command(4, Op.GAIN_YAW_P, 1_000_000_000)))
        board.uart_receive(encode(Joystick(0, 0, 0, _pilot_lift(world, 1.0) if t >= 1_500_000 else 0, 0)))
        if t > 3_000_000:
            tr = world.truth
            worst_tilt = max(worst_tilt, math.degrees(math.hypot(tr.phi, tr.theta)))
            modes.add(board.mode)
    return {"modes": modes, "tilt": worst_tilt, "crashes": len(world.crashes), "height": world.truth.h,
            "gains": {a.op: (a.status, a.value) for a in acks if a.cmd_id in (3, 4)}}


@pytest.mark.parametrize("kind", BOARDS)
def test_the_in_flight_flip_cannot_happen(kind: str) -> None:
    """The C board went to PANIC 0.42 s after the two commands and crashed at 0.79 s; now both stay level in FULL
    with the gains at the table's ends."""
    flight = _fly_with_gain_bursts(kind)
    assert flight["gains"] == {Op.GAIN_P2: (0, 1_000_000), Op.GAIN_YAW_P: (0, 5_000_000)}
    assert flight["modes"] == {Mode.FULL} and flight["crashes"] == 0
    assert flight["tilt"] < 5.0 and flight["height"] > 0.5  # still flying, level (the old C board: PANIC, crash)
