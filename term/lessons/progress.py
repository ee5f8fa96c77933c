"""The pilot's progress through the lessons: one small JSON file in the user data directory.

``lessons.json`` (next to the session recordings, platformdirs' user data directory, ``quadrupel``) keeps, per
lesson number: attempts, best score, last score, whether it was ever passed, and when it was last flown. It is
read at start and written after each attempt (to a temporary file, then renamed: a crash never leaves half a
file). A file that cannot be read (damaged, another program's) is set aside as ``lessons.json.bad`` and the
progress starts afresh; that is said once, never an exception. Sans-IO apart from ``load``/``save``: ``record``
takes the time as an argument.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

from term.core.userfile import UserFileError, read_user_file

FILE_NAME = "lessons.json"
FORMAT = 1
PROGRESS_MAX_BYTES = 1_000_000  # a score per lesson: a few kB


@dataclass
class LessonProgress:
    attempts: int = 0
    best: int = 0
    last: int = 0
    passed: bool = False
    when: float = 0.0  # UNIX time of the last attempt


@dataclass
class Progress:
    path: Path | None = None
    lessons: dict[int, LessonProgress] = field(default_factory=dict)
    problem: str = ""  # why the file could not be used (said once by the front end)

    def get(self, number: int) -> LessonProgress:
        return self.lessons.get(number, LessonProgress())

    def record(self, number: int, score: int, passed: bool, when: float) -> LessonProgress:
        """One attempt's outcome; returns the lesson's progress after it (``best`` includes it)."""
        p = self.lessons.setdefault(number, LessonProgress())
        p.attempts += 1
        p.last = score
        p.best = max(p.best, score)
        p.passed = p.passed or passed
        p.when = when
        return p

    def next_lesson(self, numbers: list[int]) -> int | None:
        """The first lesson not yet passed (None: every one is)."""
        return next((n for n in sorted(numbers) if not self.get(n).passed), None)

    def save(self) -> str | None:
        """Write the file; None, or why it could not be written (one line)."""
        if self.path is None:
            return None
        data = {"format": FORMAT, "lessons": {str(n): asdict(p) for n, p in sorted(self.lessons.items())}}
        tmp = ""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".lessons-", suffix=".tmp", dir=self.path.parent)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(data, f, indent=1)
            os.replace(tmp, self.path)
        except OSError as exc:
            if tmp:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
            return f"cannot save lesson progress to {self.path}: {exc.strerror or exc}"
        return None


def default_path() -> Path:
    from platformdirs import user_data_path

    return user_data_path("quadrupel", appauthor=False) / FILE_NAME


def _entry(v: object) -> LessonProgress | None:
    if not isinstance(v, dict):
        return None
    p = LessonProgress()
    for name, kind in (("attempts", int), ("best", int), ("last", int), ("passed", bool), ("when", float)):
        x = v.get(name, getattr(p, name))
        if kind is float and isinstance(x, int) and not isinstance(x, bool):
            x = float(x)
        if not isinstance(x, kind) or (kind is int and isinstance(x, bool)):
            return None
        if kind is float and not math.isfinite(x):
            return None
        setattr(p, name, x)
    if p.attempts < 0 or not (0 <= p.best <= 100 and 0 <= p.last <= 100):
        return None
    return p


def load(path: Path | None = None) -> Progress:
    """The progress file at ``path`` (default: the user data directory); a fresh one if there is none."""
    path = path or default_path()
    prog = Progress(path)
    if not os.path.lexists(path):
        return prog
    try:
        raw = read_user_file(path, PROGRESS_MAX_BYTES, "lesson progress")
    except UserFileError as exc:
        prog.problem = str(exc)
        prog.path = None  # do not overwrite what we could not read
        return prog
    try:
        data = json.loads(raw)
        if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("lessons"), dict):
            raise ValueError("not a lesson progress file")
        for key, v in data["lessons"].items():
            entry = _entry(v)
            if not key.isdigit() or entry is None:
                raise ValueError(f"lesson {key!r}: not a progress entry")
            prog.lessons[int(key)] = entry
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:  # 3000 nested [ is a bad file, not a crash
        if isinstance(exc, RecursionError):
            exc = ValueError("nests too deeply")
        bad = path.with_name(path.name + ".bad")
        with contextlib.suppress(OSError):
            os.replace(path, bad)
        prog.lessons = {}
        prog.problem = f"lesson progress {path} unreadable ({exc}); kept as {bad.name}, starting afresh"
    return prog
