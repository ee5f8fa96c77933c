"""The lessons' parts on their own, fast and exact: the expression language, the lesson file's checks, the attempt's
scoring on hand-made variables, the progress file, and the driver's hand-over to the pilot."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from term.input.keymap import DEFAULT_KEYMAP
from term.lessons.autopilot import Autopilot, Press, Stick
from term.lessons.driver import LessonDriver
from term.lessons.engine import ENDED, RUNNING, WAITING, LessonRun, fill
from term.lessons.expr import Expr, ExprError
from term.lessons.observe import NAMES, Box
from term.lessons.progress import Progress, load
from term.lessons.spec import DEMO, LessonError, load_lesson, load_lessons, load_script, maneuvers
from term.session.model import Model
from tests.support.paths import DOCS

ACTIONS = [b.action.name for b in DEFAULT_KEYMAP]

# --- expressions -----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("text, ns, value", [
    ("h > 0.8 and in_box", {"h": 1.0, "in_box": True}, True),
    ("mode == 'MANUAL'", {"mode": "MANUAL"}, True),
    ("abs(h - 2) <= 0.2", {"h": 1.85}, True),
    ("mode in ('FULL', 'RAW')", {"mode": "RAW"}, True),
    ("mode not in ('FULL', 'RAW')", {"mode": "RAW"}, False),
    ("0.5 < h < 1.5", {"h": 1.6}, False),
    ("max(refusals, 2) * 10 % 7", {"refusals": 3}, 2),
    ("not on_ground", {"on_ground": False}, True),
    ("h > 1", {"h": None}, False),  # not known yet: every comparison is false
    ("h / step_time", {"h": 1.0, "step_time": 0.0}, None),  # division by zero: no value
    ("mode > 3", {"mode": "SAFE"}, None),  # a type mismatch: no value (false), never an exception
    ("-h", {"h": None}, None),
])
def test_expressions_evaluate_without_eval_and_unknowns_are_false(text: str, ns: dict, value: object) -> None:
    e = Expr(text, NAMES)
    assert e(ns) == value
    assert e.true(ns) == bool(value)


@pytest.mark.parametrize("text, why", [
    ("__import__('os').system('x')", "a call of anything but"),
    ("h.real", "Attribute is not allowed"),
    ("[h][0]", "Subscript is not allowed"),
    ("lambda: 1", "Lambda is not allowed"),
    ("hieght > 1", "unknown name 'hieght' (did you mean 'height'?"),
    ("h >", "is not an expression"),
    ("h ** 2", "the operator Pow"),
    ("mode in modes", "'in' with anything but a tuple of constants"),
    ("mode in (h,)", "'in' with anything but a tuple of constants"),
    ("abs", "abs without a call"),
    ("", "non-empty"),
    ("h" * 600, "longer than 500"),
    ("b'x' == h", "the constant b'x'"),
])
def test_anything_but_the_small_language_is_a_load_error_that_says_what(text: str, why: str) -> None:
    names = set(NAMES) | {"height"}
    with pytest.raises(ExprError, match=None) as info:
        Expr(text, names)
    assert why in str(info.value)


def test_fill_shows_variables_and_nothing_else() -> None:
    assert fill("at {touchdown:.2f} m/s, {refusals} refused", {"touchdown": 0.61234, "refusals": 2}) == \
        "at 0.61 m/s, 2 refused"
    assert fill("{h:.1f} and {missing}", {"h": None}) == "? and ?"
    assert fill("{h.__class__}", {"h": 1.0}) == "{h.__class__}"  # not a field: left as it is


# --- lesson files ---------------------------------------------------------------------------------------------

MINIMAL = """
number = 42
title = "t"
goal = "g"
box = { height = 1.0, size = 1.0, tall = 0.4 }
[[step]]
say = "arm"
done = "mode == 'FULL'"
points = 20
[[step]]
say = "hold"
done = "in_box"
hold = 2
timeout = 10
timeout_why = "not held (h {h:.1f})"
points = 50
penalty = [ { while = "speed > 1", per_s = 10, why = "too fast" } ]
fail = [ { when = "crashes > 0", why = "crashed" } ]
situation = [ { do = "wind", n = -1.0 } ]
[[step]]
say = "land"
done = "on_ground"
points = 30
grade = [ { name = "td", value = "touchdown", best = 0.2, worst = 0.6, points = 20, why = "down at {value:.1f}" } ]
[[penalty]]
count = "refusals"
each = 5
why = "refused"
[[advice]]
when = "failed"
say = "try again"
[[advice]]
when = "td > 0.3"
say = "softer"
[[advice]]
say = "good"
[[show]]
press = "mode_full"
[[show]]
hover = [0, 0, 1]
for = 3
"""


def write(tmp_path: Path, text: str, name: str = "42-test.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_a_teachers_lesson_loads_and_a_number_of_a_built_in_one_replaces_it(tmp_path: Path) -> None:
    lesson = load_lesson(write(tmp_path, MINIMAL), ACTIONS)
    assert lesson.number == 42 and lesson.total_points == 100 and lesson.box == Box(height=1.0, tall=0.4)
    assert lesson.steps[1].hold == 2 and lesson.steps[1].situation == ({"do": "wind", "n": -1.0},)
    write(tmp_path, MINIMAL.replace("number = 42", "number = 3").replace('title = "t"', 'title = "mine"'),
          "my-3.toml")
    lessons, skipped = load_lessons([tmp_path], ACTIONS)
    assert not skipped and lessons[3].title == "mine" and lessons[42].title == "t" and lessons[1].number == 1
    title, goal, show = load_script(DEMO, ACTIONS)
    assert title == "demo" and show[-1].verb == "pause" and (show[-1].say or "").startswith("That was the tour")


@pytest.mark.parametrize("change, why", [
    (("title = \"t\"", "title = \"t\"\ncolour = \"red\""), "unknown field colour"),
    (("done = \"on_ground\"", "done = \"on_gruond\""), "step[2].done: 'on_gruond': unknown name"),
    (("{ do = \"wind\", n = -1.0 }", "{ do = \"wind\", speed = 3 }"), "wind: unknown argument speed"),
    (("{ do = \"wind\", n = -1.0 }", "{ do = \"flood\" }"), "unknown situation 'flood'"),
    (("[[advice]]\nsay = \"good\"", "[[advice]]\nwhen = \"true\"\nsay = \"good\""), "unknown name 'true'"),
    (("[[advice]]\nsay = \"good\"", ""), "the last advice has no 'when'"),
    (("press = \"mode_full\"", "press = \"mode_fly\""), "no key map action 'mode_fly'"),
    (("points = 50", "points = 50\nduration = 5"), "a goal (done, optionally with hold) or a duration"),
    (("timeout = 10", "timeout = -1"), "must be between"),
    (("hold = 2", "hold = \"2\""), "expected a number"),
    (("not held (h {h:.1f})", "not held ({hh})"), "{hh}: not a variable"),
    (("count = \"refusals\"", "count = \"refusal\""), "unknown counter 'refusal'"),
    (("name = \"td\"", "name = \"h\""), "must be a new identifier"),
    (("hover = [0, 0, 1]", "hover = [0, 0]"), "expected [north, east, height]"),
    (("number = 42", "number = 4.5"), "not a whole number"),
    (("[[step]]\nsay = \"arm\"", "[[stepp]]\nsay = \"arm\""), "unknown field stepp"),
])
def test_a_bad_lesson_file_is_one_line_naming_the_file_and_the_field(tmp_path: Path, change: tuple[str, str],
                                                                     why: str) -> None:
    old, new = change
    assert old in MINIMAL
    path = write(tmp_path, MINIMAL.replace(old, new, 1))
    with pytest.raises(LessonError) as info:
        load_lesson(path, ACTIONS)
    assert str(info.value).startswith("42-test.toml") and why in str(info.value)
    lessons, skipped = load_lessons([tmp_path], ACTIONS)
    assert 42 not in lessons and len(skipped) == 1 and why in skipped[0] and len(lessons) == 8


def test_not_toml_and_not_readable_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(LessonError, match="not valid TOML"):
        load_lesson(write(tmp_path, "number = = 1"))
    with pytest.raises(LessonError, match="No such file"):
        load_lesson(tmp_path / "nothing.toml")
    write(tmp_path, "\xff\xfe garbage", "bad.toml")
    (tmp_path / "bad.toml").write_bytes(b"\xff\xfe\x00garbage")
    _, skipped = load_lessons([tmp_path])
    assert any("bad.toml is not UTF-8" in line for line in skipped)


# --- the attempt's scoring ------------------------------------------------------------------------------------


def ns(**kw: object) -> dict[str, object]:
    base: dict[str, object] = dict.fromkeys(NAMES)
    base.update(mode="SAFE", on_ground=True, crashes=0, refusals=0, speed=0.0, in_box=False, touchdown=0.0, h=0.0,
                n=0.0, e=0.0, heading=0.0, landings=0)
    base.update(kw)
    return base


def run_through(run: LessonRun, frames: list[tuple[float, dict[str, object]]]) -> list[dict[str, object]]:
    sent = []
    for t, frame in frames:
        sent += run.update({**frame, **run.step_vars(t)}, t)
    return sent


def test_scoring_steps_holds_penalties_grades_and_advice(tmp_path: Path) -> None:
    lesson = load_lesson(write(tmp_path, MINIMAL), ACTIONS)
    run = LessonRun(lesson, 0.0)
    assert run.update(ns(mode="FULL", on_ground=False), 0.0) == [] and run.state == WAITING  # not on the floor
    frames = [(1.0, ns())]  # SAFE on the floor: the attempt starts
    frames += [(1.1, ns(mode="FULL"))]  # step 1 done
    # step 2: in the box, broken after 1.5 s (the hold starts again), fast for 1 s, then held 2 s
    t = 1.2
    for _k in range(15):
        frames.append((t, ns(mode="FULL", on_ground=False, in_box=True, h=1.0)))
        t += 0.1
    frames.append((t, ns(mode="FULL", on_ground=False, in_box=False, h=1.3)))
    t += 0.1
    for _k in range(10):
        frames.append((t, ns(mode="FULL", on_ground=False, in_box=False, speed=1.5, refusals=1)))
        t += 0.1
    for _k in range(22):
        frames.append((t, ns(mode="FULL", on_ground=False, in_box=True, h=1.0, refusals=1)))
        t += 0.1
    frames.append((t, ns(mode="FULL", on_ground=True, touchdown=0.4, refusals=1)))  # step 3: landed at 0.4
    sent = run_through(run, frames)
    assert sent == [{"do": "reset", "soc": 0.9}, {"do": "wind", "n": -1.0}, {"do": "wind"}]  # (still air after)
    assert run.state == ENDED
    r = run.result
    assert r is not None and r.passed and not r.failed
    # 20 + (50 - 10 too fast) + (30 - 20 * (0.4 - 0.2) / 0.4) - 5 refused = 20 + 40 + 20 - 5 = 75
    assert r.score == 75
    assert r.lines == ["step 2: too fast: -10", "step 3: down at 0.4: -10", "refused: -5"]
    assert r.values == {"td": 0.4} and r.advice == "softer"


def test_a_failure_ends_the_attempt_with_the_points_so_far(tmp_path: Path) -> None:
    lesson = load_lesson(write(tmp_path, MINIMAL), ACTIONS)
    run = LessonRun(lesson, 0.0)
    run_through(run, [(0.0, ns()), (0.1, ns(mode="FULL")), (0.2, ns(mode="FULL", on_ground=False, crashes=1))])
    r = run.result
    assert r is not None and not r.passed and r.failed == "crashed" and r.failed_step == 2
    assert r.score == 20 and r.steps_done == 1 and r.advice == "try again" and r.lines[0] == "step 2: crashed"
    run = LessonRun(lesson, 0.0)
    run_through(run, [(0.0, ns()), (0.1, ns(mode="FULL")), (10.2, ns(mode="FULL", on_ground=False, h=1.26))])
    assert run.result is not None and run.result.failed == "not held (h 1.3)"


def test_a_duration_step_ends_on_time_whatever_happens(tmp_path: Path) -> None:
    text = MINIMAL.replace('done = "in_box"\nhold = 2', "duration = 3")
    run = LessonRun(load_lesson(write(tmp_path, text), ACTIONS), 0.0)
    run_through(run, [(0.0, ns()), (0.1, ns(mode="FULL")), (1.0, ns(mode="FULL", on_ground=False))])
    assert run.state == RUNNING and run.index == 1
    run_through(run, [(3.15, ns(mode="FULL", on_ground=False))])
    assert run.index == 2 and run.caption == "3/3 land"


# --- progress ---------------------------------------------------------------------------------------------------


def test_progress_keeps_the_best_and_survives_a_damaged_file(tmp_path: Path) -> None:
    path = tmp_path / "data" / "lessons.json"
    p = load(path)
    assert not p.lessons and not p.problem and p.next_lesson([1, 2, 3]) == 1
    p.record(1, 55, False, 1000.0)
    p.record(1, 90, True, 1001.0)
    p.record(1, 70, True, 1002.0)
    assert p.save() is None
    q = load(path)
    assert q.get(1).best == 90 and q.get(1).last == 70 and q.get(1).attempts == 3 and q.get(1).passed
    assert q.next_lesson([1, 2, 3]) == 2 and not list(path.parent.glob(".lessons-*"))
    path.write_text('{"format": 1, "lessons": {"1": {"best": "lots"}}}')
    r = load(path)
    assert not r.lessons and "unreadable" in r.problem and (path.parent / "lessons.json.bad").exists()
    path.write_bytes(b"\x00\xff")
    assert "unreadable" in load(path).problem


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_progress_that_cannot_be_written_is_one_line(tmp_path: Path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    p = Progress(ro / "lessons.json")
    p.record(2, 10, False, 0.0)
    assert "cannot save lesson progress" in (p.save() or "")


def test_progress_in_a_file_where_a_directory_should_be_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    p = Progress(tmp_path / "f" / "lessons.json")
    p.record(2, 10, False, 0.0)
    assert "cannot save lesson progress" in (p.save() or "")
    assert json.loads(json.dumps({"ok": 1}))  # (the file itself never half-written: written, then renamed)


# --- the driver and the autopilot ------------------------------------------------------------------------------


def test_a_key_of_the_pilot_stops_the_autopilot_and_the_caption_says_what_runs() -> None:
    d = LessonDriver()
    script = maneuvers([{"press": "mode_calibration", "say": "calibrating"}, {"wait": "calibrations >= 1"}],
                       "t", ACTIONS)
    d.start_script("demo", "the tour", script, 0.0)
    model = Model(start=0.0)
    tick = d.tick(model, 0.0)
    assert tick.acts[0] == Press("mode_calibration") and type(tick.acts[1]) is Stick
    assert d.caption == "autopilot: calibrating" and d.flying
    assert d.pilot_acted(0.1) and not d.flying and not d.pilot_acted(0.2)
    assert d.caption == "autopilot stopped: the pilot took over"


def test_the_autopilot_gives_up_after_a_timeout_and_says_where() -> None:
    ap = Autopilot(maneuvers([{"wait": "mode == 'FULL'", "timeout": 2}], "t"), 0.0)
    ap.update(ns(mode="SAFE"), None, 0.0)
    ap.update(ns(mode="SAFE"), None, 2.5)
    assert ap.state == "failed" and ap.why == "gave up on step 1 (wait: mode == 'FULL') after 2 s"


def test_the_guides_table_of_variables_is_the_observers() -> None:
    from term.lessons.observe import names_markdown

    text = (DOCS / "lessons.md").read_text()
    table = text.split("<!-- variables:begin -->\n", 1)[1].split("<!-- variables:end -->", 1)[0]
    assert table == names_markdown(), "regenerate the table: term.lessons.observe.names_markdown()"


def test_an_attempt_that_ends_puts_back_the_faults_it_injected() -> None:
    """Issue 22: lesson 7's stuck motor outlived the attempt (the next take-off crashed with it still failed)."""
    lessons, _ = load_lessons([], ACTIONS)
    run = LessonRun(lessons[7], 0.0)
    sent = run.update(ns(), 0.0)  # on the floor in SAFE: the attempt starts from the pad
    assert sent[0]["do"] == "reset"
    for k in range(40):  # step 1: in the box in FULL for 3 s
        sent += run.update({**ns(mode="FULL", on_ground=False, in_box=True, h=1.0), **run.step_vars(0.1 + k * 0.1)},
                           0.1 + k * 0.1)
    assert {"do": "motor", "motor": 2, "level": 380} in sent and run.state == RUNNING
    end = run.update({**ns(mode="FULL", on_ground=True, crashes=1), **run.step_vars(5.0)}, 5.0)
    assert run.state == ENDED and end == [{"do": "motor", "motor": 2, "level": -1}]
    # stopped by the pilot (or another lesson started): the driver sends the undo at its next tick
    d = LessonDriver()
    d.start_lesson(lessons[7], 0.0)
    model = Model(start=0.0)
    d.run.update(ns(), 0.0)  # type: ignore[union-attr]
    d.run.sent += [{"do": "wind", "n": 2.0}, {"do": "cable", "cuts": [[0.0, 1.0]]}]  # type: ignore[union-attr]
    d.stop(model, 1.0)
    d.start_lesson(lessons[2], 1.0)
    assert d.tick(model, 1.1).situations == [{"do": "wind"}, {"do": "cable", "cuts": []}]
    assert d.tick(model, 1.2).situations == []


def test_the_advice_follows_the_score() -> None:
    """Issue 22: lesson 2's advice after "10/100 not passed ... the board had to PANIC by itself" was "Good. Now try
    FULL"; lesson 5 failed at its FULL climb got HEIGHT advice. The last advice (said otherwise) is for a pass."""
    lessons, _ = load_lessons([], ACTIONS)
    run = LessonRun(lessons[2], 0.0)
    run.update(ns(), 0.0)
    run.update({**ns(mode="MANUAL", on_ground=False, board_panics=1), **run.step_vars(1.0)}, 1.0)
    r = run.result
    assert r is not None and not r.passed and r.failed.startswith("the board had to PANIC")
    assert not r.advice.startswith("Good") and "again" in r.advice
    for n, lesson in lessons.items():  # passed: the lesson's own last word
        run = LessonRun(lesson, 0.0)
        run.update(ns(), 0.0)
        run.stop(ns(), 1.0)
        assert run.result is not None and run.result.advice != lesson.advice[-1].say, n
