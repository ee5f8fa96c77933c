"""One attempt at a lesson, sans-IO: variables in (term/lessons/observe.py), progress, situations and a score out.

``LessonRun(lesson, now)`` waits for the craft to stand on the floor in SAFE (``WAITING``), then starts
(``RUNNING``): it asks the simulator for the lesson's situation (the instructor's ``reset`` to the pad with a
fresh pack at the lesson's charge, then the lesson's own), and runs the steps in order. ``update(ns, now)`` is
called at a steady rate with the variables (``Observer.namespace``, which takes the step's own from ``step_vars``)
and returns the situations to send now; ``caption`` is what the pilot reads; ``result`` is set when the attempt
ends (``ENDED``).

Per update, in this order: a lesson-wide or step failure (``fail``) ends the attempt; penalties accrue (``while``:
per second while true; ``count``: per increment of a counter during the step (lesson-wide: the attempt)); the step
is done when its duration is over, or when its goal has held ``hold`` seconds without a break (a break starts the
count again); past its ``timeout`` the attempt fails. A step done earns its points less its penalties and its
grades (each value graded between best and worst), never below zero. The score is the points earned over the
lesson's total, less the lesson-wide penalties, as a percentage; an attempt passes if it did not fail and scores
at least the lesson's ``pass_score``. ``Result.lines`` says what went wrong (failure first, then every loss),
``advice`` is the first advice whose ``when`` holds at the end (one without ``when`` only for a pass; a failure
without advice of its own is told to try again), and ``trace`` (10 samples a second of time, height,
north, east and whether in the box) is what the summary plots.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from term.lessons.spec import Grade, Lesson, Penalty, Step

WAITING, RUNNING, ENDED = "waiting", "running", "ended"


def undo_situations(sent: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """What puts back the faults ``sent`` injected, once each: motors free, still air, no drain, the cable whole.
    (A reset needs the craft on the floor in SAFE; these work wherever it is. A radio cut ends by itself.)"""
    out: list[dict[str, Any]] = []
    for s in sent:
        verb = s.get("do")
        undo = ({"do": "motor", "motor": s.get("motor"), "level": -1} if verb == "motor" else
                {"do": "wind"} if verb == "wind" else {"do": "battery", "drain": 0.0} if verb == "battery" else
                {"do": "cable", "cuts": []} if verb == "cable" else None)
        if undo is not None and undo not in out:
            out.append(undo)
    return out
READY_CAPTION = "land and press 0 (SAFE) to start: the lesson starts with the craft on the floor in SAFE"
TRACE_PERIOD = 0.1


@dataclass(frozen=True)
class Loss:
    why: str
    points: float


@dataclass
class Result:
    lesson: int
    score: int
    passed: bool
    failed: str  # why the attempt failed ("" if it did not)
    failed_step: int  # 1-based; 0 if it did not fail
    lines: list[str]
    advice: str
    duration: float
    values: dict[str, float] = field(default_factory=dict)  # the named grades' values
    trace: list[tuple[float, float, float, float, bool]] = field(default_factory=list)  # t, h, n, e, in box
    steps_done: int = 0


class _Acc:
    """One penalty's running total."""

    def __init__(self, p: Penalty, ns: dict[str, Any]) -> None:
        self.p = p
        self.total = 0.0
        self.base = ns.get(p.count) if p.count else None

    def update(self, ns: dict[str, Any], dt: float) -> None:
        p = self.p
        if p.while_ is not None:
            if p.while_.true(ns):
                self.total += p.per_s * dt
        elif p.count is not None:
            now, base = ns.get(p.count), self.base
            if isinstance(now, int | float) and isinstance(base, int | float):
                self.total = (now - base) * p.each
        self.total = min(self.total, p.cap)


_FIELD = re.compile(r"\{(\w+)(?::([^{}]*))?\}")


def fill(text: str, ns: dict[str, Any]) -> str:
    """``{name}`` or ``{name:.2f}`` in a lesson's text: a variable's value now (no other formatting: the file is
    data, never code). Unknown or unset: "?"."""
    def sub(m: re.Match[str]) -> str:
        v = ns.get(m.group(1))
        if v is None:
            return "?"
        try:
            return format(v, m.group(2) or ("g" if isinstance(v, float) else ""))
        except (ValueError, TypeError):
            return str(v)

    return _FIELD.sub(sub, text)


class LessonRun:
    """One attempt (module docstring)."""

    def __init__(self, lesson: Lesson, now: float) -> None:
        self.lesson = lesson
        self.state = WAITING
        self.created = now
        self.started = 0.0
        self.index = 0  # the step running (0-based)
        self.caption = READY_CAPTION
        self.result: Result | None = None
        self.sent: list[dict[str, Any]] = []  # every situation the attempt sent (what it changed)
        self._undo: list[dict[str, Any]] = []
        self.earned = 0.0
        self.losses: list[Loss] = []
        self.values: dict[str, float] = {}
        self.trace: list[tuple[float, float, float, float, bool]] = []
        self._step_start = 0.0
        self._held = 0.0
        self._turn = 0.0
        self._landings0 = 0
        self._landings_in_step = 0
        self._last: float | None = None
        self._heading: float | None = None
        self._step_accs: list[_Acc] = []
        self._lesson_accs: list[_Acc] = []
        self._next_trace = 0.0

    @property
    def step(self) -> Step | None:
        return self.lesson.steps[self.index] if self.state == RUNNING else None

    @property
    def held(self) -> float:
        return self._held

    def step_vars(self, now: float) -> dict[str, float]:
        if self.state != RUNNING:
            return {}
        return {"step_time": now - self._step_start, "held": self._held, "step_turn": self._turn,
                "step_landings": self._landings_in_step}

    # --- the attempt --------------------------------------------------------------------------------------

    def ready(self, ns: dict[str, Any]) -> bool:
        return ns.get("mode") == "SAFE" and ns.get("on_ground") is True

    def start(self, ns: dict[str, Any], now: float) -> list[dict[str, Any]]:
        """The attempt begins: the situations to send (the pad, the pack, the lesson's own and its first step's)."""
        lesson = self.lesson
        self.state = RUNNING
        self.started = now
        self._lesson_accs = [_Acc(p, ns) for p in lesson.penalties]
        out: list[dict[str, Any]] = [{"do": "reset", "soc": lesson.soc}, *lesson.situation]
        return out + self._enter(0, ns, now)

    def _enter(self, index: int, ns: dict[str, Any], now: float) -> list[dict[str, Any]]:
        self.index = index
        step = self.lesson.steps[index]
        self._step_start = now
        self._held = 0.0
        self._turn = 0.0
        self._landings0 = ns.get("landings") or 0
        self._landings_in_step = 0
        self._step_accs = [_Acc(p, ns) for p in step.penalties]
        if step.say is not None:
            self.caption = f"{index + 1}/{len(self.lesson.steps)} {step.say}"
        return list(step.situation)

    def update(self, ns: dict[str, Any], now: float) -> list[dict[str, Any]]:
        """One tick: the situations to send now (module docstring); when the attempt ends, what undoes them."""
        out = self._update(ns, now)
        self.sent += out
        return out + self.take_undo()

    def take_undo(self) -> list[dict[str, Any]]:
        """Once the attempt ended (in ``update`` or by ``stop``): the situations that put back what it changed."""
        undo, self._undo = self._undo, []
        return undo

    def _update(self, ns: dict[str, Any], now: float) -> list[dict[str, Any]]:
        if self.state == ENDED:
            return []
        if self.state == WAITING:
            return self.start(ns, now) if self.ready(ns) else []
        dt = 0.0 if self._last is None else max(0.0, now - self._last)
        self._last = now
        self._track(ns, now, dt)
        step = self.lesson.steps[self.index]
        for f in (*self.lesson.fails, *step.fails):
            if f.when.true(ns):
                self._end(ns, now, fill(f.why, ns))
                return []
        for acc in (*self._lesson_accs, *self._step_accs):
            acc.update(ns, dt)
        step_time = now - self._step_start
        if step.duration is not None:
            finished = step_time >= step.duration
        else:
            assert step.done is not None
            self._held = self._held + dt if step.done.true(ns) else 0.0
            finished = step.done.true(ns) and self._held >= step.hold
        if finished:
            return self._finish_step(ns, now)
        if step.timeout is not None and step_time >= step.timeout:
            self._end(ns, now, fill(step.timeout_why, ns))
        return []

    def _track(self, ns: dict[str, Any], now: float, dt: float) -> None:
        heading = ns.get("heading")
        if isinstance(heading, float) and self._heading is not None:
            d = (heading - self._heading + 180.0) % 360.0 - 180.0
            self._turn += abs(d)
        self._heading = heading if isinstance(heading, float) else None
        landings = ns.get("landings")
        if isinstance(landings, int):
            self._landings_in_step = landings - self._landings0
        if now >= self._next_trace and isinstance(ns.get("h"), float):
            self._next_trace = now + TRACE_PERIOD
            self.trace.append((now - self.started, ns["h"], ns["n"], ns["e"], bool(ns.get("in_box"))))

    def _finish_step(self, ns: dict[str, Any], now: float) -> list[dict[str, Any]]:
        step = self.lesson.steps[self.index]
        lost = 0.0
        for acc in self._step_accs:
            if acc.total > 0.0:
                self.losses.append(Loss(f"step {self.index + 1}: {acc.p.why}", acc.total))
                lost += acc.total
        for g in step.grades:
            lost += self._grade(g, ns)
        self.earned += max(0.0, step.points - lost)
        if self.index + 1 >= len(self.lesson.steps):
            self._end(ns, now, "")
            return []
        return self._enter(self.index + 1, ns, now)

    def _grade(self, g: Grade, ns: dict[str, Any]) -> float:
        v = g.value(ns)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            self.losses.append(Loss(f"step {self.index + 1}: {fill(g.why, {**ns, 'value': None})} (not measured)",
                                    g.points))
            return g.points
        if g.name:
            self.values[g.name] = float(v)
        lost = g.lost(float(v))
        if lost > 0.0:
            self.losses.append(Loss(f"step {self.index + 1}: {fill(g.why, {**ns, 'value': float(v)})}", lost))
        return lost

    def stop(self, ns: dict[str, Any], now: float, why: str = "stopped by the pilot") -> None:
        """End the attempt early (the pilot asked, or the link to the simulator went away)."""
        if self.state != ENDED:
            self._end(ns, now, why)

    def _end(self, ns: dict[str, Any], now: float, failed: str) -> None:
        lesson = self.lesson
        wide = 0.0
        for acc in self._lesson_accs:
            if acc.total > 0.0:
                self.losses.append(Loss(acc.p.why, acc.total))
                wide += acc.total
        total = lesson.total_points
        if total > 0:
            score = max(0, round(100.0 * (self.earned - wide) / total))
        else:
            score = 0 if failed else max(0, round(100.0 - wide))
        passed = not failed and score >= lesson.pass_score
        failed_step = self.index + 1 if failed else 0
        steps_done = self.index if failed else len(lesson.steps)
        lines = ([f"step {failed_step}: {failed}"] if failed else [])
        lines += [f"{loss.why}: -{loss.points:.0f}" for loss in self.losses if round(loss.points) > 0]
        if not lines:
            lines = ["nothing: a clean flight"]
        end_ns = {**ns, **self.values, "failed": bool(failed), "failed_step": failed_step, "score": score}
        for name in lesson.grade_names:
            end_ns.setdefault(name, None)
        # an advice without a condition is the lesson's word on a pass, never on a failure (it praises, moves on)
        advice = next((a.say for a in lesson.advice if (a.when is None and passed) or
                       (a.when is not None and a.when.true(end_ns))), "")
        if not advice:
            advice = (f"Not passed yet ({failed or f'{score}/100, {lesson.pass_score} passes'}): try again (r), or let "
                      "the autopilot show it (s).")
        self.state = ENDED
        self._undo = undo_situations(self.sent)
        self.caption = f"lesson {lesson.number} {'passed' if passed else 'not passed'}: {score}/100"
        self.result = Result(lesson.number, score, passed, failed, failed_step, lines, advice,
                             now - self.started, dict(self.values), self.trace, steps_done)
