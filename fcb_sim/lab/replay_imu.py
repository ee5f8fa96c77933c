"""`fcb-sim replay-imu`: run an attitude filter over recorded IMU data (CSV or CSV.gz).

Three inputs, told apart by their header:

- IMU CSV: a header naming at least ``t`` (s), ``gx gy gz`` (rad/s) and ``ax ay az`` (m/s², specific force, chip
  frame z up); other columns are ignored (the BROAD trials of ../shared/data/broad are such files).
- The board's flash log as ``term`` writes it after a download (docs/flash_log.md): ``t_us`` and the IMU words
  the board logs every control period, ``sp sq sr`` (calibrated body rates, gyro LSB) and ``sax say saz``
  (calibrated body accelerations, accelerometer LSB), in the firmware's FRD body frame. They are turned back
  into the chip frame the filters take (docs/architecture.md: ``gx = sp, gy = -sq, gz = -sr``,
  ``ax = sax, ay = -say, az = -saz``) and into SI units (16.4 LSB per °/s, 16384 LSB per g). A new ``segment``
  (another recording in the same log) restarts the filter. The log's own angles (``phi theta psi``) are what
  the board's filter said in flight: a replay through the same filter reproduces them (tests do).
- ``term export``'s CSV in SI units (docs/recording.md), of a flash log or of a session recording: ``t_s``,
  ``sp_dps sq_dps sr_dps`` (°/s) and ``sax_g say_g saz_g`` (g), the same FRD words scaled by the packet table
  (``term.core.protocol.column_scale``), so they are turned back the same way. A session's rows are one per packet:
  each Attitude row (the rates) is a sample with the accelerations of the Motion row the board sent after it (the
  one before, if that was lost), from the first link that brought them, ``dir`` rx only. Its times are when the
  frames were read, so two frames read together share one (the second is moved 1 µs on: their intervals still
  add up). A silence (the link lost) is one long step: the filter keeps its attitude across it (restarting
  there, from the accelerometer of a quad in flight, was 28° off against 6° in the test of it).
  A session recording itself (MCAP) is refused with the command that exports it: fcb_sim imports nothing of
  ``term`` but its protocol, and the recording's reader (chunks, a file cut short by a crash, the link bytes decoded
  with the codec of the day) lives once, in term.data.recording and term.data.export; their CSV is what both programs
  share.

Any sample rate (dt from the time column, strictly increasing). The first row, and the first of each segment,
has no previous time: its dt is the next interval. Output: one row per sample with ``t, roll, pitch, yaw``
(rad) and ``qw, qx, qy, qz`` (body-to-earth, earth z up). A malformed file ends in one clear line (exit 2), and
before anything is written: the input is opened and its header and first sample checked first. A line longer
than ``LINE_MAX`` (``/dev/zero``, a binary file) is refused, not read whole into memory.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import io
import itertools
import math
import sys
import time
from collections.abc import Iterator
from typing import IO

from fcb_sim.errors import UsageError
from fcb_sim.estimation import BEST, DESCRIPTIONS, FILTERS, has_fixed_point, make_filter
from fcb_sim.world import constants as P
from term.core.protocol import column_scale

REQUIRED = ("t", "gx", "gy", "gz", "ax", "ay", "az")
FLASH_LOG = ("t_us", "sp", "sq", "sr", "sax", "say", "saz")  # the board's flash log (term's CSV of a download)
_G = 1.0 / P.RATE_LSB_PER_RAD_S
_A = 1.0 / P.ACC_LSB_PER_MS2
# chip-frame SI sample from the logged FRD words: (t, gx, gy, gz, ax, ay, az)
_FROM_LOG = (1e-6, _G, -_G, -_G, _A, -_A, -_A)
Sample = tuple[float, float, float, float, float, float, float]
# term export's SI columns (term/data/export.py names them from the packet table; a test checks they agree)
EXPORT = ("t_s", "sp_dps", "sq_dps", "sr_dps", "sax_g", "say_g", "saz_g")
_FROM_EXPORT = (1.0, *(k / column_scale(f)[0] for f, k in zip(FLASH_LOG[1:], _FROM_LOG[1:], strict=True)))
LINE_MAX = 65536  # characters of a CSV line; an IMU row has a few hundred
MCAP_MAGIC = b"\x89MCAP0\r\n"
_PROGRESS_EVERY = 100_000  # rows; progress only when stderr is a terminal


def _open_text(path: str) -> IO[str]:
    try:
        if path.endswith(".gz"):
            fh: IO[str] = gzip.open(path, "rt", newline="", encoding="utf-8")
            fh.read(0)
            return fh
        raw = open(path, "rb")
        if raw.peek(len(MCAP_MAGIC)).startswith(MCAP_MAGIC):
            raw.close()
            raise UsageError(f"{path}: a session recording (MCAP); replay-imu reads its CSV export: "
                             f"term export {path} -o imu.csv, then replay-imu imu.csv")
        return io.TextIOWrapper(raw, encoding="utf-8", newline="")
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UsageError(f"{path}: is a directory, not a CSV file") from None
    except OSError as exc:
        raise UsageError(f"{path}: cannot read ({exc.strerror or exc})") from None


def read_imu(path: str) -> Iterator[tuple[Sample, bool]]:
    """Yield ((t, gx, gy, gz, ax, ay, az), restart) in SI units and the chip frame, from either input (module
    docstring); ``restart`` is True on the first row of a new flash-log segment. Bad input is a UsageError
    naming the line."""
    fh = _open_text(path)
    with fh:
        try:
            reader = csv.reader(_lines(fh, path))
            header = next(reader, None)
            if header is None:
                raise UsageError(f"{path}: empty file; expected a CSV header with {', '.join(REQUIRED)}")
            names = [h.strip() for h in header]
            log = all(c in names for c in FLASH_LOG)
            if not log and all(c in names for c in EXPORT):
                yield from _read_export(path, reader, names)
                return
            cols = FLASH_LOG if log else REQUIRED
            missing = [c for c in REQUIRED if c not in names]
            if missing and not log:
                raise UsageError(
                    f"{path}: missing column(s) {', '.join(missing)}; the header needs {', '.join(REQUIRED)} "
                    f"(or, for the board's flash log, {', '.join(FLASH_LOG)}; for term export's CSV, "
                    f"{', '.join(EXPORT)})"
                )
            idx = [names.index(c) for c in cols]
            seg = names.index("segment") if log and "segment" in names else None
            scale = _FROM_LOG if log else (1.0,) * 7
            last_t = -math.inf
            last_seg: str | None = None
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue  # blank line
                if [c.strip() for c in row] == names:
                    continue  # the header again (a log's next segment written by another tool)
                line = reader.line_num
                try:
                    vals = tuple(float(row[i]) * k for i, k in zip(idx, scale, strict=True))
                except IndexError:
                    raise UsageError(f"{path}:{line}: too few fields ({len(row)} for {len(names)} columns)") from None
                except ValueError:
                    col, i = next((c, i) for c, i in zip(cols, idx, strict=True) if not _is_float(row[i]))
                    raise UsageError(f"{path}:{line}: column {col} is not a number: {row[i]!r}") from None
                if not all(math.isfinite(v) for v in vals):
                    raise UsageError(f"{path}:{line}: non-finite value (nan or inf)")
                restart = False
                if seg is not None and row[seg] != last_seg:
                    restart, last_seg, last_t = last_seg is not None, row[seg], -math.inf
                if vals[0] <= last_t:
                    raise UsageError(f"{path}:{line}: time {cols[0]}={row[idx[0]]} does not increase")
                last_t = vals[0]
                yield vals, restart  # type: ignore[misc]
        except (UnicodeDecodeError, gzip.BadGzipFile, EOFError, csv.Error, OSError) as exc:
            raise UsageError(f"{path}: not a readable CSV file ({exc.__class__.__name__}: {exc})") from None


def _lines(fh: IO[str], path: str) -> Iterator[str]:
    """The file's lines, none longer than LINE_MAX: a file without line ends is refused, not read into memory."""
    n = 0
    while line := fh.readline(LINE_MAX + 1):
        n += 1
        if len(line) > LINE_MAX:
            raise UsageError(f"{path}:{n}: a line longer than {LINE_MAX} characters: not a CSV of IMU data")
        yield line


def _read_export(path: str, reader: Iterator[list[str]], names: list[str]) -> Iterator[tuple[Sample, bool]]:
    """``term export``'s CSV (module docstring): a flash log's rows are whole samples; a session's Attitude row is
    one with the accelerations of the Motion row the board sent after it."""
    idx = [names.index(c) for c in EXPORT]
    where = {c: names.index(c) for c in ("segment", "link", "dir") if c in names}
    session = "packet" in names
    link: str | None = None
    accel: list[float] | None = None
    pending: tuple[float, list[float], int] | None = None  # an Attitude's time, rates and line
    last_t = -math.inf
    last_seg: str | None = None
    segment = ""

    def sample(t: float, gyro: list[float], acc: list[float], line: int) -> tuple[Sample, bool]:
        nonlocal last_t, last_seg
        restart = False
        if "segment" in where and segment != last_seg:
            restart, last_seg, last_t = last_seg is not None, segment, -math.inf
        if t <= last_t:
            if not session:
                raise UsageError(f"{path}:{line}: time t_s={t:g} does not increase")
            t = last_t + 1e-6  # frames read together share their read's time
        last_t = t
        return (t, *gyro, *acc), restart  # type: ignore[return-value]

    for row in reader:
        if not row or (len(row) == 1 and not row[0].strip()) or [c.strip() for c in row] == names:
            continue  # a blank line; the header again
        line = getattr(reader, "line_num", 0)
        if len(row) != len(names):
            raise UsageError(f"{path}:{line}: {len(row)} fields for {len(names)} columns")
        if "dir" in where and row[where["dir"]] != "rx":
            continue  # what the terminal sent
        has_g = all(row[i] for i in idx[1:4])
        has_a = all(row[i] for i in idx[4:])
        if not (has_g or has_a):
            continue  # another packet's row, or an event
        if "link" in where:
            link = link or row[where["link"]]
            if row[where["link"]] != link:
                continue  # the same board seen over the other link
        vals = _export_values(path, line, row, names, idx)
        if "segment" in where:
            segment = row[where["segment"]]
        if has_g and has_a:  # a flash log's record
            yield sample(vals[0], vals[1:4], vals[4:], line)
        elif has_g:  # an Attitude: it waits for its Motion
            if pending is not None and accel is not None:
                yield sample(pending[0], pending[1], accel, pending[2])  # its Motion lost: the last one stands in
            pending = (vals[0], vals[1:4], line)
        else:
            accel = vals[4:]
            if pending is not None:
                yield sample(pending[0], pending[1], accel, pending[2])
                pending = None
    if pending is not None and accel is not None:
        yield sample(pending[0], pending[1], accel, pending[2])


def _export_values(path: str, line: int, row: list[str], names: list[str], idx: list[int]) -> list[float]:
    """The row's EXPORT columns as a chip-frame SI sample (an empty cell reads 0.0); a bad number is one clear line."""
    try:
        vals = [float(row[i]) * k if row[i] else 0.0 for i, k in zip(idx, _FROM_EXPORT, strict=True)]
    except ValueError:
        col = next(c for c, i in zip(EXPORT, idx, strict=True) if row[i] and not _is_float(row[i]))
        raise UsageError(f"{path}:{line}: column {col} is not a number: {row[names.index(col)]!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise UsageError(f"{path}:{line}: non-finite value (nan or inf)")
    return vals


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def replay(path: str, out: IO[str], name: str = BEST, fixed_point: bool = False) -> int:
    """Run filter ``name`` over ``path`` and write the output CSV to ``out``; returns the number of rows."""
    filt = make_filter(name, fixed_point=fixed_point)
    read = read_imu(path)
    first = next(read, None)  # the file opened, its header and first sample checked before a byte is written
    if first is None:
        raise UsageError(f"{path}: no data rows")
    rows = itertools.chain((first,), read)
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["t", "roll", "pitch", "yaw", "qw", "qx", "qy", "qz"])
    progress = sys.stderr.isatty()
    n = 0
    t_start = time.monotonic()
    pending: list[Sample] = []  # a segment's first row waits for the second, whose interval it takes as its dt
    prev_t = 0.0

    def step(r: Sample) -> None:
        nonlocal prev_t, n
        t, gx, gy, gz, ax, ay, az = r
        filt.update(gx, gy, gz, ax, ay, az, t - prev_t)
        prev_t = t
        qw, qx, qy, qz = filt.quaternion()
        w.writerow((f"{t:.6f}", f"{filt.roll:.7f}", f"{filt.pitch:.7f}", f"{filt.yaw:.7f}",
                    f"{qw:.8f}", f"{qx:.8f}", f"{qy:.8f}", f"{qz:.8f}"))
        n += 1
        if progress and n % _PROGRESS_EVERY == 0:
            print(f"\r{n} rows, {n / max(time.monotonic() - t_start, 1e-9):.0f} rows/s", end="", file=sys.stderr)

    def flush_first(next_t: float | None) -> None:
        nonlocal prev_t
        first = pending.pop()
        # a lone row has no interval: assume the report's 400 Hz
        prev_t = first[0] - (next_t - first[0] if next_t is not None else 0.0025)
        step(first)

    for r, restart in rows:
        if restart:
            if pending:
                flush_first(None)
            filt.reset()
            pending.append(r)
        elif pending:
            flush_first(r[0])
            step(r)
        elif n == 0:
            pending.append(r)
        else:
            step(r)
    if pending:
        flush_first(None)
    if n == 0:
        raise UsageError(f"{path}: no data rows")
    if progress and n >= _PROGRESS_EVERY:
        print(file=sys.stderr)
    return n


def cmd_replay(args: argparse.Namespace) -> int:
    """The `fcb-sim replay-imu` subcommand."""
    if args.list_filters:
        for name in FILTERS:
            tags = ["default"] if name == BEST else []
            tags.append("float, fixed point" if has_fixed_point(name) else "float")
            print(f"{name:18s} {DESCRIPTIONS.get(name, '')} [{'; '.join(tags)}]")
        return 0
    if not args.input:
        raise UsageError("replay-imu needs an input CSV (IN.csv or IN.csv.gz, or a flash-log CSV); see --help")
    if not args.out:
        raise UsageError("replay-imu needs --out OUT.csv (use --out - for standard output)")
    name = args.filter or BEST
    if name not in FILTERS:
        raise UsageError(f"unknown filter {name!r}; choose one of {', '.join(FILTERS)} (see --list-filters)")
    if args.fixed_point and not has_fixed_point(name):
        fixed = ", ".join(f for f in FILTERS if has_fixed_point(f))
        raise UsageError(f"filter {name!r} has no fixed-point variant; with --fixed-point use one of {fixed}")
    if args.out == "-":
        replay(args.input, sys.stdout, name, args.fixed_point)
        return 0
    # Write to memory first so a malformed input never leaves a half-written output file behind.
    buf = io.StringIO()
    n = replay(args.input, buf, name, args.fixed_point)
    try:
        with open(args.out, "w", newline="", encoding="utf-8") as fh:
            fh.write(buf.getvalue())
    except OSError as exc:
        raise UsageError(f"{args.out}: cannot write ({exc.strerror or exc})") from None
    print(f"{n} rows -> {args.out} ({name}{', fixed point' if args.fixed_point else ''})", file=sys.stderr)
    return 0
