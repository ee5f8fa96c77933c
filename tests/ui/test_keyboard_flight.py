"""Keyboard flying a pilot can do (issues 13 and 22): a scripted keyboard pilot (bench/keyboard.py: it watches the
craft five times a second, as term --sim's room view shows it, and presses a or z) hovers in FULL with the lift
keys alone and holds 1 m within ±0.3 m for 30 s, on fcb_sim's board on a simulated clock.

Near hover a press moves the lift by a quarter step (the protocol's lift_trim_after); ``python -m bench.keyboard``
prints every seed (8 of 8 within 0.3 m) and its docstring the figures beside the old 1 % step and the screen's
height estimate."""

from __future__ import annotations

from tests.support.keyboard_rig import GOAL_M, hold_deviation, keyboard_hover


def test_a_keyboard_pilot_holds_its_height_within_0_3_m_for_30_s() -> None:
    track, presses = keyboard_hover(seed=1)
    assert hold_deviation(track) <= GOAL_M
    assert presses < 400  # a person's worth of presses, not a machine's
