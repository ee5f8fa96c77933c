"""The lessons' one engine for every front end: an observer, the attempt running and the autopilot flying, tied.

``LessonDriver`` is sans-IO. A front end (the app; the tests' simulated rig) hands it every station event
(``event``) and every truth sample (``truth``), and calls ``tick(model, now)`` about 50 times a second; the
``Tick`` it gets back says what to do: the situations to send to the simulator, the autopilot's key presses and
stick, a result when an attempt ended, and why the autopilot stopped when it did. The front end carries them out
the way it carries out a pilot's keys, so a lesson flown by the autopilot takes exactly a person's path.

- ``start_lesson(lesson, now, show=False)``: an attempt (``LessonRun``), the autopilot flying the lesson's
  ``[[show]]`` too with ``show``;
- ``start_script(title, goal, script, now)``: the autopilot alone (the demo);
- ``stop(now, why)``: ends both (an attempt ends as failed with ``why``); an attempt that ended, however, puts back
  the faults it injected (motors, wind, battery drain, cable cuts) in the next tick's situations;
- ``pilot_acted(now)``: the pilot pressed a key or moved a stick while the autopilot flies: it stops and hands
  over (the attempt goes on, the pilot's now).

``caption`` is the line the screen shows: the lesson and its step (with the hold's progress), or the autopilot's
caption, saying what happens and why.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from term.core.events import StationEvent
from term.lessons.autopilot import DONE, FAILED, FLYING, Act, Autopilot
from term.lessons.engine import ENDED, RUNNING, LessonRun, Result
from term.lessons.instructor import Truth
from term.lessons.observe import Observer
from term.lessons.spec import Lesson, Maneuver
from term.session.model import Model


@dataclass
class Tick:
    situations: list[dict[str, Any]] = field(default_factory=list)
    acts: list[Act] = field(default_factory=list)
    result: Result | None = None  # an attempt ended in this tick
    autopilot_ended: str | None = None  # the autopilot finished ("done") or stopped (why) in this tick


class LessonDriver:
    """Observer, attempt and autopilot (module docstring)."""

    def __init__(self) -> None:
        self.observer = Observer()
        self.run: LessonRun | None = None
        self.autopilot: Autopilot | None = None
        self.lesson: Lesson | None = None
        self.script_title = ""
        self.intro = ""  # the demo's opening caption, until the autopilot has its own
        self._undo: list[dict[str, Any]] = []  # what puts back an ended attempt's faults, for the next tick

    # --- inputs -------------------------------------------------------------------------------------------

    def event(self, ev: StationEvent, model: Model, now: float) -> None:
        self.observer.event(ev, model, now)

    def truth(self, sample: Truth) -> None:
        self.observer.truth(sample)

    # --- what runs ----------------------------------------------------------------------------------------

    @property
    def active(self) -> bool:
        return (self.run is not None and self.run.state != ENDED) or self.flying

    @property
    def flying(self) -> bool:
        """The autopilot has the sticks."""
        return self.autopilot is not None and self.autopilot.state == FLYING

    def start_lesson(self, lesson: Lesson, now: float, show: bool = False) -> None:
        self.lesson = lesson
        self.observer.box = lesson.box
        self.run = LessonRun(lesson, now)
        self.autopilot = Autopilot(lesson.show, now, f"show me: lesson {lesson.number}") if show and lesson.show \
            else None
        self.intro = ""

    def start_script(self, title: str, goal: str, script: tuple[Maneuver, ...], now: float) -> None:
        self.lesson, self.run = None, None
        self.observer.box = None
        self.observer.reset(now)
        self.script_title, self.intro = title, goal
        self.autopilot = Autopilot(script, now, title)

    def stop(self, model: Model, now: float, why: str = "stopped by the pilot") -> Result | None:
        """End what runs; the attempt's result if one was running."""
        if self.autopilot is not None:
            self.autopilot.stop(why)
        run = self.run
        if run is not None and run.state != ENDED:
            ns = self.observer.namespace(model, now, run.step_vars(now))
            run.stop(ns, now, why)
            self._undo += run.take_undo()  # (sent at the next tick, whatever starts next)
            return run.result
        return None

    def pilot_acted(self, now: float) -> bool:
        """The pilot's own key or stick: the autopilot hands over. True if it was flying."""
        if self.flying:
            assert self.autopilot is not None
            self.autopilot.stop("the pilot took over")
            return True
        return False

    def tick(self, model: Model, now: float) -> Tick:
        run = self.run
        out = Tick(situations=self._undo + (run.take_undo() if run is not None else []))  # put things back
        self._undo = []
        if not self.active:
            return out  # nothing runs: nothing to evaluate (the app ticks at the truth's rate all along)
        if run is not None and run.state != ENDED:
            ns = self.observer.namespace(model, now, run.step_vars(now))
            if run.state != RUNNING and run.ready(ns):
                self.observer.reset(now)  # the attempt starts: its counters from zero
                ns = self.observer.namespace(model, now)
            out.situations += run.update(ns, now)
            if run.state == ENDED:
                out.result = run.result
        ns = self.observer.namespace(model, now, run.step_vars(now) if run is not None else None)
        ap = self.autopilot
        if ap is not None and ap.state == FLYING:
            if run is not None and run.state != RUNNING:
                pass  # wait for the attempt to start (the craft on the floor in SAFE) before flying it
            else:
                out.acts = ap.update(ns, self.observer.sample, now)
                if ap.state != FLYING:
                    out.autopilot_ended = "done" if ap.state == DONE else ap.why
        if out.result is not None and ap is not None and ap.state == FLYING:
            ap.stop("the lesson ended")
            out.autopilot_ended = ap.why
        return out

    # --- what the screen says -----------------------------------------------------------------------------

    @property
    def caption(self) -> str:
        run, ap = self.run, self.autopilot
        parts = []
        if run is not None:
            head = f"lesson {run.lesson.number} · {run.lesson.title}"
            parts.append(f"{head}: {run.caption}" if run.state != ENDED else run.caption)
            step = run.step
            if run.state == RUNNING and step is not None and step.done is not None and step.hold > 0:
                parts.append(f"held {min(run.held, step.hold):.0f}/{step.hold:g} s")
        if ap is not None:
            if ap.state == FLYING:
                parts.append(f"autopilot: {ap.caption or self.intro or ap.title}")
            elif ap.state == FAILED:
                parts.append(f"autopilot stopped: {ap.why}")
            elif run is None:
                parts.append(f"{ap.title}: done")
        return " · ".join(parts)
