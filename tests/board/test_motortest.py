"""The bench motor test on both boards (the Python board and the C board through fcb_sim/hosts/cboard.py), through
their bytes: the guards (out of SAFE, lift up, a crash, past the level cap, a bad mask), the board's own stops
(time up, a key's level 0, a mode change, the lift, a silent terminal), the motors turning in Motion and the flag
in Status, and the board's qb_log line about it (Text packets) on the terminal's console."""

from __future__ import annotations

import pytest

from term.core.protocol import (
    MOTOR_TEST_LINK_MS,
    MOTOR_TEST_MAX_LEVEL,
    MOTOR_TEST_MAX_MS,
    Event,
    EventCode,
    Flag,
    Mode,
    Motion,
    MotorTestEnd,
    Nak,
    Op,
    Status,
    motor_test_arg,
)
from tests.support.bench_rig import KINDS, Pc, make_board


@pytest.fixture(params=KINDS)
def pc(request: pytest.FixtureRequest) -> Pc:
    p = Pc(make_board(request.param))
    p.run(0.2)
    return p


def _ends(pc: Pc) -> list[int]:
    return [e.arg for e in pc.of(Event) if e.code == EventCode.MOTOR_TEST]


def _motors(pc: Pc) -> tuple[int, int, int, int]:
    m = pc.of(Motion)[-1]
    return m.ae1, m.ae2, m.ae3, m.ae4


def test_one_motor_spins_shows_in_telemetry_and_stops_by_itself(pc: Pc) -> None:
    ack = pc.ok(Op.MOTOR_TEST, motor_test_arg(0b0010, 200))
    assert ack.value == 200
    assert pc.run_until(lambda: _motors(pc) == (0, 200, 0, 0), 0.3)
    assert pc.run_until(lambda: pc.of(Status)[-1].flags & Flag.MOTOR_TEST, 0.5)
    assert pc.board.mode == Mode.SAFE
    # the board's own qb_log line, the same words on both boards
    assert any(x.text == f"motor test: mask 2 at 200 for {MOTOR_TEST_MAX_MS} ms" for x in pc.lines)
    assert pc.run_until(lambda: _ends(pc), MOTOR_TEST_MAX_MS / 1000 + 0.2)
    assert _ends(pc) == [MotorTestEnd.TIME_UP]
    assert pc.run_until(lambda: _motors(pc) == (0, 0, 0, 0), 0.2)
    assert pc.run_until(lambda: not pc.of(Status)[-1].flags & Flag.MOTOR_TEST, 0.5)


def test_level_zero_stops_at_once(pc: Pc) -> None:
    pc.ok(Op.MOTOR_TEST, motor_test_arg(0b1111, 150))
    assert pc.run_until(lambda: _motors(pc) == (150, 150, 150, 150), 0.3)
    pc.ok(Op.MOTOR_TEST, 0)
    assert pc.run_until(lambda: _ends(pc), 0.2) and _ends(pc) == [MotorTestEnd.STOPPED]
    assert pc.run_until(lambda: _motors(pc) == (0, 0, 0, 0), 0.2)


def test_a_mode_change_stops_it(pc: Pc) -> None:
    pc.ok(Op.MOTOR_TEST, motor_test_arg(0b0001, 100))
    assert pc.run_until(lambda: _motors(pc)[0] == 100, 0.3)
    pc.command(Op.MODE, Mode.PANIC)  # PANIC from SAFE: whatever the answer, the test must end
    pc.command(Op.MODE, Mode.MANUAL)
    assert pc.run_until(lambda: _ends(pc), 0.3) and _ends(pc)[0] == MotorTestEnd.MODE
    assert pc.board.mode != Mode.SAFE or _motors(pc) == (0, 0, 0, 0)


def test_lift_up_stops_it_and_refuses_it(pc: Pc) -> None:
    pc.ok(Op.MOTOR_TEST, motor_test_arg(0b0100, 100))
    pc.ok(Op.TRIM_LIFT, 5)
    assert pc.run_until(lambda: _ends(pc), 0.3) and _ends(pc) == [MotorTestEnd.LIFT]
    assert pc.command(Op.MOTOR_TEST, motor_test_arg(0b0100, 100)).status == Nak.LIFT_NOT_ZERO
    assert pc.run_until(lambda: _motors(pc) == (0, 0, 0, 0), 0.2)


def test_a_silent_terminal_stops_it(pc: Pc) -> None:
    pc.ok(Op.MOTOR_TEST, motor_test_arg(0b1000, 120))
    assert pc.run_until(lambda: _motors(pc)[3] == 120, 0.3)
    pc.answer = False  # the terminal went quiet (a pulled cable, a frozen laptop)
    assert pc.run_until(lambda: _ends(pc), MOTOR_TEST_LINK_MS / 1000 + 0.3)
    assert _ends(pc) == [MotorTestEnd.LINK_SILENT]
    assert _motors(pc) == (0, 0, 0, 0)


def test_refused_out_of_safe_past_the_cap_and_with_a_bad_mask(pc: Pc) -> None:
    assert pc.command(Op.MOTOR_TEST, motor_test_arg(0b0001, MOTOR_TEST_MAX_LEVEL + 1)).status == Nak.OUT_OF_RANGE
    assert pc.command(Op.MOTOR_TEST, motor_test_arg(0b10000, 100)).status == Nak.BAD_ARGUMENT
    pc.ok(Op.MODE, Mode.CALIBRATION)
    assert pc.command(Op.MOTOR_TEST, motor_test_arg(0b0001, 100)).status == Nak.NOT_IN_SAFE
    assert not _ends(pc) and _motors(pc) == (0, 0, 0, 0)
