"""HEIGHT: the lift keys move the height set point, said by an event, and leave the lift trim alone (issue 34: z x4
moved the trim silently, then leaving HEIGHT dropped the craft); the terminal's line names the set point in metres."""

from __future__ import annotations

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.commands import execute
from term.core.protocol import (
    HEIGHT_KEY_STEP_MM,
    HEIGHT_SETPOINT_MAX_MM,
    HEIGHT_SETPOINT_MIN_MM,
    Command,
    Decoder,
    Event,
    EventCode,
    Mode,
    Nak,
    Op,
)
from term.session.texts import event_text


def cmd(board: Board, op: Op, arg: int = 0) -> tuple[Nak, int]:
    status, value, after = execute(board.parts, Command(1, op, arg))
    if after is not None:
        after()
    return Nak(status), value


def setpoint_events(board: Board) -> list[int]:
    board.advance(board.now + 100_000)
    return [p.arg for p in Decoder().feed(board.uart_transmit())
            if type(p) is Event and p.code == EventCode.HEIGHT_SETPOINT]


def step(sp: float, presses: int) -> float:
    """The set point after ``presses``: kept in the keys' range, never moved against the press."""
    lo, hi, new = HEIGHT_SETPOINT_MIN_MM / 1000, HEIGHT_SETPOINT_MAX_MM / 1000, sp + presses * HEIGHT_KEY_STEP_MM / 1000
    return min(new, max(hi, sp)) if presses > 0 else max(new, min(lo, sp))


def in_height(board: Board) -> None:
    assert cmd(board, Op.MODE, Mode.CALIBRATION)[0] == Nak.OK
    board.advance(board.now + 1_500_000)
    assert board.modes.mode == Mode.SAFE
    for mode in (Mode.FULL, Mode.HEIGHT):
        assert cmd(board, Op.MODE, mode) == (Nak.OK, mode)
    setpoint_events(board)  # (what came before)


def test_the_lift_keys_move_the_set_point_in_height_and_say_so() -> None:
    board = Board(BoardConfig(boot_hello=False))
    in_height(board)
    trim, sp = board.modes.trims.lift, board.core.setpoint
    assert cmd(board, Op.TRIM_LIFT, +1) == (Nak.OK, trim)  # the Ack carries the trim: unchanged
    assert cmd(board, Op.TRIM_LIFT, +1)[0] == Nak.OK
    said = setpoint_events(board)
    want = round(step(step(sp, 1), 1) * 1000)
    assert said[-1] == want and abs(board.core.setpoint * 1000 - want) < 1
    assert board.modes.trims.lift == trim
    cmd(board, Op.TRIM_LIFT, -4)  # z x4
    assert setpoint_events(board)[-1] == round(step(want / 1000, -4) * 1000)
    assert board.modes.trims.lift == trim
    cmd(board, Op.TRIM_LIFT, +100)  # kept under the room's ceiling
    assert setpoint_events(board)[-1] == HEIGHT_SETPOINT_MAX_MM
    severity, text = event_text(EventCode.HEIGHT_SETPOINT, HEIGHT_SETPOINT_MAX_MM)
    assert text.startswith("HEIGHT set point 2.50 m")


def test_out_of_height_the_lift_keys_trim_the_lift() -> None:
    board = Board(BoardConfig(boot_hello=False))
    in_height(board)
    assert cmd(board, Op.MODE, Mode.FULL)[0] == Nak.OK
    before = board.modes.trims.lift
    assert cmd(board, Op.TRIM_LIFT, +1)[1] > before and setpoint_events(board) == []


def test_a_crash_event_says_its_unit() -> None:
    assert event_text(EventCode.CRASH, 3779)[1].startswith("crash at 3.78 m/s")


def test_a_press_never_moves_the_set_point_against_itself() -> None:
    board = Board(BoardConfig(boot_hello=False))
    in_height(board)
    board.core.setpoint = 2.9  # (as if held above the keys' ceiling: entered HEIGHT up there)
    board.core.move_setpoint(0.0, 0.0, 10.0)  # (the offset follows: the next steps see 2.9)
    assert abs(board.core.move_setpoint(0.1, 0.2, 2.5) - 2.9) < 1e-9  # neither down nor further up
    assert abs(board.core.move_setpoint(-0.1, 0.2, 2.5) - 2.8) < 1e-9
