"""Session recording: every byte each link carried, both ways, and every event, kept in one MCAP file per session.

Contract (docs/recording.md has the why and the numbers):

- ``SessionRecorder(directory, now)`` opens ``<directory>/<YYYYmmdd-HHMMSS>.mcap`` (the session's UTC start) and is
  fed by the terminal: ``received(link, data, now)`` for bytes read from a link, ``sent(link, data, now)`` for
  bytes written to it, ``event(now, severity, source, text)`` for what the events panel shows, ``truth(truth,
  now)`` for the simulator's truth in ``--sim`` (``/truth``, JSON; read back as ``TruthSample``). ``now`` is the
  caller's monotonic clock in seconds; nothing here reads a clock except once, at the start, the wall clock
  (``wall_ns`` injects it), so times are absolute in the file.
- The bytes are kept exactly as they crossed the link (whole frames or any split of them, garbage included), on
  the channel ``/<link>/rx`` or ``/<link>/tx``; ``term.data.export`` and the replay decode them with the protocol codec
  of the day, so a later version can decode an old recording again. Events go to ``/events`` as ``foxglove.Log``
  JSON (Foxglove's Log panel shows them). Message ``log_time`` is the receive time, µs resolution, in ns since
  the Unix epoch; the ``session`` metadata record holds the start, the protocol version and the part number.
- Crash safety: MCAP keeps its index and summary at the end, written by ``close``. Until then the file is a run of
  whole records: ``flush`` (done by ``received``/``sent``/``event`` once ``flush_period`` has passed, and by
  ``poll``, which the caller runs at least once a second) closes the current chunk and hands it to the OS. A
  SIGKILL or a pulled cable loses at most the last ``flush_period``; ``read_recording`` reads such a file up to its
  last whole record (the mcap package's own readers stop with an error on it), and ``term export`` writes it out
  as a complete MCAP again.
- Damage (a flipped byte, a bad disk block): the reader skips a chunk whose CRC or compression fails, and bytes
  that are no record (records start again where two in a row fit), and reads on; ``Recording.damage`` lists
  what was skipped and where (``damage_text`` in one line), ``orphans`` the messages of a channel whose record was
  lost (a closed file's channels are read from its summary first, so that is rare). A file with nothing readable
  after its header (the magic then noise, a header record claiming more than the file) is a RecordingError
  naming the byte where the damage begins, never an empty recording.
- Size bound: a file that reaches ``max_file_bytes`` is closed and the session goes on in ``<stem>.p2.mcap``,
  ``.p3``…; before each new file the oldest recordings are deleted until the directory holds at most
  ``max_total_bytes``. A disk error stops the recording (``error`` says why), never the flight.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import math
import os
import re
import time
from collections.abc import Callable, Collection, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from term.core.protocol import PROTOCOL_VERSION
from term.core.userfile import RECORDING_MAX_BYTES, UserFileError, open_user_file
from term.data.mcapwalk import MAGIC, Damage, Walk, damage_text
from term.transports.base import Transport

FORMAT_VERSION = 1  # of the session layout described above
PROFILE = "quadrupel-session"
RAW_ENCODING = "quadrupel-frames"  # the link's bytes as they crossed it: COBS frames, each ended by 0x00
FLUSH_PERIOD_S = 1.0
MAX_FILE_BYTES = 64 * 1024 * 1024
MAX_TOTAL_BYTES = 1024 * 1024 * 1024
SUFFIX = ".mcap"
_NAME = re.compile(r"^(\d{8}-\d{6})(?:-(\d+))?(?:\.p(\d+))?\.mcap$")

# foxglove.Log (Foxglove's schema for log lines, JSON encoding): level 1 debug .. 5 fatal.
LOG_SCHEMA = {
    "title": "foxglove.Log",
    "type": "object",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "level": {"type": "integer", "description": "1 debug, 2 info, 3 warning, 4 error, 5 fatal"},
        "message": {"type": "string"},
        "name": {"type": "string", "description": "who said it: board, link, nak, ble, term, joystick"},
        "file": {"type": "string"},
        "line": {"type": "integer"},
    },
}
TRUTH_SAMPLE = {"title": "quadrupel.Truth", "type": "object",
                "description": "the simulator's truth as it sent it (term/lessons/instructor.py Truth): earth NED from "
                               "the pad, body FRD, SI units"}
LEVEL_OF = {"debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}
SEVERITY_OF = {v: k for k, v in LEVEL_OF.items()}


def default_directory() -> Path:
    """Where sessions are kept: the platform's user data directory (platformdirs), ``recordings`` inside it."""
    from platformdirs import user_data_path

    return user_data_path("quadrupel", appauthor=False) / "recordings"


def topic(link: str, direction: str) -> str:
    return f"/{link}/{direction}"


# --- writing --------------------------------------------------------------------------------------------------


@dataclass
class RecorderStats:
    messages: int = 0
    bytes_in: int = 0  # link bytes recorded (both directions)
    files: int = 0
    flushes: int = 0


class SessionRecorder:
    """One session's recording; see the module docstring. Not thread-safe: call it from the event loop."""

    def __init__(
        self,
        directory: Path,
        now: float,
        *,
        wall_ns: int | None = None,
        max_file_bytes: int = MAX_FILE_BYTES,
        max_total_bytes: int = MAX_TOTAL_BYTES,
        flush_period: float = FLUSH_PERIOD_S,
        compression: CompressionType = CompressionType.ZSTD,
        meta: dict[str, str] | None = None,
    ) -> None:
        """``meta``: more of the session's facts for the ``session`` metadata (the links' names, …)."""
        self.directory = Path(directory)
        self.meta = {str(k): str(v) for k, v in (meta or {}).items()}
        self.t0 = now
        self.start_ns = time.time_ns() if wall_ns is None else wall_ns
        self.max_file_bytes = max_file_bytes
        self.max_total_bytes = max_total_bytes
        self.flush_period = flush_period
        self.compression = compression
        self.stats = RecorderStats()
        self.error: str | None = None
        self.path: Path | None = None
        self.paths: list[Path] = []
        self._file: IO[bytes] | None = None
        self._writer: Writer | None = None
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self._last_flush = now
        self._dirty = False
        stamp = dt.datetime.fromtimestamp(self.start_ns / 1e9, dt.UTC).strftime("%Y%m%d-%H%M%S")
        self.stem = stamp
        self._open(now)

    # --- the terminal's side ----------------------------------------------------------------------------------

    def received(self, link: str, data: bytes, now: float) -> None:
        """Bytes read from ``link`` at ``now``."""
        self._raw(topic(link, "rx"), data, now)

    def sent(self, link: str, data: bytes, now: float) -> None:
        """Bytes written to ``link`` at ``now``."""
        self._raw(topic(link, "tx"), data, now)

    def event(self, now: float, severity: str, source: str, text: str) -> None:
        """One line of the events panel (severity "info", "warning" or "error"; source "board", "link", …)."""
        if self._writer is None:
            return
        t_ns = self._t_ns(now)
        msg = {"timestamp": {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000},
               "level": LEVEL_OF.get(severity, 2), "message": text, "name": source, "file": "", "line": 0}
        self._add("/events", json.dumps(msg, ensure_ascii=False).encode(), t_ns, now)

    def station_event(self, ev: Any, now: float) -> None:
        """One station event (``term.core.events``), kept on ``/station`` so a replay can apply it to a model again.
        A packet from a link is not kept here: the link's bytes carry it (the replay decodes them)."""
        if self._writer is None or (type(ev).__name__ == "FromLink" and type(ev.event).__name__ == "PacketReceived"):
            return
        try:
            data = json.dumps(encode_event(ev), ensure_ascii=False).encode()
        except (TypeError, ValueError):
            return  # not a plain event: nothing a replay could use
        self._add("/station", data, self._t_ns(now), now)

    def truth(self, truth: Any, now: float) -> None:
        """A sample of the simulator's truth (``term --sim``: the instructor channel's ``Truth``), its fields as the
        simulator sent them, on ``/truth``: where the craft really was, beside what the board estimated."""
        if self._writer is None:
            return
        try:
            data = json.dumps(asdict(truth), ensure_ascii=False).encode()
        except (TypeError, ValueError):
            return
        self._add("/truth", data, self._t_ns(now), now)

    def poll(self, now: float) -> None:
        """Flush if data waits and ``flush_period`` has passed; call at least once a ``flush_period``."""
        if self._dirty and now - self._last_flush >= self.flush_period:
            self.flush(now)

    def next_deadline(self) -> float:
        """When ``poll`` has work: the time the oldest unflushed data must reach the OS (inf: nothing waits)."""
        return self._last_flush + self.flush_period if self._dirty else float("inf")

    def flush(self, now: float) -> None:
        """Close the current chunk and hand it to the OS; start the next file if this one is full."""
        self._last_flush = now
        self._dirty = False
        if self._writer is None or self._file is None:
            return
        try:
            self._writer.flush()
            self.stats.flushes += 1
            full = self._file.tell() >= self.max_file_bytes
        except (OSError, ValueError) as exc:
            self._fail(exc)
            return
        if full:
            self._finish()
            self._open(now)

    def close(self) -> None:
        """Write the index and summary and close the file: a complete MCAP. Idempotent."""
        self._finish()

    @property
    def recording(self) -> bool:
        return self._writer is not None

    def __enter__(self) -> SessionRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- inside -------------------------------------------------------------------------------------------------

    def _t_ns(self, now: float) -> int:
        return self.start_ns + round((now - self.t0) * 1e6) * 1000  # µs resolution

    def _raw(self, name: str, data: bytes, now: float) -> None:
        if self._writer is None or not data:
            return
        self.stats.bytes_in += len(data)
        self._add(name, bytes(data), self._t_ns(now), now)

    def _add(self, name: str, data: bytes, t_ns: int, now: float) -> None:
        writer = self._writer
        assert writer is not None
        try:
            ch = self._channels.get(name)
            if ch is None:
                ch = self._channel(name)
            seq = self._seq[ch] = self._seq[ch] + 1
            writer.add_message(ch, log_time=t_ns, data=data, publish_time=t_ns, sequence=seq)
        except (OSError, ValueError) as exc:
            self._fail(exc)
            return
        self.stats.messages += 1
        self._dirty = True
        if now - self._last_flush >= self.flush_period:
            self.flush(now)

    def _channel(self, name: str) -> int:
        assert self._writer is not None
        if name == "/events":
            schema = self._writer.register_schema("foxglove.Log", "jsonschema", json.dumps(LOG_SCHEMA).encode())
            ch = self._writer.register_channel(name, "json", schema)
        elif name == "/station":
            ch = self._writer.register_channel(name, "json", 0)
        elif name == "/truth":
            schema = self._writer.register_schema("quadrupel.Truth", "jsonschema", json.dumps(TRUTH_SAMPLE).encode())
            ch = self._writer.register_channel(name, "json", schema)
        else:
            ch = self._writer.register_channel(name, RAW_ENCODING, 0)
        self._channels[name] = ch
        self._seq[ch] = 0
        return ch

    def _next_path(self) -> Path:
        part = len(self.paths) + 1
        suffix = f".p{part}" if part > 1 else ""
        return self.directory / f"{self.stem}{suffix}{SUFFIX}"

    def _open(self, now: float) -> None:
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            if not self.paths:  # a second session started within the same second: keep both
                base, n = self.stem, 1
                while any(p.name.startswith(self.stem + ".") for p in self.directory.iterdir()):
                    n += 1
                    self.stem = f"{base}-{n}"
            path = self._next_path()
            prune(self.directory, self.max_total_bytes, keep=set(self.paths))
            f = path.open("xb")
        except OSError as exc:
            self._fail(exc)
            return
        self._file, self.path = f, path
        self.paths.append(path)
        self.stats.files += 1
        self._channels.clear()
        self._seq.clear()
        w = Writer(f, compression=self.compression)
        try:
            w.start(PROFILE, "quadrupel term")
            w.add_metadata("session", {
                **self.meta,
                "format": str(FORMAT_VERSION),
                "protocol": str(PROTOCOL_VERSION),
                "start_ns": str(self.start_ns),
                "start_utc": dt.datetime.fromtimestamp(self.start_ns / 1e9, dt.UTC).isoformat(),
                "part": str(len(self.paths)),
                "session": self.stem,
            })
            w.flush()
        except (OSError, ValueError) as exc:
            self._writer = w
            self._fail(exc)
            return
        self._writer = w
        self._last_flush = now

    def _finish(self) -> None:
        w, f = self._writer, self._file
        self._writer = self._file = None
        if w is not None:
            with contextlib.suppress(OSError, ValueError):
                w.finish()
        if f is not None:
            with contextlib.suppress(OSError, ValueError):
                f.flush()
                os.fsync(f.fileno())
            with contextlib.suppress(OSError):
                f.close()

    def _fail(self, exc: Exception) -> None:
        self.error = f"recording stopped: {exc}"
        f = self._file
        self._writer = self._file = None  # the writer holds a half-written chunk: drop it, keep what is on disk
        if f is not None:
            with contextlib.suppress(OSError, ValueError):
                f.close()


def prune(directory: Path, max_total_bytes: int, keep: Collection[Path] = ()) -> list[Path]:
    """Delete the oldest recordings in ``directory`` until they add up to at most ``max_total_bytes``."""
    files = [p for p in list_files(directory) if p not in keep]
    total = sum(_size(p) for p in list_files(directory))
    removed = []
    for p in files:  # oldest first
        if total <= max_total_bytes:
            break
        total -= _size(p)
        with contextlib.suppress(OSError):
            p.unlink()
            removed.append(p)
    return removed


def _size(p: Path) -> int:
    try:
        return p.stat().st_size
    except OSError:
        return 0


def list_files(directory: Path) -> list[Path]:
    """The recordings in ``directory``, oldest first (names sort by start time, then part)."""
    try:
        names = [p for p in Path(directory).iterdir() if _NAME.match(p.name)]
    except OSError:
        return []
    return sorted(names, key=_sort_key)


def _sort_key(p: Path) -> tuple[str, int, int]:
    m = _NAME.match(p.name)
    assert m is not None
    return m.group(1), int(m.group(2) or 1), int(m.group(3) or 1)


def session_parts(path: Path) -> list[Path]:
    """All parts of the session that ``path`` (any part) belongs to, in order; just ``[path]`` for another name."""
    m = _NAME.match(path.name)
    if not m:
        return [path]
    key = _sort_key(path)[:2]
    return [p for p in list_files(path.parent) if _sort_key(p)[:2] == key] or [path]


# --- reading --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LinkBytes:
    """Bytes that crossed ``link`` in ``direction`` ("rx" from the board, "tx" to it) at ``t_ns`` (Unix ns)."""

    t_ns: int
    link: str
    direction: str
    data: bytes


@dataclass(frozen=True, slots=True)
class LoggedEvent:
    """A line of the events panel."""

    t_ns: int
    severity: str
    source: str
    text: str


@dataclass(frozen=True, slots=True)
class StationRecord:
    """A station event as recorded (``decode_event`` makes the event again; None if this version has no such)."""

    t_ns: int
    data: dict[str, Any]


@dataclass(frozen=True, slots=True)
class TruthSample:
    """A sample of the simulator's truth as recorded (its fields by name; unchecked: a file is hostile)."""

    t_ns: int
    data: dict[str, Any]


Item = LinkBytes | LoggedEvent | StationRecord | TruthSample


class RecordingError(ValueError):
    """Not a session recording, or unreadable; the message is one line."""


@dataclass
class Recording:
    """What ``scan`` learns of one file: its session metadata, time span and whether it was closed cleanly."""

    path: Path
    meta: dict[str, str] = field(default_factory=dict)
    complete: bool = False  # closed by the recorder (index and summary written); False: cut short
    first_ns: int | None = None
    last_ns: int | None = None
    messages: int = 0
    valid_bytes: int = 0  # the readable prefix; the rest of a cut-short file is lost
    damage: list[Damage] = field(default_factory=list)  # the byte ranges skipped as damaged (``_records``)
    orphans: int = 0  # messages skipped because their channel's record was in a damaged part

    @property
    def damage_text(self) -> str:
        """The damage skipped, in one line ("" if none)."""
        return damage_text(self.path, self.damage, self.orphans)

    @property
    def start_ns(self) -> int:
        if "start_ns" in self.meta:
            return int(self.meta["start_ns"])
        return self.first_ns or 0

    @property
    def duration_s(self) -> float:
        if self.last_ns is None:
            return 0.0
        return (self.last_ns - self.start_ns) / 1e9


def _records(path: Path, rec: Recording) -> Iterator[tuple[Any, ...]]:
    """The whole records of ``path``, in file order (term/data/mcapwalk.py: a cut-short tail ends the iteration,
    damage is skipped and noted in ``rec.damage``). A file in which nothing after the magic can be read is a
    RecordingError naming the damage. The file is read once into memory (a part is at most ``MAX_FILE_BYTES``):
    parsed with struct, some ten times quicker than the mcap package's stream reader, which replay, export and
    plot all wait on."""
    try:
        f = open_user_file(path, RECORDING_MAX_BYTES, "session recording")  # a regular file: a FIFO never hangs
    except UserFileError as exc:
        raise RecordingError(str(exc)) from None
    with f:
        raw = f.read()
    if not raw.startswith(MAGIC):
        raise RecordingError(f"{path} is not a session recording (no MCAP header)")
    walk = Walk(raw, rec.damage)
    yield from walk.records()
    rec.complete, rec.valid_bytes = walk.complete, walk.pos
    if rec.damage and not walk.read_any:
        d = rec.damage[0]
        raise RecordingError(f"{path}: damaged at byte {d.start:,}: {d.what}; nothing readable after it")


def iter_file(path: Path, recording: Recording | None = None, plain: bool = False) -> Iterator[Any]:
    """The link bytes and events of one file, in the order recorded; fills ``recording`` as it goes. ``plain``:
    link bytes as tuples ``(t_ns, link, direction, data)`` instead of ``LinkBytes`` (the export's hot path)."""
    rec = recording if recording is not None else Recording(path)
    channels: dict[int, tuple[str, str]] = {}
    known: set[int] = set()  # channel ids seen (a topic that is not the session's: its messages are not ours)
    n = 0
    try:
        for record in _records(path, rec):
            kind = record[0]
            if kind == "m":
                where = channels.get(record[1])
                if where is None:
                    rec.orphans += record[1] not in known
                    continue
                t = record[2]
                n += 1
                if rec.first_ns is None:
                    rec.first_ns = t
                if rec.last_ns is None or t > rec.last_ns:
                    rec.last_ns = t
                if where[1] in ("station", "truth"):
                    try:
                        d = json.loads(record[3])
                    except (ValueError, RecursionError):  # a hostile recording's record is skipped, never a crash
                        continue
                    if where[1] == "station":
                        yield StationRecord(t, d)
                    elif isinstance(d, dict):
                        yield TruthSample(t, d)
                elif where[1] != "events":
                    yield (t, *where, record[3]) if plain else LinkBytes(t, where[0], where[1], record[3])
                else:
                    ev = _logged(t, record[3])
                    if ev is not None:
                        yield ev
            elif kind == "c":
                known.add(record[1])
                topic = record[2]
                parts = topic.strip("/").split("/")
                if topic in ("/events", "/station", "/truth"):
                    channels[record[1]] = ("", topic[1:])
                elif len(parts) == 2 and parts[1] in ("rx", "tx"):
                    channels[record[1]] = (parts[0], parts[1])
            elif kind == "meta" and record[1] == "session":
                rec.meta = dict(record[2])
    finally:
        rec.messages += n


def _logged(t: int, data: bytes) -> LoggedEvent | None:
    try:
        d = json.loads(data)
        return LoggedEvent(t, SEVERITY_OF.get(int(d.get("level", 2)), "info"), str(d.get("name", "")),
                           str(d.get("message", "")))
    except (ValueError, TypeError, AttributeError, RecursionError):
        return None


def decoded_only(path: Path) -> bool:
    """Whether ``path`` is a ``term export`` MCAP without ``--raw``: decoded channels and no link bytes, so
    nothing a replay or a plot can decode (from the file's summary; False if it has none)."""
    try:
        with open_user_file(path, RECORDING_MAX_BYTES, "session recording") as f:  # never a FIFO
            summary = make_reader(f).get_summary()
    except Exception:  # no summary (cut short), not MCAP: not an export
        return False
    if summary is None:
        return False
    topics = [c.topic.strip("/").split("/") for c in summary.channels.values()]
    raw = any(len(t) == 2 and t[1] in ("rx", "tx") for t in topics)
    return not raw and any(len(t) == 3 and t[1] in ("rx", "tx") for t in topics)


NOT_REPLAYABLE = "is a 'term export' without --raw (decoded values only): give the session recording itself, " \
                 "or an export made with --raw"


def iter_session(path: Path) -> Iterator[Item]:
    """Every item of the session ``path`` belongs to, all its parts in order."""
    for part in session_parts(path):
        yield from iter_file(part)


def scan(path: Path) -> Recording:
    """Read one file through (its parts are separate files) and say what it holds; raises RecordingError."""
    rec = Recording(path)
    for _ in iter_file(path, rec):
        pass
    return rec


def describe(path: Path) -> Recording:
    """``scan``, but from the summary of a file closed cleanly (no need to read it through)."""
    try:
        with open_user_file(path, RECORDING_MAX_BYTES, "session recording") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            meta = next((m for m in reader.iter_metadata() if m.name == "session"), None)
            size = os.fstat(f.fileno()).st_size
    except Exception:  # no footer (cut short) or not MCAP: read it through, which says which
        return scan(path)
    stats = summary.statistics if summary is not None else None
    if stats is None or meta is None:
        return scan(path)
    rec = Recording(path, dict(meta.metadata), True, messages=stats.message_count, valid_bytes=size)
    if stats.message_count:
        rec.first_ns, rec.last_ns = stats.message_start_time, stats.message_end_time
    return rec


def sessions(directory: Path) -> list[list[Path]]:
    """The sessions in ``directory``, oldest first, each as the list of its parts."""
    groups: dict[tuple[str, int], list[Path]] = {}
    for p in list_files(directory):
        groups.setdefault(_sort_key(p)[:2], []).append(p)
    return list(groups.values())


def session_table(directory: Path) -> list[str]:
    """``term recordings``: one line per session, oldest first: start (local time), length, size, file."""
    lines = [f"{'start':19}  {'length':>8}  {'size':>9}  file"]
    for parts in sessions(directory):
        try:
            infos = [describe(p) for p in parts]
        except RecordingError as exc:
            lines.append(f"{'?':19}  {'?':>8}  {_human(sum(_size(p) for p in parts)):>9}  {parts[0]} ({exc})")
            continue
        first, last = infos[0], infos[-1]
        start = dt.datetime.fromtimestamp(first.start_ns / 1e9).astimezone().strftime("%Y-%m-%d %H:%M:%S")
        length = max(0.0, ((last.last_ns or first.start_ns) - first.start_ns) / 1e9)
        notes = [f"{len(parts)} parts"] if len(parts) > 1 else []
        if not last.complete:
            notes.append("not closed: still recording, or cut short")
        extra = f" ({', '.join(notes)})" if notes else ""
        h, rem = divmod(round(length), 3600)
        span = f"{h:d}:{rem // 60:02d}:{rem % 60:02d}"
        lines.append(f"{start:19}  {span:>8}  {_human(sum(_size(p) for p in parts)):>9}  {parts[0]}{extra}")
    return lines


def _human(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000  # type: ignore[assignment]
    return str(n)


def latest(directory: Path | None = None) -> Path:
    """The first part of the session that ended last in ``directory`` (its last part written last: issue 34, a 1 s
    demo started during a long flight is not the flight); RecordingError if there is none."""
    directory = directory or default_directory()
    groups = sessions(directory)
    if not groups:
        raise RecordingError(f"no session recordings in {directory}")

    def ended(parts: list[Path]) -> tuple[float, tuple[str, int, int]]:
        try:
            return parts[-1].stat().st_mtime, _sort_key(parts[0])
        except OSError:
            return -math.inf, _sort_key(parts[0])

    return max(groups, key=ended)[0]


# --- station events as JSON -----------------------------------------------------------------------------------
# The station's events (term.core.events, and the links' term.core.link events inside FromLink) are frozen dataclasses
# of
# plain values; they are kept by class name and field, so a replay rebuilds them. A class or field this version
# does not know is skipped on replay, never an error.


def encode_event(ev: Any) -> Any:
    """A station event (or any value inside one) as JSON-ready data."""
    import dataclasses
    from enum import Enum

    from term.core.protocol import SPEC_OF, to_dict

    if dataclasses.is_dataclass(ev) and not isinstance(ev, type):
        out = {"~": type(ev).__name__}
        for f in dataclasses.fields(ev):
            out[f.name] = encode_event(getattr(ev, f.name))
        return out
    if type(ev) in SPEC_OF:
        return {"~packet": to_dict(ev)}
    if isinstance(ev, Enum):
        return ev.value
    if isinstance(ev, (list, tuple)):
        return [encode_event(v) for v in ev]
    if ev is None or isinstance(ev, (bool, int, float, str)):
        return ev
    raise TypeError(f"cannot record {type(ev).__name__}")


def _event_classes() -> dict[str, type]:
    import dataclasses

    from term.core import console, events, link

    found: dict[str, type] = {}
    for module in (link, events, console):
        for name, obj in vars(module).items():
            if isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__module__ == module.__name__:
                found[name] = obj
    return found


_CLASSES: dict[str, type] = {}


def decode_event(data: Any) -> Any:
    """The event ``encode_event`` made ``data`` from; None for a class or field this version does not know."""
    import dataclasses
    import typing
    from enum import Enum

    from term.core.protocol import from_dict

    if isinstance(data, list):
        return [decode_event(v) for v in data]
    if not isinstance(data, dict):
        return data
    if "~packet" in data:
        try:
            return from_dict(data["~packet"])
        except (KeyError, TypeError, ValueError):
            return None
    if not _CLASSES:
        _CLASSES.update(_event_classes())
    cls = _CLASSES.get(str(data.get("~")))
    if cls is None:
        return None
    try:
        hints = typing.get_type_hints(cls)
    except Exception:
        hints = {}
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            continue  # a field added since: its default, if it has one
        v = decode_event(data[f.name])
        hint = hints.get(f.name)
        if isinstance(hint, type) and issubclass(hint, Enum) and v is not None:
            with contextlib.suppress(ValueError):
                v = hint(v)
        kwargs[f.name] = v
    try:
        return cls(**kwargs)
    except TypeError:
        return None


# --- the tap at the edge --------------------------------------------------------------------------------------


class RecordingTransport(Transport):
    """A transport that records what passes through it: ``read`` and ``write`` go to ``inner`` and their bytes to
    ``recorder`` as ``link``'s, timed by ``clock``. Everything else is ``inner``'s."""

    def __init__(self, inner: Transport, recorder: Any, link: str, clock: Callable[[], float]) -> None:
        """``recorder``: a SessionRecorder, or anything with its ``received`` and ``sent`` (the live Foxglove
        server), or a tuple of them: each gets the same bytes with the same time (one clock reading)."""
        self.inner, self.link, self.clock = inner, link, clock
        self.sinks: tuple[Any, ...] = recorder if isinstance(recorder, tuple) else (recorder,)
        self.recorder = self.sinks[0]

    @property  # type: ignore[override]
    def name(self) -> str:
        return self.inner.name

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    async def open(self) -> None:
        await self.inner.open()

    async def close(self) -> None:
        await self.inner.close()

    async def read(self) -> bytes:
        data = await self.inner.read()
        now = self.clock()
        for sink in self.sinks:
            sink.received(self.link, data, now)
        return data

    async def write(self, data: bytes) -> None:
        now = self.clock()
        for sink in self.sinks:
            sink.sent(self.link, data, now)
        await self.inner.write(data)
