"""The events list's rules: a line repeated within ``MERGE_S`` among the last ``MERGE_BACK`` is merged into one with
a count (never over a board line written after it: effects stay after their causes), a parameter's changes are one
line, and deadline misses are one line kept up to date. The model (term/session/model.py) holds the list
(``Model.events``); these functions write it."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class LogEntry:
    t: float  # seconds since the terminal started
    severity: str  # "info", "warning", "error"
    source: str  # "board", "nak", "link", "term", "joystick"
    text: str
    count: int = 1  # the same line this many times (merged: ``Model.note``)
    seq: int = 0  # the order lines were written in (a merged repeat is written again)


MERGE_S = 60.0  # a line the same as one of the last MERGE_BACK lines within this is merged into it, with a count
MERGE_BACK = 4
REFUSAL_PAIR_S = 2.0  # the board's Ack NAK and its REFUSED event for one request: said once
_BOARD_TIME = re.compile(r"^\[[0-9.]+\] ")
_PARAM_LINE = re.compile(r"^param (\S+): ")


def merge_key(text: str) -> str:
    """What makes two lines the same: their text without the board's time stamp; a parameter's changes are one
    line (its latest value, with the count)."""
    text = _BOARD_TIME.sub("", text)
    m = _PARAM_LINE.match(text)
    return f"param {m.group(1)}" if m else text


def note(m: Any, now: float, severity: str, source: str, text: str) -> None:
    """A line in the events list. The same line (``merge_key``) as one of the last few, within ``MERGE_S``,
    is merged into it: moved to the end with its count raised, not written again; but never over a board line
    written after it (a mode change, a link event: what the board did after the first stays listed after its
    cause, issue 34: a repeated "request PANIC" jumped over "mode FULL → PANIC")."""
    t = now - m.start
    events = m.events
    key = merge_key(text)
    for i in range(len(events) - 1, max(-1, len(events) - 1 - MERGE_BACK), -1):
        e = events[i]
        if e.source == source and e.severity == severity and t - e.t <= MERGE_S and merge_key(e.text) == key:
            del events[i]
            write(m, LogEntry(t, severity, source, text, e.count + 1))
            return
        if e.source == "board":
            break  # (a repeat of a board line itself may merge: it is the same effect again)
    write(m, LogEntry(t, severity, source, text))


def write(m: Any, entry: LogEntry) -> None:
    m.notes_written += 1
    m.events.append(LogEntry(entry.t, entry.severity, entry.source, entry.text, entry.count,
                                m.notes_written))
    m.version += 1


def deadline_miss(m: Any, now: float, period_us: int) -> None:
    """Deadline misses as one line, kept up to date: how many, since when, the longest period."""
    n, worst, first, seq = m._misses
    if n == 0:
        first = now - m.start
    n, worst = n + 1, max(worst, period_us)
    for i, e in enumerate(m.events):
        if e.seq == seq:
            del m.events[i]
            break
    # The board reports a miss at most every 10 s while flying: this counts its reports, F9 every miss.
    text = (f"deadline miss (period {period_us} µs; F9 counts them all)" if n == 1 else
            f"deadline misses reported {n} times since {first:.0f} s (longest period {worst} µs; at most one "
            "report per 10 s: F9 counts them all)")
    write(m, LogEntry(now - m.start, "warning", "board", text))
    m._misses = (n, worst, first, m.notes_written)
