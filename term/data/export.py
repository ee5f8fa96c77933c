"""`term export`: a session recording or a downloaded flash log as MCAP or as CSV in the terminal's units.

Contract (docs/recording.md shows how to open the results in Foxglove, PlotJuggler and pandas):

- Names and units come from the packet table (``term.core.protocol``): a field ``phi`` whose scaled unit is ``°``
  becomes ``phi_deg``, ``height`` in m ``height_m``, ``battery`` in V ``battery_v``; the value is the raw value
  times the table's ``scale``. A field without a physical unit (counters, motor commands, sticks, enumerations)
  keeps its bare name and raw value; an enumeration gets a ``<name>_name`` beside it (``mode_name``: ``MANUAL``).
- MCAP: one channel per packet type and link and direction, ``/<link>/<rx|tx>/<Packet>`` (``/serial/rx/Attitude``),
  JSON messages with a JSON schema generated from the table (title, field units and meanings), ``log_time`` the
  receive time (Unix ns, µs resolution); events on ``/events`` as ``foxglove.Log``; the raw link bytes on
  ``/<link>/<rx|tx>`` as in the session file, so an exported file is itself a session recording (replayable and
  exportable again). A recording cut short by a crash is written out complete.
- CSV (session): one row per decoded frame and per event: ``t_s`` (seconds since the session started), ``link``,
  ``dir``, ``packet``, then the columns of every packet type present (empty where a row's packet has no such
  field), then ``level``, ``source``, ``message`` for events. ``board_units=True`` writes raw field values under
  bare names.
- Flash log (the CSV a download writes, board units, time ``t_us``): to CSV with ``t_s`` and the same column names
  as the session export, or to MCAP on ``/flashlog`` (``log_time`` the board's time since boot).
- Damage: a damaged chunk or record of the recording is skipped and the rest exported (``ExportResult.damage``
  says what was skipped, where; term export then exits 1); a recording with nothing readable after its header is an
  ``ExportError`` naming where the damage begins. The output is written beside ``out`` (``.<name>.part``) and
  renamed over it at the end: a failed export leaves no half file and an earlier ``out`` as it was.

Bad input ends in ``ExportError`` with one line.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import datetime as dt
import importlib.util
import io
import json
import math
import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from term.core.logformat import LOG_TIME_COLUMN
from term.core.protocol import MAX_FRAME, PACKETS, SPEC_OF, Decoder, PacketSpec, column_scale
from term.core.userfile import LOG_MAX_BYTES, RECORDING_MAX_BYTES, UserFileError, open_user_file
from term.data.channels import EVENTS, Channels, ChannelSpec, console_line, raw_channel
from term.data.columns import (  # noqa: F401  (column_name, field_column: the export's names, used beside it)
    DIGITS,
    Column,
    _enum_name,
    _enum_of,
    _value,
    column_name,
    field_column,
    json_schema,
    packet_columns,
    packet_record,
)
from term.data.recording import (
    MAGIC,
    SEVERITY_OF,
    LinkBytes,
    LoggedEvent,
    Recording,
    RecordingError,
    iter_file,
    session_parts,
)

FORMATS = ("mcap", "csv")

class ExportError(ValueError):
    """The input cannot be exported; the message is one line."""


# --- reading the sources ----------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class DecodedFrame:
    """A packet decoded from the bytes of ``link`` in ``direction``, with the time those bytes crossed it."""

    t_ns: int
    link: str
    direction: str
    packet: Any


def decode(items: Iterable[Any], keep_raw: bool = False) -> Iterator[Any]:
    """Link bytes to the packets in them (one stream decoder per link and direction), each bytes item followed by
    its packets if ``keep_raw``; events pass through. The recorded bytes are decoded with today's codec, whatever
    version wrote them."""
    decoders: dict[tuple[str, str], Decoder] = {}
    for item in items:
        if type(item) is LinkBytes:
            if keep_raw:
                yield item
            key = (item.link, item.direction)
            dec = decoders.get(key)
            if dec is None:
                dec = decoders[key] = Decoder(keep_text=True)  # text between frames costs no frame
            for pkt in dec.feed(item.data):
                yield DecodedFrame(item.t_ns, item.link, item.direction, pkt)
        else:
            yield item


def kind_of(path: Path) -> str:
    """"session" (an MCAP recording) or "flashlog" (a CSV from the log download); ExportError otherwise."""
    if not os.path.lexists(path):
        raise ExportError(f"{path} not found")
    try:
        with open_user_file(path, RECORDING_MAX_BYTES, "recording or log") as f:  # a FIFO or device: one line
            head = f.read(256)
    except UserFileError as exc:
        raise ExportError(str(exc)) from None
    except OSError as exc:
        raise ExportError(f"cannot read {path}: {exc.strerror or exc}") from None
    if head.startswith(MAGIC):
        return "session"
    first = head.split(b"\n", 1)[0].decode("utf-8", "replace").strip().split(",")
    if LOG_TIME_COLUMN in first:
        return "flashlog"
    if first[:2] == ["offset", "hex"]:
        raise ExportError(f"{path} holds raw log bytes (the board's format was not recognised): nothing to export")
    raise ExportError(f"{path} is neither a session recording (MCAP) nor a flash-log CSV "
                      f"(no {LOG_TIME_COLUMN} column)")


def _session_items(path: Path, info: list[Recording]) -> Iterator[Any]:
    """Every part's items, link bytes as plain tuples ``(t_ns, link, direction, data)`` (``iter_file``'s
    ``plain``: no object a message on the export's hot path)."""
    for part in session_parts(path) if path.parent.exists() else [path]:
        rec = Recording(part)
        info.append(rec)
        try:
            yield from iter_file(part, rec, plain=True)
        except RecordingError as exc:
            raise ExportError(str(exc)) from None


def read_flash_csv(path: Path) -> tuple[list[str], list[list[float]]]:
    """The header and rows of a downloaded flash log (board units); a repeated header (a new segment) is skipped."""
    try:
        with io.TextIOWrapper(open_user_file(path, LOG_MAX_BYTES, "flash log"), encoding="utf-8",
                              newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None) or []
            rows = []
            for n, row in enumerate(reader, start=2):
                if not row or row == header:
                    continue
                try:
                    values = [float(v) for v in row]
                except ValueError:
                    raise ExportError(f"{path} line {n}: not numbers ({','.join(row)[:40]})") from None
                if len(values) != len(header):
                    raise ExportError(f"{path} line {n}: {len(values)} values for {len(header)} columns")
                rows.append(values)
    except UserFileError as exc:
        raise ExportError(str(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ExportError(f"cannot read {path}: {exc}") from None
    if LOG_TIME_COLUMN not in header:
        raise ExportError(f"{path} has no {LOG_TIME_COLUMN} column: not a flash-log CSV")
    return header, rows


def flash_columns(header: list[str], board_units: bool = False) -> list[Column]:
    cols = []
    for name in header:
        try:
            scale, unit = column_scale(name)
        except KeyError:  # "segment", or a variable the table does not know: as it is
            scale, unit = 1.0, ""
        enum = _enum_of(unit)
        if board_units:
            cols.append(Column(name, name, 1.0, unit, enum=enum))
        else:  # the time column is t_s, as in a session's CSV (there since the session's start, here since boot)
            shown = "t_s" if name == LOG_TIME_COLUMN else column_name(name, unit)
            cols.append(Column(shown, name, scale, unit, enum=enum))
    return cols


# --- writing ------------------------------------------------------------------------------------------------------


@dataclass
class ExportResult:
    kind: str  # "session" or "flashlog"
    rows: int  # frames and events (session) or records (flash log) written
    complete: bool = True  # False: the recording was cut short (a crash); everything readable was written
    damage: list[str] = dataclasses.field(default_factory=list)  # damaged parts skipped, one line a file


Progress = Callable[[int, int | None], None]  # (items read, items in the recording or None if not known)
PROGRESS_EVERY = 5_000  # items of the recording between two calls of ``progress`` (a second of a session is ~200)


def export(src: Path, out: Path, fmt: str | None = None, board_units: bool = False, raw: bool = False,
           progress: Progress | None = None, library: str = "auto") -> ExportResult:
    """Convert ``src`` (a session recording or a flash-log CSV) to ``out`` in ``fmt`` (from the suffix if None).
    ``raw``: MCAP keeps the link bytes and the station's records too (it replays); ``progress`` is told how far;
    ``library``: the MCAP writer, "sdk", "mcap" or "auto" (the SDK's if installed)."""
    fmt = fmt or out.suffix.lstrip(".").lower()
    if fmt == "tlog":  # a MAVLink telemetry log (term/data/tlog.py; helper mavlink)
        from term.data.tlog import TlogError, write_tlog

        if board_units or raw or kind_of(src) != "session" or (out.exists() and out.resolve() == src.resolve()):
            raise ExportError("a telemetry log is written from a session recording to another file, in MAVLink's "
                              "units (no --board-units, no --raw)")
        tlog_info: list[Recording] = []
        try:
            n = write_tlog(_counted(_session_items(src, tlog_info), src, progress), out, tlog_info)
        except TlogError as exc:
            raise ExportError(str(exc)) from None
        return ExportResult("session", n, all(r.complete for r in tlog_info))
    if fmt not in FORMATS:
        raise ExportError(f"unknown format {fmt!r}: use -f mcap or -f csv (or an -o ending in .mcap or .csv)")
    if board_units and fmt != "csv":
        raise ExportError("--board-units is for CSV; MCAP carries SI units (and the raw bytes with --raw)")
    if raw and fmt != "mcap":
        raise ExportError("--raw is for MCAP: a CSV holds decoded values only")
    kind = kind_of(src)
    if out.exists() and out.resolve() == src.resolve():
        raise ExportError(f"{out} is the input: choose another output")
    if not out.parent.is_dir():  # (created without a word, it hid a typo in the path: issue 34)
        raise ExportError(f"cannot write {out}: folder {out.parent} does not exist (create it first)")
    if out.exists() and not out.is_file():
        raise ExportError(f"cannot write {out}: not a regular file")
    part = out.with_name(f".{out.name}.part")  # written beside, renamed at the end (module docstring)
    try:
        if fmt == "csv":
            f = part.open("w", newline="", encoding="utf-8")
        else:
            f = part.open("wb")
    except OSError as exc:
        raise ExportError(f"cannot write {out}: {exc.strerror or exc}") from None
    try:
        with f:
            if kind == "session":
                info: list[Recording] = []
                items = _counted(_session_items(src, info), src, progress)
                if fmt == "csv":
                    n = _session_csv(src, items, f, board_units, info)
                else:
                    n = _session_mcap(src, items, f, info, raw, library)
                result = ExportResult(kind, n, all(r.complete for r in info),
                                      [r.damage_text for r in info if r.damage_text])
            else:
                header, rows = read_flash_csv(src)
                n = _flash_csv(header, rows, f, board_units) if fmt == "csv" else _flash_mcap(src, header, rows, f)
                result = ExportResult(kind, n)
        os.replace(part, out)
        return result
    except OSError as exc:
        raise ExportError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        with contextlib.suppress(OSError):
            part.unlink()  # (gone already after the rename)


def message_count(src: Path) -> int | None:
    """The messages in ``src``'s session (every part) from the files' summaries; None if one has none (cut short)."""
    from mcap.reader import make_reader

    total = 0
    for part in session_parts(src) if src.parent.exists() else [src]:
        try:
            with open_user_file(part, RECORDING_MAX_BYTES, "session recording") as f:  # never a FIFO
                summary = make_reader(f).get_summary()
        except Exception:  # a file cut short has no summary: the mcap package's reader gives up on it
            return None
        if summary is None or summary.statistics is None:
            return None
        total += summary.statistics.message_count
    return total


def _counted(items: Iterator[Any], src: Path, progress: Progress | None) -> Iterator[Any]:
    """``items``, telling ``progress`` how far they are; the first call (0 of the total) at once, before a CSV's
    first pass or a plot's first read, so the bar is there from the start."""
    if progress is None:
        return items
    total = message_count(src)
    progress(0, total)
    return _counting(items, total, progress)


def _counting(items: Iterator[Any], total: int | None, progress: Progress) -> Iterator[Any]:
    n = 0
    for item in items:
        n += 1
        if n % PROGRESS_EVERY == 0:
            progress(n, total)
        yield item
    progress(n, n)


_UTC_SECOND: dict[int, str] = {}


def utc_text(t_ns: int) -> str:
    """``t_ns`` (Unix ns) as ISO 8601 UTC to the µs: ``2026-11-25T14:45:39.123456Z``."""
    us = t_ns // 1000
    sec, frac = divmod(us, 1_000_000)
    head = _UTC_SECOND.get(sec)
    if head is None:  # one strftime a second of the session, not one a row
        if len(_UTC_SECOND) > 4096:
            _UTC_SECOND.clear()
        head = _UTC_SECOND[sec] = dt.datetime.fromtimestamp(sec, dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{head}.{frac:06d}Z"


def _types_present(items: Iterator[Any]) -> dict[int, PacketSpec]:
    """The packet types in the recording's frames, from each frame's type byte without decoding it (a frame is
    COBS-encoded and its first data byte, the type, is never zero, so it stands as sent): a damaged frame can at
    worst add a column that stays empty. The bytes of each link and direction are split a batch at a time."""
    present: dict[int, PacketSpec] = {}
    pending: dict[tuple[str, str], bytes] = {}
    batch: dict[tuple[str, str], list[bytes]] = {}
    n = 0
    for item in items:
        if type(item) is tuple:
            datas = batch.get((item[1], item[2]))
            if datas is None:
                datas = batch[(item[1], item[2])] = []
            datas.append(item[3])
            n += 1
            if n == TYPES_BATCH:
                _scan_types(batch, pending, present)
                batch, n = {}, 0
    _scan_types(batch, pending, present)
    return present


TYPES_BATCH = 4096  # link reads split together


def _scan_types(batch: dict[tuple[str, str], list[bytes]], pending: dict[tuple[str, str], bytes],
                present: dict[int, PacketSpec]) -> None:
    for key, datas in batch.items():
        pieces = (pending.get(key, b"") + b"".join(datas)).split(b"\x00")
        tail = pieces.pop()
        if len(tail) > MAX_FRAME or any(len(p) > MAX_FRAME for p in pieces):
            # a run longer than a frame: read by read, each keeping at most a frame's length pending
            for data in datas:
                pieces = (pending.get(key, b"") + data).split(b"\x00")
                pending[key] = pieces.pop()[-MAX_FRAME:]
                _add_types(pieces, present)
            continue
        pending[key] = tail  # (no read's pending piece was longer than a frame: the same pieces as read by read)
        _add_types(pieces, present)


def _add_types(pieces: list[bytes], present: dict[int, PacketSpec]) -> None:
    for type_id, size in {(p[1], len(p)) for p in pieces if len(p) > 4}:
        if type_id not in present:
            spec = PACKETS.get(type_id)
            if spec is not None and size == spec.struct.size + 5:
                present[spec.type_id] = spec


def _finite(x: float) -> Any:
    return x if math.isfinite(x) else ""


def _finite_scaled(x: float, scale: float) -> Any:
    v = round(x * scale, DIGITS)
    return v if math.isfinite(v) else ""


def _row_text(spec: PacketSpec, columns: list[Column], index: dict[str, int], width: int) -> Callable[[Any], str]:
    """A function giving the text of a packet's CSV row from its ``packet`` cell to the line's end (``width``
    cells, its columns in their places: ``index``), as ``csv.writer`` writes the values ``packet_record`` has, from
    one f-string per packet type (the export's hot path). No cell of it needs quoting: numbers, hex, the names of
    an enumeration."""
    cells = [""] * width
    env: dict[str, Any] = {"_f": _finite, "_fs": _finite_scaled}
    for i, (col, fs) in enumerate(zip(columns, spec.fields, strict=True)):
        if fs.fmt.endswith("s"):
            value = f"p[{i}].hex()"
        elif fs.fmt == "e":  # a float on the wire: nan and inf are empty cells, as None is to csv.writer
            value = f"_f(p[{i}])" if col.scale == 1.0 else f"_fs(p[{i}], {col.scale!r})"
        elif col.scale != 1.0:
            value = f"round(p[{i}] * {col.scale!r}, {DIGITS})"
        else:
            value = f"p[{i}]"
        cells[index[col.name]] = "{" + value + "}"
        if col.enum is not None:
            env[f"_n{i}"] = {int(m): m.name for m in col.enum}
            cells[index[f"{col.name}_name"]] = f"{{_n{i}.get(p[{i}]) or p[{i}]}}"
    cells[4] = spec.cls.__name__
    text = ",".join(cells[4:]) + "\r\n"
    src = f"def row(p):\n    return f{text!r}\n"
    exec(src, env)  # noqa: S102  # built from the packet table above, never from input
    return env["row"]  # type: ignore[no-any-return]


def _csv_cell(text: str) -> str:
    """``text`` as ``csv.writer`` writes it among other cells (quoted if it holds a comma, quote or line end)."""
    buf = io.StringIO()
    csv.writer(buf).writerow([text, ""])
    return buf.getvalue()[:-3]


CSV_BATCH = 2048  # rows joined into one write


def _csv_header(present: dict[int, PacketSpec], board_units: bool) -> tuple[list[str], dict[int, list[Column]]]:
    """The CSV's header, and each present packet type's columns."""
    columns: dict[int, list[Column]] = {}
    names: list[str] = []
    for type_id in sorted(present):
        columns[type_id] = cols = packet_columns(present[type_id], board_units)
        for c in cols:
            for name in (c.name, f"{c.name}_name") if c.enum is not None else (c.name,):
                if name not in names:
                    names.append(name)
    return ["t_s", "utc", "link", "dir", "packet", *names, "level", "source", "message"], columns


def _session_csv(src: Path, items: Iterator[Any], f: Any, board_units: bool, info: list[Recording]) -> int:
    # first pass: which packet types are there (the columns)
    header, columns = _csv_header(_types_present(_session_items(src, [])), board_units)
    index = {name: i for i, name in enumerate(header)}
    width = len(header)
    rows: dict[type, Callable[[Any], str] | None] = {}
    cells: dict[str, str] = {}  # a link's or direction's name as a cell
    decoders: dict[tuple[str, str], Decoder] = {}
    w = csv.writer(f)
    w.writerow(header)
    out: list[str] = []
    start: int | None = None
    n = 0
    for item in items:
        if type(item) is tuple:
            t_ns, link, direction, data = item
            dec = decoders.get((link, direction))
            if dec is None:
                dec = decoders[(link, direction)] = Decoder(keep_text=True)  # text between frames costs no frame
            pkts = dec.feed(data)
            if not pkts:
                continue
            if start is None:
                start = info[0].start_ns if info[0].meta else t_ns
            head = cells.get(link)
            if head is None:
                head = cells[link] = _csv_cell(link)
            prefix = f"{(t_ns - start) / 1e9:.6f},{utc_text(t_ns)},{head},{direction},"
            for pkt in pkts:
                row = rows.get(type(pkt), False)
                if row is False:
                    spec = SPEC_OF[type(pkt)]  # (a type the first pass did not see has no column: None)
                    row = rows[type(pkt)] = (_row_text(spec, columns[spec.type_id], index, width)
                                             if spec.type_id in columns else None)
                if row is not None:
                    out.append(prefix + row(pkt))
            if len(out) >= CSV_BATCH:
                f.write("".join(out))
                n += len(out)
                out.clear()
        elif type(item) is LoggedEvent:
            if start is None:
                start = info[0].start_ns if info[0].meta else item.t_ns
            f.write("".join(out))
            n += len(out) + 1
            out.clear()
            line = [""] * width
            line[:2] = [f"{(item.t_ns - start) / 1e9:.6f}", utc_text(item.t_ns)]
            line[4] = "log"
            line[-3:] = [item.severity, item.source, item.text]
            w.writerow(line)
        else:  # the station's records are for a replay, not a table (but the console's); the first starts the clock
            if start is None:
                start = info[0].start_ns if info[0].meta else item.t_ns
            n += _console_csv_row(item, w, f, out, start, width)
    f.write("".join(out))
    return n + len(out)


def _console_csv_row(item: Any, w: Any, f: Any, out: list[str], start: int, width: int) -> int:
    """A console line (a station record of one, term.data.channels.console_line) as a CSV row: ``packet``
    "console", ``level``, ``source`` (link/uart or link/board), ``message``; 1 if one was written."""
    line = console_line(getattr(item, "data", None))
    if line is None:
        return 0
    link, source, level, text = line
    k = len(out)  # the frames' rows before it: written first, in time order
    f.write("".join(out))
    out.clear()
    row = [""] * width
    row[:5] = [f"{(item.t_ns - start) / 1e9:.6f}", utc_text(item.t_ns), link, "rx", "console"]
    row[-3:] = [SEVERITY_OF.get(level, "info"), source, text]
    w.writerow(row)
    return k + 1


class _McapLibWriter:
    """MCAP through the mcap package (always installed)."""

    def __init__(self, f: Any) -> None:
        self.w = Writer(f, compression=CompressionType.ZSTD)
        self.w.start("", "quadrupel term export")
        self.schemas: dict[str, int] = {}
        self.seq: dict[int, int] = {}

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.w.add_metadata(name, data)

    def channel(self, spec: ChannelSpec) -> Callable[[bytes, int], None]:
        """The channel's ``log(data, log_time_ns)``."""
        sid = self.schemas.get(spec.schema_name)
        if sid is None:
            sid = self.schemas[spec.schema_name] = self.w.register_schema(spec.schema_name, spec.schema_encoding,
                                                                          spec.schema)
        ch = self.w.register_channel(spec.topic, spec.message_encoding, sid)
        seq, add = [0], self.w.add_message

        def log(data: bytes, t_ns: int) -> None:
            seq[0] += 1
            add(ch, log_time=t_ns, data=data, publish_time=t_ns, sequence=seq[0])

        return log

    def finish(self) -> None:
        self.w.finish()


class _SdkWriter:
    """MCAP through Foxglove's SDK (the 'foxglove' extra; the live server's library): some seven times quicker a
    message than the mcap package, which is what makes a long export quick."""

    def __init__(self, f: Any) -> None:
        import foxglove
        from foxglove.mcap import MCAPWriteOptions

        self.fg = foxglove
        self.context = foxglove.Context()
        # one compression thread: this machine's other core is the pilot's
        self.w = foxglove.open_mcap(f, context=self.context, writer_options=MCAPWriteOptions(compression_threads=0))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.w.write_metadata(name, data)

    def channel(self, spec: ChannelSpec) -> Callable[[bytes, int], None]:
        """The channel's ``log(data, log_time_ns)``."""
        schema = self.fg.Schema(name=spec.schema_name, encoding=spec.schema_encoding, data=spec.schema)
        return self.fg.Channel(spec.topic, schema=schema, message_encoding=spec.message_encoding,  # type: ignore
                               context=self.context).base.log

    def finish(self) -> None:
        self.w.close()


def mcap_writer(f: Any, library: str = "auto") -> _McapLibWriter | _SdkWriter:
    """The SDK's writer if it is installed (or asked for), else the mcap package's."""
    if library == "sdk" or (library == "auto" and importlib.util.find_spec("foxglove") is not None):
        return _SdkWriter(f)
    return _McapLibWriter(f)


def _session_mcap(src: Path, items: Iterator[Any], f: Any, info: list[Recording], raw: bool,
                  library: str = "auto") -> int:
    """The session's channels (term.data.channels: the ones the live server serves) into an MCAP file."""
    w = mcap_writer(f, library)
    channels: dict[str, tuple[Callable[[bytes, int], None], bool]] = {}  # by topic (a spec's hash hashes its schema)
    decoders: dict[tuple[str, str], Decoder] = {}
    n = 0
    meta_written = False
    dumps = json.dumps
    maker = Channels(raw=raw)
    frame = maker.frame
    for item in items:
        if not meta_written and info[0].meta:
            w.metadata("session", dict(info[0].meta, exported_from=src.name))
            meta_written = True
        if type(item) is tuple:  # link bytes: decoded here (Channels.item's work, without an object a message)
            t_ns, link, direction, data = item
            if raw:
                n += _log(w, channels, raw_channel(link, direction), t_ns, data)
            dec = decoders.get((link, direction))
            if dec is None:
                dec = decoders[(link, direction)] = Decoder(keep_text=True)  # text between frames costs no frame
            for pkt in dec.feed(data):
                for spec, t, msg in frame(t_ns, link, direction, pkt):
                    found = channels.get(spec.topic)
                    if found is None:
                        n += _log(w, channels, spec, t, msg)
                    else:
                        found[0](msg, t)
                        n += found[1]
            continue
        for spec, t_ns, msg in maker.item(item):
            n += _log(w, channels, spec, t_ns, msg if type(msg) is bytes else dumps(msg, ensure_ascii=False).encode())
    w.finish()
    return n


def _log(w: _McapLibWriter | _SdkWriter, channels: dict[str, tuple[Callable[[bytes, int], None], bool]],
         spec: ChannelSpec, t_ns: int, data: bytes) -> bool:
    """One message on ``spec``'s channel (registered on first use); whether it is a row (a frame or an event, as
    the CSV counts its rows)."""
    found = channels.get(spec.topic)
    if found is None:
        found = channels[spec.topic] = (w.channel(spec), spec is EVENTS or spec.topic.count("/") == 3)
    found[0](data, t_ns)
    return found[1]


def _flash_csv(header: list[str], rows: list[list[float]], f: Any, board_units: bool) -> int:
    cols = flash_columns(header, board_units)
    names: list[str] = []
    for c in cols:
        names.append(c.name)
        if c.enum is not None:
            names.append(f"{c.name}_name")
    w = csv.writer(f)
    w.writerow(names)
    for row in rows:
        out: list[Any] = []
        for c, raw in zip(cols, row, strict=True):
            v = int(raw) if raw.is_integer() else raw
            out.append(_value(v, c.scale))
            if c.enum is not None:
                out.append(_enum_name(c.enum, int(raw)))
        w.writerow(out)
    return len(rows)


def _flash_mcap(src: Path, header: list[str], rows: list[list[float]], f: Any) -> int:
    cols = flash_columns(header)
    props = {c.name: {"type": "number" if c.scale != 1.0 else "integer", "description": c.unit} for c in cols}
    schema = {"$schema": "http://json-schema.org/draft-07/schema#", "title": "quadrupel.FlashLog",
              "description": "one record of the board's flash log", "type": "object", "properties": props}
    w = Writer(f, compression=CompressionType.ZSTD)
    w.start("", "quadrupel term export")
    w.add_metadata("flashlog", {"exported_from": src.name, "time": "board time since boot"})
    sid = w.register_schema("quadrupel.FlashLog", "jsonschema", json.dumps(schema).encode())
    ch = w.register_channel("/flashlog", "json", sid)
    t_index = header.index(LOG_TIME_COLUMN)
    for i, row in enumerate(rows):
        rec = {}
        for c, raw in zip(cols, row, strict=True):
            rec[c.name] = _value(int(raw) if raw.is_integer() else raw, c.scale)
            if c.enum is not None:
                rec[f"{c.name}_name"] = _enum_name(c.enum, int(raw))
        t_ns = max(0, int(row[t_index])) * 1000
        w.add_message(ch, log_time=t_ns, data=json.dumps(rec).encode(), publish_time=t_ns, sequence=i + 1)
    w.finish()
    return len(rows)


def all_packet_schemas() -> dict[str, dict[str, Any]]:
    """Every packet type's JSON schema, by packet name (docs and tests)."""
    return {spec.cls.__name__: json_schema(spec) for spec in sorted(PACKETS.values(), key=lambda s: s.type_id)}
