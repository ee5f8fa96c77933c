"""The lift keys step finer near hover (issue 22: "49 % stays on the ground, 50 % climbs at 0.5 m/s and accelerates
to 0.9"): a press of a or z moves the lift by trim.lift_step (1 %), a quarter of it between 40 and 60 % of lift.
The rule is the protocol's (``lift_trim_after``); the Python board and the C board apply it alike, and the
terminal counts presses with it."""

from __future__ import annotations

import shutil

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fcb_sim.board.board import Board
from fcb_sim.board.parts import BoardConfig
from term.core.protocol import (
    LIFT_FINE_DIVISOR,
    LIFT_FINE_FROM,
    LIFT_FINE_TO,
    STICK_MAX,
    Ack,
    Command,
    Decoder,
    Joystick,
    Op,
    encode,
    lift_trim_after,
)

STEP = 328  # trim.lift_step's default


def one_press_at_a_time(trim: int, steps: int, lift_step: int, joystick_lift: int = 0) -> int:
    """The rule as a pilot meets it, press by press: fine while the press starts and ends in the band."""
    fine, coarse = max(1, lift_step // LIFT_FINE_DIVISOR), max(1, lift_step)
    for _ in range(abs(steps)):
        level = joystick_lift + trim
        if steps > 0:
            step = fine if LIFT_FINE_FROM <= level and level + fine <= LIFT_FINE_TO else coarse
            trim = min(STICK_MAX, trim + step)
        else:
            step = fine if level <= LIFT_FINE_TO and level - fine >= LIFT_FINE_FROM else coarse
            trim = max(0, trim - step)
    return trim


@given(st.integers(0, STICK_MAX), st.integers(-400, 400), st.integers(1, 4096), st.integers(-32768, STICK_MAX))
def test_a_burst_of_presses_is_the_presses_one_at_a_time(trim: int, steps: int, lift_step: int, js: int) -> None:
    assert lift_trim_after(trim, steps, lift_step, js) == one_press_at_a_time(trim, steps, lift_step, js)


def test_near_hover_a_press_is_a_quarter_step_and_the_take_off_stays_quick() -> None:
    trim = lift_trim_after(0, 40, STEP)  # 40 presses of 1 % from the ground reach the band
    assert trim == 40 * STEP and LIFT_FINE_FROM <= trim
    assert lift_trim_after(trim, 1, STEP) - trim == STEP // 4  # 0.25 %: 1 % of the thrust at hover
    assert lift_trim_after(trim, -1, STEP) == trim - STEP  # down out of the band: 1 % again
    hover = lift_trim_after(trim, 36, STEP)
    assert hover == 40 * STEP + 36 * 82 and abs(hover - STICK_MAX // 2) < 2 * STEP
    assert lift_trim_after(STICK_MAX, -32767, STEP) == 0  # Z: zero from anywhere, at once
    assert lift_trim_after(hover, 2**31 - 1, STEP) == STICK_MAX


def test_the_band_is_on_the_lift_the_motors_get_joystick_plus_trim() -> None:
    assert lift_trim_after(0, 1, STEP, joystick_lift=15000) == 82  # the throttle holds 46 %: the trim steps finely
    assert lift_trim_after(0, 1, STEP, joystick_lift=5000) == STEP


def _presses(board: object, presses: list[tuple[int, int]]) -> list[int]:
    """Send (joystick lift, presses) pairs in SAFE; the trim each Ack reports."""
    dec, out, t_us = Decoder(), [], 0
    for i, (js, n) in enumerate(presses):
        board.uart_receive(encode(Joystick(0, 0, 0, js, 0)))  # type: ignore[attr-defined]
        board.uart_receive(encode(Command(i & 0xFF, Op.TRIM_LIFT, n)))  # type: ignore[attr-defined]
        t_us += 20_000
        board.advance(t_us)  # type: ignore[attr-defined]
        acks = [p for p in dec.feed(board.uart_transmit()) if type(p) is Ack and p.cmd_id == i & 0xFF]  # type: ignore[attr-defined]
        assert len(acks) == 1 and acks[0].status == 0
        out.append(acks[0].value)
    return out


@pytest.mark.parametrize("kind", ["python", "c"])
def test_both_boards_step_the_lift_trim_by_the_protocols_rule(kind: str) -> None:
    if kind == "c":
        if shutil.which("cc") is None or shutil.which("make") is None:
            pytest.skip("no C compiler (cc) or make")
        from fcb_sim.hosts.cboard import CBoard

        board: object = CBoard(BoardConfig(seed=4))
    else:
        board = Board(BoardConfig(seed=4))
    script = [(0, 3), (0, 37), (0, 1), (0, 5), (0, -1), (0, -9), (0, 60), (0, 1), (0, -32767), (12000, 4), (12000, 30),
              (12000, -2), (-5000, 7), (0, -32767), (0, 2**31 - 1), (0, -(2**31) + 1)]
    trims, want, trim = _presses(board, script), [], 0
    for js, n in script:
        trim = lift_trim_after(trim, n, STEP, js)
        want.append(trim)
    assert trims == want
