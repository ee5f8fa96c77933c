"""Keyboard flying a pilot can do (issue 13): a scripted keyboard pilot (bench/keyboard.py: it reads the screen's
height five times a second and presses a or z) hovers in FULL with the lift keys alone and holds 1 m within
±0.5 m for 30 s, on fcb_sim's board on a simulated clock.

What limits the hold is not the key's step (1 % of lift; 0.5 % and 0.25 % did no better) but the height estimate
the pilot reads: in climbing and sinking flight it is 0.15-0.4 m off the truth. Seven of seeds 1-8 stay within
0.5 m, seed 5 strays to 0.9 m (``python -m bench.keyboard`` prints each)."""

from __future__ import annotations

from tests.support.keyboard_rig import hold_deviation, keyboard_hover


def test_a_keyboard_pilot_holds_its_height_within_half_a_metre_for_30_s() -> None:
    track, presses = keyboard_hover(seed=1)
    assert hold_deviation(track) <= 0.5
    assert presses < 400  # a person's worth of presses, not a machine's
