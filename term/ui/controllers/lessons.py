"""The lessons, the room view and the demo in the app (term --sim): the app's ``LessonController``.

The sans-IO parts do the work: ``term.lessons.driver.LessonDriver`` (observer, attempt, autopilot),
``term.lessons.room`` (the truth for the room view) and ``term.lessons.progress``; this controller wires them to
the app, through ``LessonHost`` (what only the app can do):

- the instructor channel (``term.lessons.instructor.InstructorClient``, opened by the cli beside the child board): each
  truth sample goes to the room and the driver; a situation the simulator refused is said in the events;
- every station event goes to the driver (``on_station_event``, from the app's station-event hook); a board
  command of the pilot's (a key, the palette, the phone: ``on_action``, from ``perform``) or a stick moved away from
  the autopilot's while it flies hands control back to the pilot;
- a timer at the truth's rate (``tick``) runs the driver and carries out its tick: situations to the
  simulator, the autopilot's presses through ``perform`` (exactly a key's path) and its stick through
  ``set_stick``; the caption line shows what happens; an attempt's end records the progress (not for "show me")
  and opens the summary (again, show me, next lesson, close); once the autopilot stopped, the stick it left goes
  back to neutral (``leftover_stick``: the lift once the craft is out of the flight modes);
- the palette lists every lesson, each lesson's "show me", the demo, and stopping what runs.

Without the simulator (a real board) there is no truth: the room panel says why, and the lessons are not offered.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any, Protocol

from textual.app import SystemCommand
from textual.screen import Screen

from term.core.events import StationEvent, StickSet
from term.core.protocol import FLIGHT_MODES, INSTRUCTOR_TRUTH_HZ, STICK_MAX, STICK_NEUTRAL, Flag, Joystick, Mode, Op
from term.input.keymap import Action, KeyBinding, action_by_name
from term.lessons.autopilot import COMMANDS, Press, Stick
from term.lessons.driver import LessonDriver
from term.lessons.engine import Result
from term.lessons.instructor import InstructorClient, Refused, Truth
from term.lessons.progress import Progress, load
from term.lessons.room import Room
from term.lessons.spec import DEMO, Lesson, LessonError, load_lessons, load_script
from term.session.model import Model
from term.session.station import Station
from term.session.texts import mode_name
from term.ui.widgets.lesson import SummaryScreen


class LessonHost(Protocol):
    """What the lessons need of the app: a key's path, the stick, the screens, a timer, the caption line."""

    def perform(self, action: Action) -> None: ...
    def send(self, op: Op, arg: int = 0) -> int | None: ...
    def set_stick(self, js: Joystick) -> None: ...
    def show_screen(self, name: str) -> None: ...
    def push_screen(self, screen: Screen[Any], callback: Callable[[Any], None]) -> Any: ...
    def show_caption(self, text: str) -> None: ...
    def set_interval(self, interval: float, callback: Callable[[], None]) -> Any: ...


class LessonController:
    """The lessons in the app (module docstring). The app builds it in its ``__init__``, calls ``mount`` in
    ``on_mount``, ``on_station_event`` for each station event and ``on_action`` before it performs an action."""

    def __init__(self, station: Station, clock: Callable[[], float], keymap: Sequence[KeyBinding],
                 host: LessonHost, instructor: InstructorClient | None, lesson: int | None = None,
                 demo: bool = False, lessons_dirs: Sequence[Path] = (), progress: Progress | None = None) -> None:
        self.station = station
        self.clock = clock
        self.keymap = keymap
        self.host = host
        self.instructor = instructor
        self.room: Room | None = Room() if instructor is not None else None
        self.driver = LessonDriver()
        self.by_number: dict[int, Lesson] = {}
        self.lessons_skipped: list[str] = []
        if instructor is not None:
            actions = [b.action.name for b in self.keymap]
            self.by_number, self.lessons_skipped = load_lessons(lessons_dirs, actions)
            instructor.on_truth = self._on_truth
            instructor.on_refused = self._on_refused
            instructor.on_lost = self._on_instructor_lost
        self.progress = progress if progress is not None else (load() if instructor is not None else Progress())
        self._start_lesson = lesson
        self._start_demo = demo
        self._autopilot_acting = False
        self._autopilot_stick = Joystick(0, 0, 0, 0, 0)  # the last stick the autopilot held
        self._touches = 0  # the simulator's ceiling and wall touches said so far
        self._shown_attempt = False  # the attempt running is the autopilot's ("show me")
        self.lesson_results: list[Result] = []

    @property
    def model(self) -> Model:
        return self.station.model

    def mount(self) -> None:
        if self.instructor is None:
            return
        for line in self.lessons_skipped:
            self.station.note("warning", "lesson", f"lesson file skipped: {line}")
        if self.progress.problem:
            self.station.note("warning", "lesson", self.progress.problem)
        self.host.set_interval(1.0 / INSTRUCTOR_TRUTH_HZ, self.tick)
        if self._start_demo:
            self.start_demo()
        elif self._start_lesson is not None:
            self.start_lesson(self._start_lesson)

    # --- the instructor channel ---------------------------------------------------------------------------

    def _on_truth(self, truth: Truth) -> None:
        if self.room is not None:
            self.room.update(truth)
        if truth.touches != self._touches:  # the simulator says what the board can only guess from its accelerometer
            if truth.touches > self._touches:  # (fewer: a simulator started anew counts from zero)
                self.station.note("warning", "sim", f"the craft touched the {truth.touched} at "
                                  f"{truth.touch_speed:.1f} m/s (the simulator's room)")
            self._touches = truth.touches
        self.driver.truth(truth)

    def _on_refused(self, refused: Refused) -> None:
        self.station.note("warning", "sim", f"the simulator could not set up {refused.verb}: {refused.why}")

    def _on_instructor_lost(self, why: str) -> None:
        self.station.note("error", "sim", f"{why}: no room view, no lessons")
        self.driver.stop(self.model, self.clock(), why)

    # --- what runs ----------------------------------------------------------------------------------------

    def start_lesson(self, number: int, show: bool = False) -> None:
        lesson = self.by_number.get(number)
        if lesson is None or self.instructor is None:
            self.station.note("error", "lesson", f"no lesson {number}" if self.instructor is not None
                              else "lessons need the simulator's truth: term --sim")
            return
        now = self.clock()
        self.driver.stop(self.model, now, "another lesson started")
        if self.room is not None:
            self.room.set_box(lesson.box)
        self.driver.start_lesson(lesson, now, show=show)
        self._shown_attempt = show
        self.host.show_screen("flight")
        who = "the autopilot shows " if show else ""
        self.station.note("info", "lesson", f"{who}lesson {lesson.number}: {lesson.title}. {lesson.goal}")
        self.tick()

    def start_demo(self) -> None:
        if self.instructor is None:
            self.station.note("error", "demo", "the demo needs the simulator: term --sim --demo")
            return
        try:
            title, goal, script = load_script(DEMO, [b.action.name for b in self.keymap])
        except LessonError as exc:
            self.station.note("error", "demo", str(exc))
            return
        now = self.clock()
        self.driver.stop(self.model, now, "the demo started")
        if self.room is not None:
            self.room.set_box(None)
        self.driver.start_script(title, goal, script, now)
        self.host.show_screen("flight")
        self.station.note("info", "demo", f"{goal}; any key of yours takes control back")
        self.tick()

    def stop_lesson(self) -> None:
        was_flying = self.driver.flying
        result = self.driver.stop(self.model, self.clock())
        if result is None and not was_flying:
            self.station.note("info", "lesson", "nothing to stop")
        if was_flying:
            self._handed_over("autopilot stopped")

    def _handed_over(self, what: str, loud: bool = True) -> None:
        """The autopilot let go: in the air (``loud``) the pilot flies now, on the lift it left (which stays until
        the board is out of the flight modes: ``leftover_stick``), and is told so loudly, with the way down."""
        self._show_caption()  # (with the event, not a tick later)
        mode = self.model.mode
        if loud and mode in FLIGHT_MODES:
            self.station.note("warning", "lesson", f"{what}: YOU FLY NOW ({mode_name(mode)}, on the autopilot's "
                              "lift): z lowers the lift to land, 1 is PANIC (it lands by itself)")
        else:
            self.station.note("info", "lesson", f"{what}: you have control")

    # --- events and the tick ------------------------------------------------------------------------------

    def on_station_event(self, ev: StationEvent) -> None:
        self.driver.event(ev, self.model, self.clock())
        if type(ev) is StickSet and not self._autopilot_acting and self._moved(ev.stick):
            self._take_over(loud=False)  # (the pilot's own stick has the lift now)

    def on_action(self, action: Action) -> None:
        """A key map action is being performed: the pilot's own (a key, the palette, the phone) if the autopilot
        is not the one pressing; a board command of the pilot's takes control (looking at a screen does not)."""
        if action.op is not None and not self._autopilot_acting:
            # (PANIC or SAFE is the way down already: nothing to tell but who flies)
            self._take_over(loud=not (action.op == Op.MODE and action.arg in (Mode.PANIC, Mode.SAFE)))

    def _take_over(self, loud: bool) -> None:
        if self.driver.pilot_acted(self.clock()):
            self._handed_over("autopilot off", loud=loud)

    def _moved(self, stick: Joystick) -> bool:
        """A stick of the pilot's, not the autopilot's: an axis away from the autopilot's by more than the neutral
        band (a joystick at rest, its first report, a little noise: not a pilot taking over)."""
        mine = self._autopilot_stick
        return any(abs(a - b) > STICK_NEUTRAL for a, b in zip(stick[:4], mine[:4], strict=True))

    def tick(self) -> None:
        now = self.clock()
        tick = self.driver.tick(self.model, now)
        if self.instructor is not None:
            for cmd in tick.situations:
                why = self.instructor.send(cmd)
                if why is not None:
                    self.station.note("error", "sim", why)
        self._autopilot_acting = True
        try:
            for act in tick.acts:
                if type(act) is Press:
                    self._autopilot_press(act.action)
                elif type(act) is Stick:
                    self._autopilot_stick = act.js
                    if act.js != self.model.stick:
                        self.host.set_stick(act.js)
        finally:
            self._autopilot_acting = False
        if tick.autopilot_ended is not None:
            text = "autopilot: done" if tick.autopilot_ended == "done" else f"autopilot off: {tick.autopilot_ended}"
            self.station.note("info" if tick.autopilot_ended == "done" else "warning", "lesson", text)
        if not self.driver.flying:
            left = leftover_stick(self.model.stick, self._autopilot_stick, self.model.mode)
            if left is not None:
                self._autopilot_stick = left
                self.host.set_stick(left)
        if tick.result is not None:
            self._attempt_ended(tick.result)
        self._show_caption()

    def _autopilot_press(self, name: str) -> None:
        if name in COMMANDS:
            self.host.send(*COMMANDS[name])
            return
        action = action_by_name(self.keymap, name)
        if action is not None:
            self.host.perform(action)

    def _show_caption(self) -> None:
        self.host.show_caption(self.driver.caption)

    def _attempt_ended(self, result: Result) -> None:
        lesson = self.by_number.get(result.lesson)
        if lesson is None:
            return
        self.lesson_results.append(result)
        shown = self._shown_attempt
        if shown:
            entry = self.progress.get(lesson.number)
        else:
            entry = self.progress.record(lesson.number, result.score, result.passed, time.time())
            why = self.progress.save()
            if why is not None:
                self.station.note("warning", "lesson", why)
        verdict = "passed" if result.passed else "not passed"
        self.station.note("info" if result.passed else "warning", "lesson",
                          f"lesson {lesson.number} {verdict}: {result.score}/100"
                          + (" (the autopilot's)" if shown else f", best {entry.best}") + f". {result.advice}")
        later = [n for n in self.by_number if n > lesson.number]
        screen = SummaryScreen(result, f"lesson {lesson.number} · {lesson.title}", entry, lesson.box, shown=shown,
                               has_next=bool(later))

        def chosen(what: str | None) -> None:
            self._tidy_after()
            if what == "again":
                self.start_lesson(lesson.number)
            elif what == "show":
                self.start_lesson(lesson.number, show=True)
            elif what == "next" and later:
                self.start_lesson(later[0])

        self.host.push_screen(screen, chosen)

    def _tidy_after(self) -> None:
        """The summary closed, in SAFE: the board as a new flight wants it, each step said (issue 34: the lift trim
        stayed at 1 % and a crash still needed c). The crash was the lesson's, summed up already; the simulator
        puts the craft back on its feet."""
        model = self.model
        if model.mode != Mode.SAFE:
            return
        if model.flags & Flag.CRASHED:
            self.host.send(Op.ACK_CRASH)
            self.station.note("info", "lesson", "lesson over: its crash acknowledged (c) for the next flight")
        trim = model.status.trim_lift if model.status is not None else 0
        if trim > 0:
            self.host.send(Op.TRIM_LIFT, -STICK_MAX)
            self.station.note("info", "lesson", f"lesson over: lift trim {100 * trim / STICK_MAX:.1f} % back to 0")

    # --- the palette --------------------------------------------------------------------------------------

    def commands(self) -> Iterable[SystemCommand]:
        if self.instructor is None:
            return
        yield SystemCommand("Demo: the autopilot's tour", "calibrate, FULL, HEIGHT, a handover, PANIC, landing, "
                            "log download, with captions (any key of yours takes over)", self.start_demo)
        for n, lesson in self.by_number.items():
            p = self.progress.get(n)
            mark = f"best {p.best}/100{' ✓' if p.passed else ''}" if p.attempts else "not flown yet"
            yield SystemCommand(f"Lesson {n}: {lesson.title}", f"{mark} · {lesson.goal}", _call(self.start_lesson, n))
            if lesson.show:
                yield SystemCommand(f"Lesson {n}: show me", f"the autopilot flies lesson {n}: {lesson.title}",
                                    _call(self.start_lesson, n, True))
        yield SystemCommand("Lesson: stop", "end the lesson, the show or the demo that runs", self.stop_lesson)


def leftover_stick(stick: Joystick, autopilot: Joystick, mode: int | None) -> Joystick | None:
    """The stick to put back once the autopilot stopped, or None: while the stick is still the one it left, its
    roll, pitch and yaw go at once; its lift stays while the craft flies (a keyboard pilot who took over would
    drop it) and goes once the board is out of the flight modes (landed, PANIC, SAFE)."""
    if stick != autopilot or stick[:4] == (0, 0, 0, 0):
        return None  # the pilot's own stick (a joystick moved), or nothing left
    keep = stick.lift if mode in FLIGHT_MODES else 0
    put = stick._replace(roll=0, pitch=0, yaw=0, lift=keep)
    return None if put == stick else put


def _call(fn: Callable[..., None], *args: Any) -> Callable[[], None]:
    return lambda: fn(*args)
