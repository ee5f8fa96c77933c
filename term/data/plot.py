"""`term plot SOURCE -o out.png`: a flight drawn with matplotlib (Agg, no display needed), from a session recording
or a downloaded flash log alike.

- SOURCE is a session recording (MCAP: what ``term`` records of every session, or a ``term export`` MCAP) or the
  flash-log CSV of a download. A recording is decoded as ``term export`` decodes it (term/data/export.py: the bytes
  each link brought, with today's codec); its time is seconds since the session started. A flash log's is the
  board's time since boot.
- Both are drawn in the same SI units from the packet table (``term.core.protocol``: each field's ``scale`` and
  ``scaled_unit``, the units of ``term export``'s CSV): time in s, angles in °, rates in °/s, accelerations in g,
  height in m, battery in V. Series that share a unit share a panel (``PANELS``). A field a recording got over
  more than one link is drawn once per link, labelled with it.
- ``signals`` chooses the series by field name (``phi``) or by ``term export``'s column name (``phi_deg``), one
  panel each; ``start``/``end`` (s, on the x axis) choose the time window.

The flash-log CSV is checked as it is read (``read_log``): a CSV that is not a flight log (no ``t_us`` and logged
variables), a row of another length than the header, a field that is no finite number in its column's range
(nan, inf, a mode of 3.5), broken quoting or bad UTF-8 is a ``PlotError`` of one line naming the file, line and
column. A recording that cannot be read, a series that is not there, a window with nothing in it are one line too.
The output must name an image (.png, .svg, .pdf) in a folder that exists; it is written as named.
"""

from __future__ import annotations

import csv
import io
import math
import os
from array import array
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from term.core.protocol import LOG_TIME_COLUMN, column_scale
from term.core.schema import Number, one_line, shown
from term.core.userfile import LOG_MAX_BYTES, RECORDING_MAX_BYTES, UserFileError, open_user_file

# Panels: columns that share a unit share one. Scales and units come from the packet table (the log's columns are
# named after telemetry fields, in the same board units): term.core.protocol.column_scale.
PANELS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("attitude", ("phi", "theta", "psi")),
    ("body rates", ("sp", "sq", "sr")),
    ("accelerations", ("sax", "say", "saz")),
    ("motors", ("ae1", "ae2", "ae3", "ae4")),
    ("height", ("height",)),
    ("pressure", ("pressure",)),
    ("battery", ("battery",)),
    ("mode", ("mode",)),
)

NO_MATPLOTLIB = ("term plot needs matplotlib, which the default install leaves out: pip install 'quadrupel[plot]' "
                 "(in a clone: .venv/bin/pip install -e '.[plot]')")


def _scale(column: str) -> tuple[float, str]:
    try:
        return column_scale(column)
    except KeyError:  # a column the packet table does not know: drawn as it is
        return 1.0, ""


# (title, unit, [(column, scale to the unit)]) per panel; the mode panel is labelled with mode names instead.
GROUPS: tuple[tuple[str, str, tuple[tuple[str, float], ...]], ...] = tuple(
    (title, "" if title == "mode" else _scale(cols[0])[1], tuple((c, _scale(c)[0]) for c in cols))
    for title, cols in PANELS
)


class PlotError(ValueError):
    """The log cannot be drawn; the message is one line."""


# The flight-log CSV, as the log download writes it (term/core/logfile.py): a header naming the columns, then one
# record per row, every field a finite number in board units. Checked as it is read, column by column.
TIME_COLUMN = LOG_TIME_COLUMN  # board time, µs: a flight log always has it
INT32 = 2**32  # board values are at most 32-bit (the log's absolute records are int32, its time uint32)
COLUMNS: dict[str, Number] = {
    "segment": Number(0, 65535, integer=True),
    TIME_COLUMN: Number(0, INT32 - 1, integer=True),
    "mode": Number(0, 255, integer=True),
}
ANY_COLUMN = Number(-INT32, INT32)
FIELD_MAX = 32  # characters: a longer field is no number the board logs (csv's own limit is 131 072)
LINE_MAX = 4096  # characters of a row: COLUMNS_MAX fields of FIELD_MAX, three times over
COLUMNS_MAX = 40  # the board logs 18 variables; each column not in GROUPS gets a panel of its own
IMAGE_TYPES = (".png", ".svg", ".pdf")


def _parse(text: str) -> float:
    if len(text) > FIELD_MAX:
        raise ValueError
    try:
        return int(text)
    except ValueError:
        return float(text)


def read_log(path: Path) -> dict[str, list[float]]:
    """The columns of a flight-log CSV; anything that is not one (another CSV, a raw hex dump, a row of another
    length, a field that is no finite number in range, broken quoting, bad UTF-8) is a ``PlotError``: one line
    naming the file, the line and the column."""
    try:
        with io.TextIOWrapper(open_user_file(path, LOG_MAX_BYTES, "flight log"), encoding="utf-8-sig",
                              newline="") as f:
            reader = csv.reader(_lines(f, path), strict=True)
            try:
                header = next(reader, None)
                if not header:
                    raise PlotError(f"{path} is empty")
                _check_header(path, header)
                cols: dict[str, list[float]] = {h: [] for h in header}
                specs = [COLUMNS.get(h, ANY_COLUMN) for h in header]
                for row in reader:
                    if not row or row == header:
                        continue  # a blank line; a repeated header (a new segment)
                    if len(row) != len(header):
                        raise PlotError(f"{path} line {reader.line_num}: {len(row)} fields, the header has "
                                        f"{len(header)}: not a flight log")
                    for h, spec, text, col in zip(header, specs, row, cols.values(), strict=True):
                        col.append(_value(path, reader.line_num, h, spec, text))
            except csv.Error as exc:
                raise PlotError(f"{path} line {reader.line_num}: not a readable CSV ({one_line(str(exc))})") from None
    except FileNotFoundError:
        raise PlotError(f"{path} not found") from None
    except UserFileError as exc:
        raise PlotError(str(exc) if os.path.lexists(path) else f"{path} not found") from None
    except UnicodeDecodeError as exc:
        raise PlotError(f"{path} is not UTF-8 text (byte {exc.object[exc.start]:#04x}): not a flight log") from None
    except OSError as exc:
        raise PlotError(f"cannot read {path}: {exc.strerror or exc}") from None
    return cols


def _lines(f: TextIO, path: Path) -> Iterator[str]:
    """The file's lines, none longer than LINE_MAX: a file without line ends (/dev/zero, a binary) is refused
    instead of read whole into memory."""
    n = 0
    while line := f.readline(LINE_MAX + 1):
        n += 1
        if len(line) > LINE_MAX:
            raise PlotError(f"{path} line {n} is longer than {LINE_MAX} characters: not a flight log")
        yield line


def _check_header(path: Path, header: list[str]) -> None:
    if "hex" in header and "offset" in header:
        raise PlotError(f"{path} holds raw log bytes (the board's format was not recognised), nothing to plot")
    known = {c for g in GROUPS for c, _ in g[2]}
    if TIME_COLUMN not in header or not known & set(header):
        raise PlotError(f"{path} is not a flight log: its header ({shown(','.join(header))}) needs {TIME_COLUMN} "
                        "and logged variables such as phi, ae1, height (write one with the log download, F5)")
    if len(header) > COLUMNS_MAX:
        raise PlotError(f"{path} has {len(header)} columns, a flight log at most {COLUMNS_MAX}")
    for i, h in enumerate(header):
        if not h or h in header[:i]:
            raise PlotError(f"{path} line 1: column {i + 1} is {'empty' if not h else f'{h!r} again'}")


def _value(path: Path, line: int, column: str, spec: Number, text: str) -> float:
    try:
        v = _parse(text)
        if not spec.lo <= v <= spec.hi or spec.integer and not isinstance(v, int):  # nan fails the comparison
            raise ValueError
        return v
    except ValueError:
        raise PlotError(f"{path} line {line}, column {column}: must be {spec.describe()}, got {shown(text)}") from None


def check_output(output: Path) -> None:
    """Refuse, before any work, an image path that cannot be written as asked: a folder, a name without an image
    type (matplotlib would add .png and write another file than the one named), a folder that does not exist."""
    if output.is_dir():
        raise PlotError(f"{output} is a folder: name the image, e.g. {output / 'flight.png'}")
    if output.suffix.lower() not in IMAGE_TYPES:
        raise PlotError(f"{output}: the name must end in {', '.join(IMAGE_TYPES)} (the type of image to write)")
    if not output.parent.is_dir():
        raise PlotError(f"cannot write {output}: folder {output.parent} does not exist")


@dataclass
class Trace:
    """One series to draw: its label, times (s) and values (in ``unit``)."""

    label: str
    unit: str
    t: array[float] = field(default_factory=lambda: array("d"))
    v: array[float] = field(default_factory=lambda: array("d"))


@dataclass
class Source:
    """What a recording or a flash log holds to draw: the traces of each field (one per link for a recording)."""

    kind: str  # "session" or "flashlog"
    xlabel: str
    traces: dict[str, list[Trace]]
    records: int


MCAP_MAGIC = b"\x89MCAP0\r\n"
SESSION_PACKETS = ("Attitude", "Motion", "Height", "Status", "Gains", "Compact", "Compact2",  # the board's figures
                   "Heartbeat")


def read_flash_log(path: Path) -> Source:
    cols = read_log(path)
    t = array("d", (v * column_scale(TIME_COLUMN)[0] for v in cols[TIME_COLUMN]))
    if not t:
        raise PlotError(f"{path} has a header but no records")
    traces = {}
    for name, values in cols.items():
        if name in (TIME_COLUMN, "segment"):
            continue
        scale, unit = _scale(name)
        traces[name] = [Trace(name, unit, t, array("d", (v * scale for v in values)))]
    return Source("flashlog", "board time (s)", traces, len(t))


def read_session(path: Path, progress: Any = None) -> Source:
    """The telemetry the board sent in the session ``path`` belongs to (every part), in SI units. ``progress``:
    told how far the reading is, as ``term export`` tells it (items read, items in the recording or None)."""
    from term.core.protocol import SPEC_OF
    from term.data.export import DecodedFrame, _counted, decode
    from term.data.recording import Recording, RecordingError, iter_file, session_parts

    per_link: dict[tuple[str, str], Trace] = {}
    fields: dict[type, list[tuple[str, float, str]]] = {}
    start: int | None = None
    n = 0

    def items() -> Iterator[Any]:
        nonlocal start
        for part in session_parts(path):
            rec = Recording(part)
            for item in iter_file(part, rec):
                if start is None:
                    start = rec.start_ns if rec.meta else item.t_ns
                yield item

    try:
        for item in decode(_counted(items(), path, progress)):
            if type(item) is not DecodedFrame or item.direction != "rx":
                continue
            kind = type(item.packet)
            spec = fields.get(kind)
            if spec is None:
                fs = SPEC_OF[kind].fields if kind.__name__ in SESSION_PACKETS else ()
                spec = fields[kind] = [(f.name, f.scale, f.scaled_unit) for f in fs]  # as column_scale
            if not spec:
                continue
            n += 1
            assert start is not None
            t = (item.t_ns - start) / 1e9
            for name, scale, unit in spec:
                tr = per_link.get((name, item.link))
                if tr is None:
                    tr = per_link[(name, item.link)] = Trace(name, unit)
                tr.t.append(t)
                tr.v.append(getattr(item.packet, name) * scale)
    except RecordingError as exc:
        raise PlotError(str(exc)) from None
    if not n:
        from term.data.recording import NOT_REPLAYABLE, decoded_only

        if decoded_only(path):
            raise PlotError(f"{path} {NOT_REPLAYABLE}")
        raise PlotError(f"{path} holds no telemetry from the board (a session without a link up?)")
    traces: dict[str, list[Trace]] = {}
    for (name, _link), tr in per_link.items():
        traces.setdefault(name, []).append(tr)
    for (name, link), tr in per_link.items():
        if len(traces[name]) > 1:  # the cable and the radio both brought it: one line each, named
            tr.label = f"{name} ({link})"
    return Source("session", "time since the session started (s)", traces, n)


def read_source(path: Path, progress: Any = None) -> Source:
    """A session recording (MCAP) or a flash-log CSV, told apart by the MCAP header (or a .mcap name)."""
    if not os.path.lexists(path):
        raise PlotError(f"{path} not found")
    try:
        with open_user_file(path, RECORDING_MAX_BYTES, "recording or log") as f:  # a FIFO or device: one line
            head = f.read(len(MCAP_MAGIC))
    except UserFileError as exc:
        raise PlotError(str(exc)) from None
    except OSError as exc:
        raise PlotError(f"cannot read {path}: {exc.strerror or exc}") from None
    if head == MCAP_MAGIC or path.suffix.lower() == ".mcap":
        return read_session(path, progress)
    if _is_export_csv(path):
        return read_export_csv(path)
    return read_flash_log(path)


EXPORT_HEAD = ("t_s", "utc", "link", "dir", "packet")  # a session exported by `term export -o x.csv` begins so


def _is_export_csv(path: Path) -> bool:
    try:
        with open_user_file(path, LOG_MAX_BYTES, "flight log") as f:
            first = f.read(LINE_MAX).split(b"\n", 1)[0].decode("utf-8-sig", "replace").strip()
    except (UserFileError, OSError):
        return False
    return tuple(first.split(",")[: len(EXPORT_HEAD)]) == EXPORT_HEAD


def read_export_csv(path: Path) -> Source:
    """``term export``'s own CSV of a session (issue 34: ``term plot`` refused it): the board's telemetry rows
    (``dir`` rx, the SESSION_PACKETS), their SI columns drawn as a recording's are, one trace per link."""
    units = _export_units()
    per_link: dict[tuple[str, str], Trace] = {}
    n = 0
    try:
        with io.TextIOWrapper(open_user_file(path, LOG_MAX_BYTES, "exported session"), encoding="utf-8-sig",
                              newline="") as f:
            reader = csv.reader(_lines(f, path), strict=True)
            header = next(reader, None) or []
            index = {h: i for i, h in enumerate(header)}
            cols = [(i, h, *units[h]) for i, h in enumerate(header) if h in units]
            for row in reader:
                if len(row) != len(header):
                    raise PlotError(f"{path} line {reader.line_num}: {len(row)} fields, the header has "
                                    f"{len(header)}")
                if row[index["dir"]] != "rx" or row[index["packet"]] not in SESSION_PACKETS:
                    continue
                t = _value(path, reader.line_num, "t_s", Number(0, 1e9), row[index["t_s"]])
                link = row[index["link"]]
                got = False
                for i, h, name, unit in cols:
                    if not row[i]:
                        continue  # another packet's column
                    v = _value(path, reader.line_num, h, Number(-1e12, 1e12), row[i])
                    tr = per_link.get((name, link))
                    if tr is None:
                        tr = per_link[(name, link)] = Trace(name, unit)
                    tr.t.append(t)
                    tr.v.append(v)
                    got = True
                n += got
    except csv.Error as exc:
        raise PlotError(f"{path}: not a readable CSV ({one_line(str(exc))})") from None
    except UserFileError as exc:
        raise PlotError(str(exc)) from None
    except UnicodeDecodeError:
        raise PlotError(f"{path} is not UTF-8 text") from None
    except OSError as exc:
        raise PlotError(f"cannot read {path}: {exc.strerror or exc}") from None
    if not n:
        raise PlotError(f"{path} holds no telemetry from the board (exported with --board-units? plot takes SI)")
    traces: dict[str, list[Trace]] = {}
    for (name, _link), tr in per_link.items():
        traces.setdefault(name, []).append(tr)
    for (name, link), tr in per_link.items():
        if len(traces[name]) > 1:
            tr.label = f"{name} ({link})"
    return Source("session", "time since the session started (s)", traces, n)


def _export_units() -> dict[str, tuple[str, str]]:
    """``term export``'s SI column names of the board's telemetry (phi_deg) to (field name, unit)."""
    from term.core.protocol import SPEC_OF
    from term.data.export import column_name

    out: dict[str, tuple[str, str]] = {}
    for kind, spec in SPEC_OF.items():
        if kind.__name__ not in SESSION_PACKETS:
            continue
        for f in spec.fields:
            out.setdefault(column_name(f.name, f.scaled_unit or f.unit), (f.name, f.scaled_unit or f.unit))
    return out


def _export_names() -> dict[str, str]:
    """``term export``'s SI column names (phi_deg) to field names (phi)."""
    from term.core.protocol import SPEC_OF
    from term.data.export import column_name

    out: dict[str, str] = {}
    for spec in SPEC_OF.values():
        for f in spec.fields:
            out.setdefault(column_name(f.name, f.scaled_unit or f.unit), f.name)
    return out


def _window(tr: Trace, start: float, end: float) -> Trace:
    if start == -math.inf and end == math.inf:
        return tr
    keep = [i for i, t in enumerate(tr.t) if start <= t <= end]
    return Trace(tr.label, tr.unit, array("d", (tr.t[i] for i in keep)), array("d", (tr.v[i] for i in keep)))


Panel = tuple[str, str, list[Trace]]  # title, unit, traces


def window(start: float | None, end: float | None) -> tuple[float, float]:
    """The time window (s) asked for, open where not given; PlotError for nan, inf or an empty one."""
    for name, v in (("--from", start), ("--to", end)):
        if v is not None and not math.isfinite(v):
            raise PlotError(f"{name} must be a finite number of seconds, got {v}")
    lo = -math.inf if start is None else start
    hi = math.inf if end is None else end
    if not lo < hi:
        raise PlotError(f"the window is empty: --from {lo:g} s is not before --to {hi:g} s")
    return lo, hi


def panels_of(src: Source, path: Path, signals: Sequence[str] | None = None, start: float | None = None,
              end: float | None = None) -> list[Panel]:
    """The panels to draw of ``src``: the chosen ``signals`` (field or export column names), one panel each, or
    every panel present; each trace cut to the window ``start``..``end`` (s). PlotError if there is nothing."""
    lo, hi = window(start, end)
    traces = src.traces
    if signals:
        names = _export_names()
        wanted = [x.strip() for x in signals]
        chosen = [s if s in traces else names.get(s, s) for s in wanted]
        unknown = [s for s, c in zip(wanted, chosen, strict=True) if c not in traces]
        if unknown:
            raise PlotError(f"no column {unknown[0]!r} in {path}; columns: {', '.join(traces)}")
        panels = [(c, traces[c][0].unit, (c,)) for c in chosen]
    else:
        panels = [(title, unit, tuple(c for c, _ in cols)) for title, unit, cols in GROUPS
                  if any(c in traces for c, _ in cols)]
        if src.kind == "flashlog":  # a log's other columns (the board may log more than we know)
            known = {c for g in GROUPS for c, _ in g[2]}
            panels += [(c, traces[c][0].unit, (c,)) for c in traces if c not in known]
    drawn = [(title, unit, [_window(tr, lo, hi) for c in cols for tr in traces.get(c, ())])
             for title, unit, cols in panels]
    if not any(tr.t for _, _, trs in drawn for tr in trs):
        spans = [tr.t for trs in traces.values() for tr in trs if tr.t]
        first = min((t[0] for t in spans), default=0.0)
        last = max((t[-1] for t in spans), default=0.0)
        raise PlotError(f"{path} has nothing between {lo:g} s and {hi:g} s (it spans {first:.1f} to {last:.1f} s)")
    return drawn


def plot_log(path: Path, output: Path, signals: Sequence[str] | None = None, start: float | None = None,
             end: float | None = None, progress: Any = None) -> Path:
    """Draw the recording or flash log at ``path`` to ``output`` (the very file named); returns it. ``signals``:
    the series to draw (field or export column names; default: every panel present); ``start``, ``end``: the
    window on the x axis (s); ``progress``: told how far the reading of a recording is."""
    try:  # first: the one thing a default install lacks (matplotlib is the plot extra's, issue 25)
        import matplotlib
    except ImportError:
        raise PlotError(NO_MATPLOTLIB) from None
    check_output(output)
    window(start, end)  # before reading a file that may be large
    src = read_source(path, progress)
    drawn = panels_of(src, path, signals, start, end)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(drawn), 1, sharex=True, figsize=(11, 2.0 * len(drawn) + 0.6), squeeze=False)
    for ax, (title, unit, trs) in zip(axes[:, 0], drawn, strict=True):
        for tr in trs:
            ax.plot(tr.t, tr.v, label=tr.label, linewidth=0.9)
        ax.set_ylabel(f"{title}\n({unit})" if unit and title != "mode" else title)
        if title == "mode":
            from term.core.protocol import Mode

            present = sorted({int(v) for tr in trs for v in tr.v} & {int(m) for m in Mode})
            ax.set_yticks(present, [Mode(v).name for v in present])
        ax.grid(True, alpha=0.3)
        if len(trs) > 1:
            ax.legend(loc="upper right", fontsize="small", ncol=len(trs))
    axes[-1, 0].set_xlabel(src.xlabel)
    if start is not None or end is not None:
        axes[-1, 0].set_xlim(None if start is None else start, None if end is None else end)
    what = "records" if src.kind == "flashlog" else "telemetry frames"
    fig.suptitle(f"{path.name}: {src.records} {what}")
    fig.tight_layout()
    try:
        fig.savefig(output, dpi=110, format=output.suffix[1:].lower())
    except OSError as exc:
        raise PlotError(f"cannot write {output}: {exc.strerror or exc}") from None
    except ValueError as exc:  # matplotlib's own refusals (an image too large, ...)
        raise PlotError(one_line(f"cannot draw {output}: {exc}")) from None
    finally:
        plt.close(fig)
    return output
