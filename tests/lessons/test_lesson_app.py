"""The lessons, the room view and the demo through the real app (Textual's Pilot) and real parts: the board served
in real time on a pseudo-terminal (fcb_sim.hosts.serve's ThreadedServer, in this process so the test can read the
world the simulator flies) with its instructor channel on a local TCP port, and term's SerialTransport,
InstructorClient and TermApp, as `term --sim` wires them. The command line's checks of --lesson and --demo come
last."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from term.cli.main import main
from term.core.protocol import FLIGHT_MODES, EventCode, Flag, Joystick, Mode
from term.lessons.observe import Box
from term.lessons.progress import default_path
from term.lessons.room import arrow
from term.lessons.spec import maneuvers
from term.ui.app import TermApp
from term.ui.widgets.lesson import LessonBar, SummaryScreen
from term.ui.widgets.room import NO_ROOM, RoomView
from tests.support.sim_app_rig import sim_app
from tests.support.waits import until

SIZE = (120, 44)


def craft_cell(view: RoomView, glyphs: str, first_col: int, cols: int) -> tuple[int, int] | None:
    """Where the view drew one of ``glyphs``, within the columns of one of its two views."""
    lines = view._shown.plain.split("\n")  # what the panel shows now
    for row, line in enumerate(lines[:-1]):
        for col in range(first_col, min(len(line), first_col + cols)):
            if line[col] in glyphs:
                return col - first_col, row
    return None


async def test_the_room_view_draws_the_craft_where_the_simulator_has_it() -> None:
    """Flown (by the autopilot, through the keys) to 1 m north, 0.7 m west, 1.1 m up, facing east: the arrow in
    the top view and the diamond in the side view sit in the cells of the simulator's own position, the arrow
    points east, the figures line gives the position, and the lesson's box turns green around it."""
    async with sim_app(seed=3) as (app, pilot, board):
        room = app.lessons.room
        await until(pilot, lambda: app.model.mode == Mode.SAFE and room is not None and room.truth)
        script = maneuvers([
            {"press": "mode_calibration"}, {"wait": "calibrations >= 1 and mode == 'SAFE'", "timeout": 10},
            {"press": "mode_full"}, {"wait": "mode == 'FULL'", "timeout": 5},
            {"hover": [1.0, -0.7, 1.1], "heading": 90, "speed": 1.0, "timeout": 60}, {"pause": 60}], "test")
        app.lessons.driver.start_script("test", "to a place in the room", script, app.clock())
        app.lessons.room.set_box(Box(north=1.0, east=-0.7, height=1.1, size=0.8, tall=0.6))
        w = board.world

        def there() -> bool:
            t = w.truth
            return (abs(t.n - 1.0) < 0.1 and abs(t.e + 0.7) < 0.1 and abs(t.h - 1.1) < 0.1
                    and abs(math.degrees(t.psi) - 90) < 10 and t.vn ** 2 + t.ve ** 2 < 0.05)

        await until(pilot, there, timeout=40)
        app.render_now()
        view = app.screen.query_one(RoomView)
        await pilot.pause(0.1)
        app.render_now()
        top, side = view.top, view.side
        assert top is not None and side is not None
        truth = w.truth  # the simulator's own (this thread reads the board's floats: fine for a check)
        at = craft_cell(view, "↑↗→↘↓↙←↖", 0, top.cols)
        assert at is not None
        expect = top.cell(truth.n, truth.e)
        assert abs(at[0] - expect[0]) <= 1 and abs(at[1] - expect[1]) <= 1, (at, expect)
        assert view._shown.plain.split("\n")[at[1]][at[0]] == arrow(90.0) == "→"
        side_at = craft_cell(view, "◆", top.cols + 1, side.cols)
        expect = side.cell(truth.e, truth.h)
        assert side_at is not None and abs(side_at[0] - expect[0]) <= 1 and abs(side_at[1] - expect[1]) <= 1
        figures = view._shown.plain.split("\n")[-1]
        n, e, h = (float(x) for x in (figures.split()[1], figures.split()[3], figures.split()[5]))
        assert abs(n - truth.n) < 0.15 and abs(e - truth.e) < 0.15 and abs(h - truth.h) < 0.15
        words = figures.split()
        assert figures.endswith("in box") and abs(int(words[words.index("hdg") + 1].rstrip("°")) - 90) < 10
        assert view.border_subtitle is not None and "6 × 6 × 3 m room" in str(view.border_subtitle)
        app.lessons.driver.stop(app.model, app.clock())


async def test_a_lesson_flown_with_the_keys_is_scored_saved_and_summed_up() -> None:
    """Lesson 1 from the command line's --lesson: the pilot's keys (3, then 2, then 0) pass it; the caption says
    each step; the summary shows 100/100 and the progress file has it; "show me" (s) lets the autopilot fly it,
    which is shown as the autopilot's and not counted."""
    path = default_path()
    if path.exists():
        path.unlink()
    async with sim_app(seed=4, lesson=1) as (app, pilot, board):
        await until(pilot, lambda: app.lessons.driver.run is not None and app.lessons.driver.run.state == "running")
        bar = app.screen.query_one(LessonBar)
        assert bar.text.startswith("lesson 1 · Arm the lab way: 1/3 Calibrate") and bar.has_class("running")
        app.simulate_key("3")
        await until(pilot, lambda: "2/3 Arm in MANUAL" in bar.text)
        app.simulate_key("2")
        await until(pilot, lambda: "3/3 Disarm" in bar.text)
        app.simulate_key("0")
        await until(pilot, lambda: isinstance(app.screen, SummaryScreen) and bool(app.screen.query("#summary-head")))
        summary = app.screen
        assert summary.result.score == 100 and summary.result.passed and not summary.shown
        head = summary.query_one("#summary-head").render()
        assert "100/100" in str(head) and "best 100/100 · 1 attempt" in str(head)
        saved = json.loads(path.read_text())
        assert saved["lessons"]["1"]["best"] == 100 and saved["lessons"]["1"]["attempts"] == 1
        await pilot.press("s")  # show me
        await until(pilot, lambda: isinstance(app.screen, SummaryScreen) and app.screen.shown, timeout=30)
        assert app.screen.result.score == 100
        assert json.loads(path.read_text())["lessons"]["1"]["attempts"] == 1  # the autopilot's is not counted
        await pilot.press("x")
        await until(pilot, lambda: not isinstance(app.screen, SummaryScreen))
        assert app.lessons.driver.lesson is not None and app.lessons.driver.lesson.number == 1


async def test_the_demo_starts_through_the_app_and_a_key_of_the_pilot_takes_over() -> None:
    async with sim_app(seed=5, demo=True) as (app, pilot, board):
        bar = app.screen.query_one(LessonBar)
        await until(pilot, lambda: bar.text.startswith("autopilot: F2"))  # after 4 s of welcome
        await until(pilot, lambda: board.log.recording)  # the autopilot pressed F2, as a key does
        app.simulate_key("0")  # the pilot's own key
        await until(pilot, lambda: any("you have control" in e.text for e in app.model.events))
        assert not app.lessons.driver.flying and bar.text == "autopilot stopped: the pilot took over"
        await until(pilot, lambda: app.model.mode == Mode.SAFE)
        await pilot.pause(0.5)
        assert app.model.mode == Mode.SAFE  # nothing else is pressed for the pilot


async def test_without_the_simulator_there_is_no_room_and_the_panel_says_why() -> None:
    app = TermApp(joystick=False)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause(0.1)
        app.render_now()
        view = app.screen.query_one(RoomView)
        assert view.has_class("absent") and view._shown.plain == NO_ROOM
        assert list(app.lessons.commands()) == []
        app.lessons.start_lesson(1)
        assert "lessons need the simulator's truth" in app.model.events[-1].text


@pytest.mark.parametrize("argv, why", [
    (["--serial", "/dev/null", "--lesson", "1"],
     "--lesson, --demo and --lessons need --sim: only the simulator knows where the craft is"),
    (["--sim", "--lesson", "99"], "no lesson 99; there are 1, 2, 3, 4, 5, 6, 7, 8"),
    (["--sim", "--lesson", "1", "--demo"], "--lesson or --demo, not both"),
    (["--sim", "--lessons", "/nonexistent"], "--lessons /nonexistent: not a directory"),
])
def test_the_command_line_says_what_is_wrong_in_one_line(argv: list[str], why: str,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"term: {why}" and "\n" not in err


def test_a_broken_lesson_of_a_teacher_is_named_on_the_command_line(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "09-loop.toml").write_text('number = 9\ntitle = "loop"\ngoal = "g"\n[[step]]\nsay = "x"\n'
                                           'done = "looping"\n')
    assert main(["--sim", "--lessons", str(tmp_path), "--lesson", "9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("term: ") and "09-loop.toml.step[0].done: 'looping': unknown name" in err


def test_the_room_figures_never_read_minus_zero() -> None:
    # Seen on the pad: "h -0.00 m" (the truth a millimetre under the pad's height).
    from dataclasses import fields

    from term.lessons.instructor import Truth
    from term.lessons.room import Room
    from term.ui.widgets.room import figures

    room = Room()
    room.update(Truth(**{f.name: (-0.001 if f.name in ("n", "e", "h") else 0.0) for f in fields(Truth)}))
    assert str(figures(room, False)).startswith("n +0.00 e +0.00 h 0.00 m")


async def test_show_me_stopped_in_flight_leaves_no_lift_behind_once_in_safe() -> None:
    """Issue 22: after lesson 2's "show me" ended in the air, the sticks panel kept the autopilot's lift (48 %),
    z did nothing, and 2 was refused ("throttle is up") until the terminal was quit."""
    async with sim_app(seed=3) as (app, pilot, board):
        room = app.lessons.room
        await until(pilot, lambda: app.model.mode == Mode.SAFE and room is not None and bool(room.truth))
        app.lessons.start_lesson(2, show=True)
        await until(pilot, lambda: app.model.mode == Mode.MANUAL and app.model.stick.lift > 0, timeout=30)
        app.lessons.stop_lesson()
        stopped = app.clock()
        m = app.model
        said = m.events[-1]  # in the air, loudly: who flies now, on which lift, and the way down
        assert said.severity == "warning" and "YOU FLY NOW (MANUAL, on the autopilot's lift)" in said.text
        assert "z lowers the lift" in said.text and "1 is PANIC" in said.text
        # The lift stays while the board flies (the pilot has to bring it down) and goes once it is out of the flight
        # modes; roll, pitch and yaw go at once. Unflown in MANUAL the craft may tip over and PANIC before the next
        # tick on a busy machine (make test-busy): either way the stick has to follow the board's mode.
        await until(pilot, lambda: m.stick[:3] == (0, 0, 0) and (m.stick.lift > 0) == (m.mode in FLIGHT_MODES))
        app.simulate_key("1")  # PANIC: it lands by itself, then SAFE (the board's own event says so)
        done = (int(Mode.PANIC) << 8) | int(Mode.SAFE)  # (or the board's own PANIC, if it tipped over first)
        await until(pilot, lambda: m.event_times.get(EventCode.MODE_CHANGED, -1e9) > stopped
                    and m.event_args.get(EventCode.MODE_CHANGED) == done, timeout=30,
                    what=lambda: f"PANIC -> SAFE; the events: {[e.text for e in list(m.events)[-6:]]}")
        await until(pilot, lambda: app.model.mode == Mode.SAFE and app.model.stick == Joystick(0, 0, 0, 0, 0))
        if board.status().flags & Flag.CRASHED:  # unflown, it hit the wall on a busy machine: acknowledged, as asked
            app.simulate_key("c")
            await until(pilot, lambda: not board.status().flags & Flag.CRASHED)
        app.simulate_key("2")
        await until(pilot, lambda: app.model.mode == Mode.MANUAL,
                    what=lambda: f"MANUAL after 2; the events: {[e.text for e in list(m.events)[-6:]]}")


async def test_the_simulator_says_a_touch_of_the_ceiling_in_the_events() -> None:
    """Issue 35: the room view said "at the ceiling" only while pressed there; a touch is an event too."""
    async with sim_app(seed=3) as (app, pilot, board):
        room = app.lessons.room
        await until(pilot, lambda: room is not None and bool(room.truth))
        world = board.world
        world.on_ground, world.d, world.vd = False, -2.95, -1.5  # thrown up under the 3 m ceiling (SAFE: it falls)
        await until(pilot, lambda: any("touched the ceiling" in e.text for e in app.model.events))
        said = [e for e in app.model.events if "touched the ceiling" in e.text]
        assert len(said) == 1 and said[0].severity == "warning" and " m/s" in said[0].text
