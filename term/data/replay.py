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
- Indexed: a session whose files were closed (their MCAP summary says how long it is and whether the station's
  events are there) is read as the playback goes, ``LOAD_AHEAD_S`` past the position (a seek reads on to where
  it goes), so the first frame of an hour's recording shows at once; one cut short is read whole first. What was
  read stays in memory (about 250 bytes a frame: some 200 MB for an hour at full telemetry), so going back is
  quick.
- A damaged chunk or record is skipped as it is read and the rest plays (``damage`` counts them, ``status()``
  says so); a file with nothing readable after its header is a RecordingError naming where.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from term.core.events import Fatal, FromLink, LinkUp, Note, StickSet
from term.core.link import PacketReceived
from term.core.protocol import Decoder, Joystick
from term.core.userfile import RECORDING_MAX_BYTES, open_user_file
from term.data.recording import (
    NOT_REPLAYABLE,
    LinkBytes,
    LoggedEvent,
    Recording,
    RecordingError,
    StationRecord,
    TruthSample,
    decode_event,
    decoded_only,
    iter_file,
    session_parts,
)

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
SORT_WINDOW_S = 1.0  # the most a record may be stamped before one written ahead of it
LOAD_AHEAD_S = 5.0  # an indexed replay decodes this far past the position (and on to where a seek goes)


def _events(items: Iterable[Any], start_ns: int, has_station: bool) -> Iterator[tuple[float, Any]]:
    """The station events a recording's items stand for, each with its time (s since ``start_ns``), in file order."""
    decoders: dict[tuple[str, str], Decoder] = {}
    for item in items:
        t = (item.t_ns - start_ns) / 1e9
        kind = type(item)
        if kind is LinkBytes:
            if item.direction == "tx" and has_station:
                continue  # the sticks and commands sent are in the station's events
            key = (item.link, item.direction)
            dec = decoders.get(key) or decoders.setdefault(key, Decoder(keep_text=True))
            for pkt in dec.feed(item.data):
                if item.direction == "rx":
                    yield (t, FromLink(item.link, PacketReceived(pkt)))
                elif type(pkt) is Joystick:
                    yield (t, StickSet(pkt))
        elif kind is StationRecord:
            ev = decode_event(item.data)
            if ev is None or type(ev) is Fatal:
                continue
            if type(ev) is LinkUp:
                ev = LinkUp(ev.link, f"replay of {ev.name}", ev.again)
            yield (t, ev)
        elif kind is LoggedEvent and not has_station:
            yield (t, Note(item.severity, item.source, item.text))
        elif kind is TruthSample:  # the simulator's truth (term --sim): the front end's room view, not the model
            yield (t, item)


def build_timeline(items: Iterable[Any], start_ns: int | None = None) -> list[tuple[float, Any]]:
    """The station events a recording's items stand for, each with its time (s since ``start_ns``), in time order."""
    items = list(items)
    has_station = any(type(i) is StationRecord for i in items)
    if start_ns is None:
        start_ns = items[0].t_ns if items else 0
    out = list(_events(items, start_ns, has_station))
    out.sort(key=lambda e: e[0])  # stable: the recorded order within one instant is kept
    return out


def _in_order(events: Iterator[tuple[float, Any]]) -> Iterator[tuple[float, Any]]:
    """``events`` in time order, given that none comes more than ``SORT_WINDOW_S`` after a later one (the link's
    thread and the event loop stamp their records apart by far less); the recorded order within an instant kept."""
    heap: list[tuple[float, int, Any]] = []
    for n, (t, ev) in enumerate(events):
        heapq.heappush(heap, (t, n, ev))
        while heap[0][0] < t - SORT_WINDOW_S:
            t0, _, e0 = heapq.heappop(heap)
            yield (t0, e0)
    while heap:
        t0, _, e0 = heapq.heappop(heap)
        yield (t0, e0)


def _summaries(parts: list[Path]) -> tuple[bool, int, dict[str, str], bool] | None:
    """From the parts' MCAP summaries (no message read): whether the station's events were recorded, the end
    time (ns), the session metadata and whether the simulator's truth was recorded; None if a part has no summary
    (cut short: then it is read whole)."""
    from mcap.reader import make_reader

    has_station, end_ns, meta, has_truth = False, 0, {}, False
    for i, part in enumerate(parts):
        try:
            with open_user_file(part, RECORDING_MAX_BYTES, "session recording") as f:  # never a FIFO
                reader = make_reader(f)
                summary = reader.get_summary()
                if summary is None or summary.statistics is None:
                    return None
                has_station |= any(c.topic == "/station" for c in summary.channels.values())
                has_truth |= any(c.topic == "/truth" for c in summary.channels.values())
                end_ns = max(end_ns, summary.statistics.message_end_time)
                if i == 0:
                    meta = next((dict(m.metadata) for m in reader.iter_metadata() if m.name == "session"), {})
        except Exception:  # a file without its summary: the mcap package's reader gives up on it
            return None
    return has_station, end_ns, meta, has_truth


class Replay:
    """A recorded session's timeline and the playback position (see the module docstring)."""

    def __init__(self, timeline: list[tuple[float, Any]], source: str = "", meta: dict[str, str] | None = None,
                 more: Iterator[tuple[float, Any]] | None = None, duration: float | None = None) -> None:
        """``more``: the rest of the timeline, read as the playback needs it (``load``); ``duration`` then says
        how long the session is (its summary's), until the last event is read."""
        self.timeline = timeline
        self.source = source
        self.meta = meta or {}  # the session's facts as recorded (links' names, start, protocol version)
        self._more = more
        self.duration = timeline[-1][0] if timeline else 0.0
        if more is not None and duration is not None:
            self.duration = max(self.duration, duration)
        self.position = 0.0  # s since the session's start: how far the playback is
        self.speed = 1.0
        self.paused = False
        self._index = 0
        self._now = 0.0
        self.has_truth = any(type(ev) is TruthSample for _, ev in timeline)  # (load: from the summaries)
        self.recordings: list[Recording] = []  # the files read (``load``): their damage skipped, as it is read

    @property
    def damage(self) -> int:
        """Damaged parts of the recording skipped so far (term.data.recording), and messages of lost channels."""
        return sum(len(r.damage) + (r.orphans > 0) for r in self.recordings)

    @classmethod
    def load(cls, path: Path) -> Replay:
        """Every part of the session ``path`` belongs to; RecordingError if it cannot be read. A session whose files
        have their summary (closed) is read as the playback goes (the first frame of an hour's recording at once),
        one cut short is read whole first."""
        parts = session_parts(Path(path))
        if decoded_only(Path(path)):
            raise RecordingError(f"{path} {NOT_REPLAYABLE}")
        found = _summaries(parts)
        if found is not None:
            has_station, end_ns, meta, has_truth = found
            start_ns = int(meta.get("start_ns", 0) or 0) if meta else 0
            if start_ns:
                read = [Recording(part) for part in parts]
                items = (item for rec in read for item in iter_file(rec.path, rec))
                replay = cls([], str(path), meta, _in_order(_events(items, start_ns, has_station)),
                             (end_ns - start_ns) / 1e9)
                replay.recordings = read
                replay._load_to(LOAD_AHEAD_S)
                replay.has_truth = has_truth
                if not replay.timeline and replay._more is None:
                    raise RecordingError(f"{path}: nothing recorded")
                return replay
        items = []
        read: list[Recording] = []
        first: Recording | None = None
        for part in parts:
            rec = Recording(part)
            items.extend(iter_file(part, rec))
            first = first or rec
            read.append(rec)
        if not items or first is None:
            raise RecordingError(f"{path}: nothing recorded")
        replay = cls(build_timeline(items, first.start_ns if first.meta else None), str(path), first.meta)
        replay.recordings = read
        return replay

    def clock(self) -> float:
        """The time of the event being applied, else the playback position (s since the session's start)."""
        return self._now

    @property
    def finished(self) -> bool:
        return self._index >= len(self.timeline) and self._more is None

    def _load_to(self, t: float) -> None:
        """Read the timeline on to ``t`` s (and a little past it: an instant's events all together)."""
        more, timeline = self._more, self.timeline
        if more is None or (timeline and timeline[-1][0] > t):
            return
        for ev in more:
            timeline.append(ev)
            if ev[0] > t:
                return
        self._more = None  # read to its end: the duration is the last event's
        self.duration = timeline[-1][0] if timeline else 0.0
        self.position = min(self.position, self.duration)
    def advance(self, dt: float) -> Iterator[Any]:
        """Move the position by ``dt`` wall seconds times the speed (not while paused); the events passed."""
        if not self.paused:
            self._load_to(self.position + max(0.0, dt) * self.speed + LOAD_AHEAD_S)
            self.position = min(self.duration, self.position + max(0.0, dt) * self.speed)
        return self.catch_up()

    def catch_up(self) -> Iterator[Any]:
        """The events from where the last call stopped up to the position, lazily: apply each before taking the
        next, as ``clock()`` is the time of the one just taken."""
        timeline, end = self.timeline, self.position
        self._load_to(end + LOAD_AHEAD_S)
        while self._index < len(timeline) and timeline[self._index][0] <= end:
            self._now, ev = timeline[self._index]
            self._index += 1
            yield ev
        self._now = end

    def seek(self, t: float) -> bool:
        """Move the position to ``t`` (clamped to the session); True if it went back: apply ``catch_up()`` to a
        fresh model then."""
        self._load_to(t + LOAD_AHEAD_S)
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
        damage = f" · {self.damage} damaged part{'s' * (self.damage > 1)} skipped" if self.damage else ""
        return f"REPLAY {_mmss(self.position)} / {_mmss(self.duration)} {state}{damage}"


def _mmss(t: float) -> str:
    m, s = divmod(max(0.0, t), 60.0)
    return f"{int(m):02d}:{s:04.1f}"
