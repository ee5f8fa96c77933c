"""Lesson files: TOML a teacher writes, read and checked here; nothing in them is code.

A lesson is a short scripted situation with steps, each with a goal the simulator's truth is checked against, a
score out of 100 and one line of advice at the end. The built-in lessons are ``term/lessons/*.toml``; a teacher
adds one by dropping a file into the lessons directory of the config (``term --config-path`` shows where) or
into ``--lessons DIR``: the same number as a built-in one replaces it. The format, field by field, is in
docs/lessons.md; every expression is a one-liner over the variables of term/lessons/observe.py (``NAMES``),
checked when the file is read (term/lessons/expr.py), so a lesson that loads is one that can run.

``load_lesson(path)`` returns a ``Lesson`` or raises ``LessonError`` naming the file and the field;
``load_lessons(dirs)`` reads every ``*.toml`` (but ``demo.toml``) of the built-in directory and then ``dirs``, and
returns the lessons by number and one line per file it skipped; ``load_script(path)`` reads an autopilot script
alone (the demo). Scores: each step has ``points``; a step done earns them less its penalties and grades; a failed
attempt earns nothing for the step it failed in and the steps after; lesson-wide penalties come off the total.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from term.core.protocol import STICK_MAX, Op
from term.core.protocol.numbers import finite, shown_text
from term.core.userfile import UserFileError, read_user_toml
from term.lessons.expr import Expr, ExprError
from term.lessons.instructor import check_situation
from term.lessons.observe import NAMES, Box

BUILTIN = Path(__file__).resolve().parent
DEMO = BUILTIN / "demo.toml"
MAX_S = 3600.0
END_NAMES = ("failed", "failed_step", "score")  # the advice's variables beside the lesson's and the grades' names
# What a script may press beside the key map's actions: the palette's board commands that have no key.
COMMANDS: dict[str, tuple[Op, int]] = {"handback": (Op.WIRELESS, 0)}  # "Link: hand control back to the cable"
TEXT_MAX = 1000  # characters of a caption, a reason or an advice
_SAFE_FORMAT = re.compile(r"[<>^]?[+ -]?[0-9]{0,2}(\.[0-9]{1,2})?[fgde%]?", re.ASCII)  # {h:.2f}: never {h:999999999}
VERBS = ("press", "wait", "hover", "land", "sticks", "pause", "say")  # the autopilot's maneuvers


class LessonError(ValueError):
    """A lesson file that cannot be used; the message names the file and the field."""


@dataclass(frozen=True)
class Fail:
    when: Expr
    why: str


@dataclass(frozen=True)
class Penalty:
    """Points lost ``per_s`` while ``while_`` holds, or ``each`` time the counter ``count`` goes up; at most
    ``cap``."""

    why: str
    while_: Expr | None = None
    per_s: float = 0.0
    count: str | None = None
    each: float = 0.0
    cap: float = math.inf


@dataclass(frozen=True)
class Grade:
    """At the end of its step, ``value`` is graded: at ``best`` or better nothing is lost, at ``worst`` or worse
    ``points``, linearly between (``best`` may be above ``worst``: higher is better). ``name`` makes the value a
    variable of the advice."""

    why: str
    value: Expr
    best: float
    worst: float
    points: float
    name: str | None = None

    def lost(self, v: float) -> float:
        if self.best == self.worst:
            return 0.0 if (v <= self.best) else self.points
        f = (v - self.best) / (self.worst - self.best)
        return self.points * max(0.0, min(1.0, f))


@dataclass(frozen=True)
class Step:
    say: str | None  # the caption; None keeps the one before (a step the pilot must not see coming)
    done: Expr | None = None
    hold: float = 0.0
    duration: float | None = None
    timeout: float | None = None
    timeout_why: str = "ran out of time"
    points: float = 0.0
    situation: tuple[dict[str, Any], ...] = ()
    fails: tuple[Fail, ...] = ()
    penalties: tuple[Penalty, ...] = ()
    grades: tuple[Grade, ...] = ()


@dataclass(frozen=True)
class Advice:
    say: str
    when: Expr | None = None


@dataclass(frozen=True)
class Maneuver:
    """One line of an autopilot script: ``verb`` with its ``arg``, a caption, and how it ends."""

    verb: str
    arg: Any
    say: str | None = None
    until: Expr | None = None
    seconds: float | None = None  # "for"
    timeout: float = 60.0
    options: dict[str, float] = field(default_factory=dict)  # hover: speed, yaw_rate, heading; land: rate


@dataclass(frozen=True)
class Lesson:
    number: int
    title: str
    goal: str
    steps: tuple[Step, ...]
    pass_score: int = 60
    soc: float = 0.9
    situation: tuple[dict[str, Any], ...] = ()
    box: Box | None = None
    penalties: tuple[Penalty, ...] = ()
    fails: tuple[Fail, ...] = ()
    advice: tuple[Advice, ...] = ()
    show: tuple[Maneuver, ...] = ()
    source: str = ""

    @property
    def total_points(self) -> float:
        return sum(s.points for s in self.steps)

    @property
    def grade_names(self) -> tuple[str, ...]:
        return tuple(g.name for s in self.steps for g in s.grades if g.name)


# --- reading ----------------------------------------------------------------------------------------------------


class _Reader:
    """Typed access to one TOML table; unknown keys are errors (a typo must not pass as a default)."""

    def __init__(self, table: Any, where: str, names: frozenset[str] = frozenset(NAMES)) -> None:
        if not isinstance(table, dict):
            raise LessonError(f"{where}: expected a table")
        self.t = table
        self.where = where
        self.names = names
        self.used: set[str] = set()

    def err(self, key: str, msg: str) -> LessonError:
        return LessonError(f"{self.where}.{key}: {msg}")

    def get(self, key: str, default: Any = None) -> Any:
        self.used.add(key)
        return self.t.get(key, default)

    def text(self, key: str, default: str | None = None) -> str | None:
        v = self.get(key, default)
        if v is not None and (not isinstance(v, str) or not v.strip()):
            raise self.err(key, "expected non-empty text")
        if v is not None and len(v) > TEXT_MAX:
            raise self.err(key, f"longer than {TEXT_MAX} characters")
        for m in re.finditer(r"\{\w*:([^{}]*)\}", v or ""):
            if not _SAFE_FORMAT.fullmatch(m.group(1)):
                raise self.err(key, f"{{…:{m.group(1)[:20]}}}: a format is like .2f, 5.1f or g (width and "
                                    "precision at most 2 digits)")
        return v

    def number(self, key: str, default: float | None = None, lo: float = -math.inf, hi: float = math.inf) -> Any:
        v = self.get(key, default)
        if v is None:
            return None
        if not finite(v):
            raise self.err(key, f"expected a number, got {shown_text(v)}")
        if not lo <= v <= hi:  # exact for an int of any size
            raise self.err(key, f"must be between {lo:g} and {hi:g}, got {shown_text(v)}")
        return float(v)

    def why(self, key: str, extra: tuple[str, ...] = (), default: str | None = None) -> str | None:
        """A text that may show variables: ``{h:.2f}`` (checked against the lesson's names)."""
        v = self.text(key, default)
        if v is not None:
            for m in re.finditer(r"\{(\w*)(?::[^{}]*)?\}", v):
                if m.group(1) not in self.names and m.group(1) not in extra:
                    raise self.err(key, f"{{{m.group(1)}}}: not a variable of the lesson")
        return v

    def expr(self, key: str, names: frozenset[str] | None = None) -> Expr | None:
        v = self.get(key)
        if v is None:
            return None
        try:
            return Expr(v, names or self.names)
        except ExprError as exc:
            raise self.err(key, str(exc)) from None

    def tables(self, key: str) -> list[Any]:
        v = self.get(key, [])
        if not isinstance(v, list):
            raise self.err(key, "expected a list of tables ([[" + key + "]])")
        return v

    def done(self) -> None:
        extra = sorted(set(self.t) - self.used)
        if extra:
            raise LessonError(f"{self.where}: unknown field {', '.join(extra)}")


def _situations(r: _Reader, key: str) -> tuple[dict[str, Any], ...]:
    out = []
    for i, cmd in enumerate(r.tables(key)):
        if not isinstance(cmd, dict):
            raise r.err(f"{key}[{i}]", "expected a table like {do = \"wind\", n = -1.5}")
        why = check_situation(cmd)
        if why is not None:
            raise r.err(f"{key}[{i}]", why)
        out.append(dict(cmd))
    return tuple(out)


def _fails(r: _Reader, key: str) -> tuple[Fail, ...]:
    out = []
    for i, t in enumerate(r.tables(key)):
        f = _Reader(t, f"{r.where}.{key}[{i}]", r.names)
        out.append(Fail(f.expr("when") or _missing(f, "when"), f.why("why") or _missing(f, "why")))
        f.done()
    return tuple(out)


def _penalties(r: _Reader, key: str) -> tuple[Penalty, ...]:
    out = []
    for i, t in enumerate(r.tables(key)):
        p = _Reader(t, f"{r.where}.{key}[{i}]", r.names)
        why = p.text("why") or _missing(p, "why")
        while_, per_s = p.expr("while"), p.number("per_s", 0.0, 0.0, 1000.0)
        count, each = p.text("count"), p.number("each", 0.0, 0.0, 1000.0)
        cap = p.number("max", None, 0.0)
        if (while_ is None) == (count is None):
            raise p.err("while", "a penalty has either while (with per_s) or count (with each)")
        if count is not None and count not in r.names:
            raise p.err("count", f"unknown counter {count!r}")
        out.append(Penalty(why, while_, per_s, count, each, math.inf if cap is None else cap))
        p.done()
    return tuple(out)


def _grades(r: _Reader, key: str) -> tuple[Grade, ...]:
    out = []
    for i, t in enumerate(r.tables(key)):
        g = _Reader(t, f"{r.where}.{key}[{i}]", r.names)
        name = g.text("name")
        if name is not None and (not name.isidentifier() or name in NAMES):
            raise g.err("name", f"{name!r} must be a new identifier (not a variable of the lesson)")
        out.append(Grade(g.why("why", ("value",)) or _missing(g, "why"), g.expr("value") or _missing(g, "value"),
                         g.number("best", 0.0), g.number("worst", 1.0), g.number("points", 0.0, 0.0, 1000.0), name))
        g.done()
    return tuple(out)


def _missing(r: _Reader, key: str) -> Any:
    raise r.err(key, "missing")


def _step(t: Any, where: str) -> Step:
    r = _Reader(t, where)
    done, duration = r.expr("done"), r.number("duration", None, 0.0, MAX_S)
    if (done is None) == (duration is None):
        raise r.err("done", "a step has a goal (done, optionally with hold) or a duration")
    step = Step(
        say=r.text("say"), done=done, hold=r.number("hold", 0.0, 0.0, MAX_S), duration=duration,
        timeout=r.number("timeout", None, 0.1, MAX_S), timeout_why=r.why("timeout_why", (), "ran out of time") or "",
        points=r.number("points", 0.0, 0.0, 1000.0), situation=_situations(r, "situation"), fails=_fails(r, "fail"),
        penalties=_penalties(r, "penalty"), grades=_grades(r, "grade"))
    r.done()
    return step


def _box(t: Any, where: str) -> Box:
    r = _Reader(t, where)
    b = Box(north=r.number("north", 0.0, -50, 50), east=r.number("east", 0.0, -50, 50),
            height=r.number("height", 1.0, 0.0, 100.0), size=r.number("size", 1.0, 0.05, 50.0),
            tall=r.number("tall", 1.0, 0.05, 50.0))
    r.done()
    return b


def maneuvers(tables: list[Any], where: str, actions: Iterable[str] | None = None) -> tuple[Maneuver, ...]:
    """An autopilot script from its tables (``[[show]]``); ``actions``: the key map's action names."""
    known = frozenset(actions) | frozenset(COMMANDS) if actions is not None else None
    out = []
    for i, t in enumerate(tables):
        r = _Reader(t, f"{where}[{i}]")
        verbs = [v for v in VERBS if v in t and not (v == "say" and any(o in t for o in VERBS if o != "say"))]
        if len(verbs) != 1:
            raise LessonError(f"{where}[{i}]: one of {', '.join(VERBS)} (with say as its caption)")
        verb = verbs[0]
        say = r.text("say")
        arg: Any = None
        if verb == "press":
            arg = r.text("press")
            if known is not None and arg not in known:
                raise r.err("press", f"no key map action {arg!r}")
        elif verb == "wait":
            arg = r.expr("wait")
        elif verb == "hover":
            arg = r.get("hover")
            if (not isinstance(arg, list) or len(arg) != 3
                    or not all(finite(x) and abs(x) <= 1000 for x in arg) or not 0 <= arg[2] <= 100):
                raise r.err("hover", "expected [north, east, height] in m (height 0 to 100)")
            arg = tuple(float(x) for x in arg)
        elif verb == "land":
            arg = r.number("land", 0.3, 0.05, 2.0)
        elif verb == "sticks":
            s = _Reader(r.get("sticks"), f"{where}[{i}].sticks")
            arg = {k: int(s.number(k, 0, -STICK_MAX if k != "lift" else 0, STICK_MAX))
                   for k in ("roll", "pitch", "yaw", "lift")}
            s.done()
        elif verb == "pause":
            arg = r.number("pause", None, 0.0, MAX_S)
        options = {k: r.number(k, None) for k in ("speed", "yaw_rate", "heading", "rate") if k in t}
        m = Maneuver(verb, arg, say, r.expr("until"), r.number("for", None, 0.0, MAX_S),
                     r.number("timeout", 60.0, 0.1, MAX_S), options)
        r.done()
        out.append(m)
    return tuple(out)


MAX_FILES = 200  # lesson files read from one folder
LESSON_MAX_BYTES = 200_000  # the built-in lessons are 2 to 6 kB


def _parse(path: Path) -> dict[str, Any]:
    try:
        return read_user_toml(path, LESSON_MAX_BYTES, "lesson file")
    except UserFileError as exc:
        raise LessonError(str(exc)) from None


def load_lesson(path: Path, actions: Iterable[str] | None = None) -> Lesson:
    """One lesson file (module docstring); ``actions``: the key map's names, to check the autopilot's presses."""
    where = path.name
    r = _Reader(_parse(path), where)
    number = r.number("number", None, 1, 999)
    if number is None or number != int(number):
        raise r.err("number", "missing, or not a whole number 1 to 999")
    steps = tuple(_step(t, f"{where}.step[{i}]") for i, t in enumerate(r.tables("step")))
    if not steps:
        raise r.err("step", "a lesson has at least one [[step]]")
    names = frozenset(NAMES) | {g.name for s in steps for g in s.grades if g.name} | set(END_NAMES)
    box = r.get("box")
    lesson = Lesson(
        number=int(number), title=r.text("title") or _missing(r, "title"), goal=r.text("goal") or _missing(r, "goal"),
        steps=steps, pass_score=int(r.number("pass_score", 60, 0, 100)), soc=r.number("soc", 0.9, 0.05, 1.0),
        situation=_situations(r, "situation"), box=_box(box, f"{where}.box") if box is not None else None,
        penalties=_penalties(r, "penalty"), fails=_fails(r, "fail"),
        advice=_advice(r, names), show=maneuvers(r.tables("show"), f"{where}.show", actions), source=str(path))
    r.done()
    if not lesson.advice or lesson.advice[-1].when is not None:
        raise LessonError(f"{where}.advice: the last advice has no 'when' (it is the one said otherwise)")
    return lesson


def _advice(r: _Reader, names: frozenset[str]) -> tuple[Advice, ...]:
    out = []
    for i, t in enumerate(r.tables("advice")):
        a = _Reader(t, f"{r.where}.advice[{i}]", names)
        out.append(Advice(a.text("say") or _missing(a, "say"), a.expr("when")))
        a.done()
    return tuple(out)


def load_script(path: Path, actions: Iterable[str] | None = None) -> tuple[str, str, tuple[Maneuver, ...]]:
    """An autopilot script file (the demo): its title, its opening caption and its maneuvers."""
    r = _Reader(_parse(path), path.name)
    title, goal = r.text("title") or _missing(r, "title"), r.text("goal") or _missing(r, "goal")
    show = maneuvers(r.tables("show"), f"{path.name}.show", actions)
    r.done()
    if not show:
        raise r.err("show", "an autopilot script has at least one [[show]]")
    return title, goal, show


def load_lessons(dirs: Iterable[Path] = (), actions: Iterable[str] | None = None
                 ) -> tuple[dict[int, Lesson], list[str]]:
    """Every lesson of the built-in directory, then of ``dirs`` (a later one of the same number wins); the
    lessons by number and one line per file skipped."""
    acts = tuple(actions) if actions is not None else None
    builtin, skipped_builtin = _builtin_lessons(acts)
    lessons: dict[int, Lesson] = dict(builtin)
    skipped: list[str] = list(skipped_builtin)
    for d in dirs:
        if not d.is_dir():
            continue
        paths = sorted(p for p in d.glob("*.toml") if p.name != DEMO.name)
        if len(paths) > MAX_FILES:  # a folder of thousands is not a teacher's: read the first, say so
            skipped_files = len(paths) - MAX_FILES
            paths = paths[:MAX_FILES]
        else:
            skipped_files = 0
        _load_into(lessons, skipped, paths, acts)
        if skipped_files:
            skipped.append(f"{d}: more than {MAX_FILES} lesson files; the last {skipped_files} were not read")
    return dict(sorted(lessons.items())), skipped


def _load_into(lessons: dict[int, Lesson], skipped: list[str], paths: Iterable[Path],
               acts: tuple[str, ...] | None) -> None:
    for path in paths:
        try:
            lesson = load_lesson(path, acts)
        except LessonError as exc:
            skipped.append(str(exc))
            continue
        lessons[lesson.number] = lesson


@functools.lru_cache(maxsize=8)
def _builtin_lessons(acts: tuple[str, ...] | None) -> tuple[tuple[tuple[int, Lesson], ...], tuple[str, ...]]:
    """The built-in lessons, read once per process (they ship with the package; a Lesson is frozen): each reload
    of a teacher's folder reads only that folder."""
    lessons: dict[int, Lesson] = {}
    skipped: list[str] = []
    _load_into(lessons, skipped, sorted(p for p in BUILTIN.glob("*.toml") if p.name != DEMO.name), acts)
    return tuple(lessons.items()), tuple(skipped)
