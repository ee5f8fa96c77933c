"""`term replay`: a session recording played back as the station events it produced, on a playback clock.

Sans-IO: ``Replay`` holds the session's timeline and a playback position; the front end moves it (``advance`` by
the wall time that passed, ``seek``, ``speed``, ``paused``) and applies the events it returns to a model, with
``clock()`` as their time, exactly as the live station did. Contract:

- ``Replay.load(path)`` reads every part of the session (``term.data.recording``) and builds the timeline, times in
  seconds since the session's start: the bytes each link received are decoded again with today's codec into
  ``FromLink(link, PacketReceived(packet))``, and the station's recorded events (``/station``) are made again
  (``decode_event``). A ``LinkUp`` says ``replay of <transport>``, so the link panel shows a replay; ``Fatal`` is
  dropped (the replay does not end where the flight did). A recording without station events (written by another
  tool) still plays: its event lines become ``Note``s and the sticks it sent ``StickSet``s.
- ``advance(dt)`` yields the events from the position up to ``position + dt * speed`` (nothing moves while
  paused); while the caller applies them one by one, ``clock()`` is each event's own recorded time, so plots and
  the events list carry the recorded times. ``seek(t)`` moves anywhere: going back returns ``True``, and the
  caller starts again from a fresh model; then ``catch_up()`` yields the events up to the new position.
- The whole timeline is held in memory (about 250 bytes a frame: some 200 MB for an hour at full telemetry).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from term.core.events import Fatal, FromLink, LinkUp, Note, StickSet
from term.core.link import PacketReceived
from term.core.protocol import Decoder, Joystick
from term.data.recording import (
    LinkBytes,
    LoggedEvent,
    Recording,
    RecordingError,
    StationRecord,
    decode_event,
    iter_file,
    session_parts,
)

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)


def build_timeline(items: Iterable[Any], start_ns: int | None = None) -> list[tuple[float, Any]]:
    """The station events a recording's items stand for, each with its time (s since ``start_ns``)."""
    items = list(items)
    has_station = any(type(i) is StationRecord for i in items)
    if start_ns is None:
        start_ns = items[0].t_ns if items else 0
    decoders: dict[tuple[str, str], Decoder] = {}
    out: list[tuple[float, Any]] = []
    for item in items:
        t = (item.t_ns - start_ns) / 1e9
        kind = type(item)
        if kind is LinkBytes:
            if item.direction == "tx" and has_station:
                continue  # the sticks and commands sent are in the station's events
            key = (item.link, item.direction)
            dec = decoders.get(key) or decoders.setdefault(key, Decoder())
            for pkt in dec.feed(item.data):
                if item.direction == "rx":
                    out.append((t, FromLink(item.link, PacketReceived(pkt))))
                elif type(pkt) is Joystick:
                    out.append((t, StickSet(pkt)))
        elif kind is StationRecord:
            ev = decode_event(item.data)
            if ev is None or type(ev) is Fatal:
                continue
            if type(ev) is LinkUp:
                ev = LinkUp(ev.link, f"replay of {ev.name}", ev.again)
            out.append((t, ev))
        elif kind is LoggedEvent and not has_station:
            out.append((t, Note(item.severity, item.source, item.text)))
    out.sort(key=lambda e: e[0])  # stable: the recorded order within one instant is kept
    return out


class Replay:
    """A recorded session's timeline and the playback position (see the module docstring)."""

    def __init__(self, timeline: list[tuple[float, Any]], source: str = "", meta: dict[str, str] | None = None) -> None:
        self.timeline = timeline
        self.source = source
        self.meta = meta or {}  # the session's facts as recorded (links' names, start, protocol version)
        self.duration = timeline[-1][0] if timeline else 0.0
        self.position = 0.0  # s since the session's start: how far the playback is
        self.speed = 1.0
        self.paused = False
        self._index = 0
        self._now = 0.0

    @classmethod
    def load(cls, path: Path) -> Replay:
        """Every part of the session ``path`` belongs to; RecordingError if it cannot be read."""
        items: list[Any] = []
        first: Recording | None = None
        for part in session_parts(Path(path)):
            rec = Recording(part)
            items.extend(iter_file(part, rec))
            first = first or rec
        if not items or first is None:
            raise RecordingError(f"{path}: nothing recorded")
        return cls(build_timeline(items, first.start_ns if first.meta else None), str(path), first.meta)

    def clock(self) -> float:
        """The time of the event being applied, else the playback position (s since the session's start)."""
        return self._now

    @property
    def finished(self) -> bool:
        return self._index >= len(self.timeline)

    def advance(self, dt: float) -> Iterator[Any]:
        """Move the position by ``dt`` wall seconds times the speed (not while paused); the events passed."""
        if not self.paused:
            self.position = min(self.duration, self.position + max(0.0, dt) * self.speed)
        return self.catch_up()

    def catch_up(self) -> Iterator[Any]:
        """The events from where the last call stopped up to the position, lazily: apply each before taking the
        next, as ``clock()`` is the time of the one just taken."""
        timeline, end = self.timeline, self.position
        while self._index < len(timeline) and timeline[self._index][0] <= end:
            self._now, ev = timeline[self._index]
            self._index += 1
            yield ev
        self._now = end

    def seek(self, t: float) -> bool:
        """Move the position to ``t`` (clamped to the session); True if it went back: apply ``catch_up()`` to a
        fresh model then."""
        t = min(max(0.0, t), self.duration)
        back = t < self.position or (t < self._now)
        if back:
            self._index = 0
            self._now = 0.0
        self.position = t
        return back

    def faster(self) -> float:
        self.speed = next((s for s in SPEEDS if s > self.speed), SPEEDS[-1])
        return self.speed

    def slower(self) -> float:
        self.speed = next((s for s in reversed(SPEEDS) if s < self.speed), SPEEDS[0])
        return self.speed

    def status(self) -> str:
        """One line for the screen: position, length, speed, paused."""
        state = "paused" if self.paused else f"{self.speed:g}x"
        return f"REPLAY {_mmss(self.position)} / {_mmss(self.duration)} {state}"


def _mmss(t: float) -> str:
    m, s = divmod(max(0.0, t), 60.0)
    return f"{int(m):02d}:{s:04.1f}"
