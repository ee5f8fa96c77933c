"""Hostile lesson files (issue 23): a teacher's TOML is data, and the expression language has resource limits by
construction. Every bad file is skipped with one line at load; an expression that goes wrong at run time is a
value of None (the step's condition reads false, a grade is "not measured"), never a traceback, a MemoryError or a
frozen display."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from term.lessons.expr import Expr, ExprError
from term.lessons.observe import NAMES
from term.lessons.spec import LessonError, load_lesson, load_lessons

NS = {name: 1.0 for name in NAMES} | {"mode": "MANUAL", "on_ground": True, "refusals": 0, "landings": 0}

LESSON = """number = 70
title = "hostile"
goal = "nothing"
[[step]]
say = "go"
done = {done}
points = 100
[[advice]]
say = {say}
"""


def _lesson(tmp_path: Path, done: str = '"h > 1"', say: str = '"ok"') -> Path:
    f = tmp_path / "70.toml"
    f.write_text(LESSON.format(done=done, say=say))
    return f


# The expressions of the issue: each allocated a gigabyte or more, or ended the terminal with MemoryError.
BOMBS = ["'x' * 99999999999 == mode", "'xxxxxxxxxx' * 100000000 == mode", "(1,) * 999999999 == mode",
         "(h,h,h,h) * 100000000 == mode", "mode * 99999999999 == mode", "99999999999 * mode == mode",
         "'%999999999d' % 1 == mode", "mode % 1 == mode", "[1] * 999999999 == mode", "mode + mode == mode",
         "min('x' * 999999999) == mode", "round(h, 99999999999999999999) > 0", "(h,) + (h,) == mode"]


@pytest.mark.parametrize("text", BOMBS)
def test_no_expression_repeats_text_or_tuples(text: str) -> None:
    try:
        e = Expr(text, NAMES)
    except ExprError as exc:
        assert "\n" not in str(exc)
        return
    t0 = time.process_time()
    assert e(NS) in (None, False)  # failed: the condition reads false
    assert time.process_time() - t0 < 1.0  # not a timing test: a bomb costs seconds, a refusal microseconds


@pytest.mark.parametrize("text", ["-" * 499 + "h", "(" * 240 + "h" + ")" * 240, "not " * 120 + "h",
                                  " + ".join(["h"] * 160), "abs(" * 120 + "h" + ")" * 120])
def test_deep_or_long_expressions_are_refused_at_load_or_work(text: str) -> None:
    try:
        e = Expr(text, NAMES)
    except ExprError as exc:
        assert "\n" not in str(exc)
        return
    e(NS)


def test_ordinary_expressions_still_work() -> None:
    assert Expr("mode in ('MANUAL', 'FULL')", NAMES)(NS) is True
    assert Expr("abs(h - 2) <= 1.5 and not on_ground == False", NAMES)(NS) is True
    assert Expr("max(h, 3) + min(1, 2) * 2 % 3", NAMES)(NS) == 5.0
    assert Expr("round(h * 10) / 10", NAMES)(NS) == 1.0
    assert Expr("mode == 'MANUAL'", NAMES)(NS) is True


@pytest.mark.parametrize("say", ['"{h:999999999}"', '"{h:.999999999f}"', '"{h:>99999999}"'])
def test_text_fields_cannot_ask_for_huge_formatting(tmp_path: Path, say: str) -> None:
    with pytest.raises(LessonError) as info:
        load_lesson(_lesson(tmp_path, say=say))
    assert "\n" not in str(info.value) and "70.toml" in str(info.value)


def test_a_fifo_lesson_is_skipped_in_one_line_without_hanging(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "70.toml")
    lessons, skipped = load_lessons([tmp_path])
    assert 70 not in lessons and len(skipped) == 1 and "FIFO" in skipped[0] and "\n" not in skipped[0]


def test_a_link_to_dev_zero_and_a_huge_file_are_skipped(tmp_path: Path) -> None:
    (tmp_path / "70.toml").symlink_to("/dev/zero")
    (tmp_path / "71.toml").write_bytes(b"#" * 2_000_000)
    lessons, skipped = load_lessons([tmp_path])
    assert 70 not in lessons and 71 not in lessons and len(skipped) == 2, skipped
    assert any("device" in s for s in skipped) and any("larger than" in s for s in skipped)


@pytest.mark.parametrize("body", ["a = " + "[" * 5000 + "]" * 5000, "a = " + "{b=" * 2000 + "1" + "}" * 2000,
                                  "\xff\xfe", "number = 1e999", "number = " + "9" * 400],
                         ids=["arrays", "tables", "utf8", "inf", "digits"])
def test_malformed_lesson_files_are_one_line(tmp_path: Path, body: str) -> None:
    (tmp_path / "70.toml").write_bytes(body.encode("latin-1") if body.startswith("\xff") else body.encode())
    lessons, skipped = load_lessons([tmp_path])
    assert 70 not in lessons and len(skipped) == 1 and "\n" not in skipped[0] and "70.toml" in skipped[0]


def test_a_bomb_in_a_lesson_file_is_refused_at_load(tmp_path: Path) -> None:
    lessons, skipped = load_lessons([_lesson(tmp_path, done="\"'x' * 99999999999 == mode\"").parent])
    assert 70 not in lessons and len(skipped) == 1 and "70.toml" in skipped[0]


_atoms = st.sampled_from(["h", "mode", "'x'", "(1,)", "(h, h)", "99999999999", "1e308", "0", "-1", "True",
                          "on_ground", "'MANUAL'", "1.5"])
_ops = st.sampled_from([" * ", " + ", " - ", " / ", " % ", " == ", " < ", " and ", " or ", " in "])


@st.composite
def _expressions(draw: st.DrawFn) -> str:
    parts = [draw(_atoms)]
    for _ in range(draw(st.integers(0, 6))):
        parts += [draw(_ops), draw(_atoms)]
    text = "".join(parts)
    for f in draw(st.lists(st.sampled_from(["abs", "min", "max", "round", "not ", "-"]), max_size=3)):
        text = f"{f}({text})" if f.isalpha() else f"{f}({text})"
    return text


@settings(max_examples=400, deadline=None)
@given(_expressions())
def test_any_expression_loads_and_runs_quickly_or_is_one_line(text: str) -> None:
    try:
        e = Expr(text, NAMES)
    except ExprError as exc:
        assert "\n" not in str(exc)
        return
    t0 = time.process_time()
    e(NS)
    assert time.process_time() - t0 < 1.0


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=400))
def test_any_lesson_bytes_load_or_are_skipped_in_one_line(tmp_path_factory: pytest.TempPathFactory,
                                                          data: bytes) -> None:
    d = tmp_path_factory.mktemp("l")
    (d / "70.toml").write_bytes(b"number = 70\ntitle = \"t\"\ngoal = \"g\"\n" + data)
    lessons, skipped = load_lessons([d])
    assert all("\n" not in s for s in skipped)


@pytest.mark.parametrize("situation", ['{ do = "wind", n = 1e999 }', '{ do = "wind", n = ' + "9" * 400 + " }",
                                       '{ do = "motor", motor = 1.5 }', '{ do = "cable", cuts = [[0, 60], [60, 60], '
                                       "[120, 60]] }", '{ do = "radio", cut = nan }'])
def test_a_situation_the_simulator_would_refuse_is_refused_at_load(tmp_path: Path, situation: str) -> None:
    f = tmp_path / "70.toml"
    f.write_text(LESSON.format(done='"h > 1"', say='"ok"').replace('points = 100\n',
                                                                    f"points = 100\nsituation = [{situation}]\n"))
    with pytest.raises(LessonError) as info:
        load_lesson(f)
    assert "situation" in str(info.value) and "\n" not in str(info.value)


def test_a_folder_of_thousands_of_lesson_files_is_read_only_so_far(tmp_path: Path) -> None:
    from term.lessons.spec import MAX_FILES

    for i in range(MAX_FILES + 5):
        (tmp_path / f"{i:05d}.toml").write_text("number = = 1")
    lessons, skipped = load_lessons([tmp_path])
    assert len(skipped) == MAX_FILES + 1 and "more than" in skipped[-1] and "\n" not in skipped[-1]
