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

Bad input ends in ``ExportError`` with one line.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from term.core import protocol
from term.core.logformat import LOG_TIME_COLUMN
from term.core.protocol import PACKETS, SPEC_OF, Decoder, FieldSpec, PacketSpec, column_scale
from term.data.recording import (
    LEVEL_OF,
    LOG_SCHEMA,
    MAGIC,
    RAW_ENCODING,
    LinkBytes,
    LoggedEvent,
    Recording,
    RecordingError,
    StationRecord,
    iter_file,
    session_parts,
)

FORMATS = ("mcap", "csv")
DIGITS = 6  # decimals kept after scaling: below every field's resolution, no float noise in the files

# How a unit is spelled at the end of a column name (ASCII, lower case). Units not named here are no physical
# unit (sticks, 0..1000 motor commands, bits, enumerations): those columns keep the bare field name.
UNIT_SUFFIX = {
    "°": "deg", "°/s": "dps", "g": "g", "m": "m", "m/s": "mps", "V": "v", "°C": "degc", "s": "s", "ms": "ms",
    "µs": "us", "Pa": "pa", "%": "pct", "bytes": "bytes",
}


class ExportError(ValueError):
    """The input cannot be exported; the message is one line."""


# --- columns from the packet table ------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Column:
    """One output column: where it comes from (``field``), its name, the factor to its unit, and that unit."""

    name: str
    field: str
    scale: float
    unit: str
    doc: str = ""
    enum: type[IntEnum] | None = None


def column_name(field: str, unit: str) -> str:
    suffix = UNIT_SUFFIX.get(unit)
    return f"{field}_{suffix}" if suffix else field


def _enum_of(unit: str) -> type[IntEnum] | None:
    cls = getattr(protocol, unit, None) if unit.isidentifier() else None
    if isinstance(cls, type) and issubclass(cls, IntEnum) and not issubclass(cls, IntFlag):
        return cls
    return None


def field_column(fs: FieldSpec, board_units: bool = False) -> Column:
    if board_units:
        return Column(fs.name, fs.name, 1.0, fs.unit, fs.doc, _enum_of(fs.unit))
    unit = fs.scaled_unit or fs.unit
    return Column(column_name(fs.name, unit), fs.name, fs.scale, unit, fs.doc, _enum_of(fs.unit))


def packet_columns(spec: PacketSpec, board_units: bool = False) -> list[Column]:
    return [field_column(fs, board_units) for fs in spec.fields]


def _value(raw: Any, scale: float) -> Any:
    if isinstance(raw, bytes):
        return raw.hex()
    if scale == 1.0:
        return raw if not isinstance(raw, float) or math.isfinite(raw) else None
    v = round(raw * scale, DIGITS)
    return v if math.isfinite(v) else None


def _enum_name(enum: type[IntEnum], raw: int) -> str:
    try:
        return enum(raw).name
    except ValueError:
        return str(raw)


def packet_record(pkt: Any, columns: list[Column]) -> dict[str, Any]:
    """``pkt`` as a dict of column name to value (scaled), enumerations named beside their number."""
    out: dict[str, Any] = {}
    for col in columns:
        raw = getattr(pkt, col.field)
        out[col.name] = _value(raw, col.scale)
        if col.enum is not None:
            out[f"{col.name}_name"] = _enum_name(col.enum, raw)
    return out


def json_schema(spec: PacketSpec) -> dict[str, Any]:
    """The JSON schema of a packet's exported messages, generated from its table entry."""
    props: dict[str, Any] = {}
    for fs, col in zip(spec.fields, packet_columns(spec), strict=True):
        kind = "string" if fs.fmt.endswith("s") else "integer" if col.scale == 1.0 and fs.fmt != "e" else "number"
        desc = f"{fs.doc} ({col.unit})" if fs.doc and col.unit else fs.doc or col.unit
        props[col.name] = {"type": kind, "description": desc}
        if col.enum is not None:
            props[f"{col.name}_name"] = {"type": "string", "enum": [m.name for m in col.enum],
                                         "description": f"{col.enum.__name__} of {col.name}"}
    return {"$schema": "http://json-schema.org/draft-07/schema#", "title": f"quadrupel.{spec.cls.__name__}",
            "description": f"{spec.doc} Direction: {spec.direction}. Rate: {spec.rate}.",
            "type": "object", "properties": props}


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
                dec = decoders[key] = Decoder()
            for pkt in dec.feed(item.data):
                yield DecodedFrame(item.t_ns, item.link, item.direction, pkt)
        else:
            yield item


def kind_of(path: Path) -> str:
    """"session" (an MCAP recording) or "flashlog" (a CSV from the log download); ExportError otherwise."""
    try:
        with path.open("rb") as f:
            head = f.read(256)
    except FileNotFoundError:
        raise ExportError(f"{path} not found") from None
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
    for part in session_parts(path) if path.parent.exists() else [path]:
        rec = Recording(part)
        info.append(rec)
        try:
            yield from iter_file(part, rec)
        except RecordingError as exc:
            raise ExportError(str(exc)) from None


def read_flash_csv(path: Path) -> tuple[list[str], list[list[float]]]:
    """The header and rows of a downloaded flash log (board units); a repeated header (a new segment) is skipped."""
    try:
        with path.open(newline="", encoding="utf-8") as f:
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


def export(src: Path, out: Path, fmt: str | None = None, board_units: bool = False) -> ExportResult:
    """Convert ``src`` (a session recording or a flash-log CSV) to ``out`` in ``fmt`` (from the suffix if None)."""
    fmt = fmt or out.suffix.lstrip(".").lower()
    if fmt not in FORMATS:
        raise ExportError(f"unknown format {fmt!r}: use -f mcap or -f csv (or an -o ending in .mcap or .csv)")
    if board_units and fmt != "csv":
        raise ExportError("--board-units is for CSV; MCAP carries the raw bytes beside the converted values")
    kind = kind_of(src)
    if out.exists() and out.resolve() == src.resolve():
        raise ExportError(f"{out} is the input: choose another output")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        if fmt == "csv":
            f = out.open("w", newline="", encoding="utf-8")
        else:
            f = out.open("wb")
    except OSError as exc:
        raise ExportError(f"cannot write {out}: {exc.strerror or exc}") from None
    try:
        with f:
            if kind == "session":
                info: list[Recording] = []
                n = _session_csv(src, f, board_units, info) if fmt == "csv" else _session_mcap(src, f, info)
                return ExportResult(kind, n, all(r.complete for r in info))
            header, rows = read_flash_csv(src)
            n = _flash_csv(header, rows, f, board_units) if fmt == "csv" else _flash_mcap(src, header, rows, f)
            return ExportResult(kind, n)
    except OSError as exc:
        raise ExportError(f"cannot write {out}: {exc.strerror or exc}") from None


def _session_csv(src: Path, f: Any, board_units: bool, info: list[Recording]) -> int:
    present: dict[int, PacketSpec] = {}
    for item in decode(_session_items(src, [])):  # first pass: which packet types are there
        if type(item) is DecodedFrame:
            spec = SPEC_OF[type(item.packet)]
            present.setdefault(spec.type_id, spec)
    columns: dict[int, list[Column]] = {}
    names: list[str] = []
    for type_id in sorted(present):
        columns[type_id] = cols = packet_columns(present[type_id], board_units)
        for c in cols:
            for name in (c.name, f"{c.name}_name") if c.enum is not None else (c.name,):
                if name not in names:
                    names.append(name)
    header = ["t_s", "link", "dir", "packet", *names, "level", "source", "message"]
    index = {name: i for i, name in enumerate(header)}
    w = csv.writer(f)
    w.writerow(header)
    start: int | None = None
    n = 0
    for item in decode(_session_items(src, info)):
        if start is None:
            start = info[0].start_ns if info[0].meta else item.t_ns
        row: list[Any] = [""] * len(header)
        row[0] = f"{(item.t_ns - start) / 1e9:.6f}"
        if type(item) is DecodedFrame:
            spec = SPEC_OF[type(item.packet)]
            row[1], row[2], row[3] = item.link, item.direction, spec.cls.__name__
            for k, v in packet_record(item.packet, columns[spec.type_id]).items():
                row[index[k]] = "" if v is None else v
        elif type(item) is not LoggedEvent:
            continue  # the station's own records are for a replay, not a table
        else:
            row[3] = "log"
            row[-3:] = [item.severity, item.source, item.text]
        w.writerow(row)
        n += 1
    return n


def _session_mcap(src: Path, f: Any, info: list[Recording]) -> int:
    w = Writer(f, compression=CompressionType.ZSTD)
    w.start("", "quadrupel term export")
    schemas: dict[int, int] = {}
    channels: dict[str, int] = {}
    columns: dict[int, list[Column]] = {}
    seq: dict[int, int] = {}
    n = 0
    meta_written = False

    def channel(topic: str, encoding: str, schema: int) -> int:
        ch = channels.get(topic)
        if ch is None:
            ch = channels[topic] = w.register_channel(topic, encoding, schema)
            seq[ch] = 0
        return ch

    def add(ch: int, t_ns: int, data: bytes) -> None:
        seq[ch] += 1
        w.add_message(ch, log_time=t_ns, data=data, publish_time=t_ns, sequence=seq[ch])

    log_schema = 0
    for item in decode(_session_items(src, info), keep_raw=True):
        if not meta_written and info[0].meta:
            w.add_metadata("session", dict(info[0].meta, exported_from=src.name))
            meta_written = True
        kind = type(item)
        if kind is DecodedFrame:
            spec = SPEC_OF[type(item.packet)]
            sid = schemas.get(spec.type_id)
            if sid is None:
                sid = schemas[spec.type_id] = w.register_schema(
                    f"quadrupel.{spec.cls.__name__}", "jsonschema", json.dumps(json_schema(spec)).encode())
                columns[spec.type_id] = packet_columns(spec)
            ch = channel(f"/{item.link}/{item.direction}/{spec.cls.__name__}", "json", sid)
            add(ch, item.t_ns, json.dumps(packet_record(item.packet, columns[spec.type_id])).encode())
        elif kind is LinkBytes:
            add(channel(f"/{item.link}/{item.direction}", RAW_ENCODING, 0), item.t_ns, item.data)
        elif kind is StationRecord:  # kept as recorded, so the exported file replays as the session did
            add(channel("/station", "json", 0), item.t_ns, json.dumps(item.data, ensure_ascii=False).encode())
            continue
        else:
            if not log_schema:
                log_schema = w.register_schema("foxglove.Log", "jsonschema", json.dumps(LOG_SCHEMA).encode())
            t = item.t_ns
            msg = {"timestamp": {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000},
                   "level": LEVEL_OF.get(item.severity, 2), "message": item.text, "name": item.source,
                   "file": "", "line": 0}
            add(channel("/events", "json", log_schema), t, json.dumps(msg, ensure_ascii=False).encode())
        n += kind is not LinkBytes  # frames and events, as the CSV counts its rows
    w.finish()
    return n


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
