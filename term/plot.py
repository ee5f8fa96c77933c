"""`term plot LOG.csv -o out.png`: the logged signals, drawn with matplotlib (Agg, no display needed).

Columns in board units (as the log download writes them) are converted for reading: time in s, angles in °,
rates in °/s, accelerations in g, height in m, battery in V. Groups that share a unit share a panel.

The input is checked as it is read (``read_log``): a CSV that is not a flight log (no ``t_us`` and logged
variables), a row of another length than the header, a field that is no finite number in its column's range
(nan, inf, a mode of 3.5), broken quoting or bad UTF-8 is a ``PlotError`` of one line naming the file, line and
column. The output must name an image (.png, .svg, .pdf) in a folder that exists; it is written as named.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TextIO

from term.protocol import LOG_TIME_COLUMN, column_scale
from term.schema import Number, one_line, shown

# Panels: columns that share a unit share one. Scales and units come from the packet table (the log's columns are
# named after telemetry fields, in the same board units): term.protocol.column_scale.
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


# The flight-log CSV, as the log download writes it (term/logfile.py): a header naming the columns, then one
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
        with path.open(newline="", encoding="utf-8-sig") as f:
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


def plot_log(path: Path, output: Path, signals: Sequence[str] | None = None) -> Path:
    """Draw the log at ``path`` to ``output`` (the very file named); returns it."""
    check_output(output)
    cols = read_log(path)
    t = [v * column_scale(TIME_COLUMN)[0] for v in cols[TIME_COLUMN]]
    xlabel = "board time (s)"
    if not t:
        raise PlotError(f"{path} has a header but no records")
    if signals:
        unknown = [s for s in signals if s not in cols]
        if unknown:
            raise PlotError(f"no column {unknown[0]!r} in {path}; columns: {', '.join(cols)}")
        panels = [(s, "", ((s, 1.0),)) for s in signals]
    else:
        panels = [g for g in GROUPS if any(c in cols for c, _ in g[2])]
        known = {c for g in GROUPS for c, _ in g[2]} | {TIME_COLUMN, "segment"}
        panels += [(c, "", ((c, 1.0),)) for c in cols if c not in known]

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(11, 2.0 * len(panels) + 0.6), squeeze=False)
    for ax, (title, unit, series) in zip(axes[:, 0], panels, strict=True):
        for col, scale in series:
            if col in cols:
                ax.plot(t, [v * scale for v in cols[col]], label=col, linewidth=0.9)
        ax.set_ylabel(f"{title}\n({unit})" if unit else title)
        if title == "mode" and "mode" in cols:
            from term.protocol import Mode

            present = sorted({int(v) for v in cols["mode"]} & {int(m) for m in Mode})
            ax.set_yticks(present, [Mode(v).name for v in present])
        ax.grid(True, alpha=0.3)
        if len(series) > 1:
            ax.legend(loc="upper right", fontsize="small", ncol=len(series))
    axes[-1, 0].set_xlabel(xlabel)
    fig.suptitle(f"{path.name}: {len(t)} records")
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
