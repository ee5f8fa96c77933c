"""Lessons 1 and 2 done wrong on purpose (issue 34): lesson 1 scores the mistake it teaches (arming before
calibrating), lesson 2 says what a crash hit and how fast, and its goal names the draught. Flown on the lessons'
rig (tests/support/lessons_rig.py: term's station and lesson driver, fcb_sim's board and instructor)."""

from __future__ import annotations

from typing import Any

from term.input.keymap import DEFAULT_KEYMAP
from term.lessons.engine import Result
from term.lessons.spec import load_lessons, maneuvers
from tests.support.lessons_rig import Rig

LESSONS, _ = load_lessons(actions=[b.action.name for b in DEFAULT_KEYMAP])


def fly(number: int, script: list[dict[str, Any]]) -> tuple[Rig, Result]:
    rig = Rig(1)
    rig.run(0.5)
    return rig, rig.fly_lesson(LESSONS[number], maneuvers(script, "test pilot"))


def test_lesson_1_fails_a_pilot_who_arms_before_calibrating() -> None:
    rig, r = fly(1, [{"press": "mode_manual"}, {"wait": "mode == 'MANUAL'", "timeout": 5}, {"pause": 1},
                     {"press": "mode_safe"}, {"wait": "mode == 'SAFE'"}])
    assert not r.passed and r.failed_step == 1, (r.score, r.lines)
    assert "armed MANUAL before calibrating" in r.failed, r.failed
    assert r.advice.startswith("Calibrate before you arm"), r.advice


def test_lesson_2_says_what_a_crash_hit_and_how_fast_and_names_the_draught() -> None:
    assert "draught" in LESSONS[2].goal
    rig, r = fly(2, [{"press": "mode_manual"}, {"wait": "mode == 'MANUAL'", "timeout": 5},
                     {"hover": [0, 0, 1.2], "timeout": 20}, {"sticks": {"lift": 0}, "for": 5}])  # cut at 1.2 m
    assert not r.passed and "crashed into " in r.failed, (r.failed, r.lines)
    assert r.failed.startswith("crashed into the floor at ") and r.failed.endswith(" m/s"), r.failed
    assert rig.board.world.crashes
