"""`fcb-sim replay-imu`: run an attitude filter over recorded IMU data (CSV or CSV.gz).

Two inputs, told apart by their header:

- IMU CSV: a header naming at least ``t`` (s), ``gx gy gz`` (rad/s) and ``ax ay az`` (m/s², specific force, chip
  frame z up); other columns are ignored (the BROAD trials of ../shared/data/broad are such files).
- The board's flash log as ``term`` writes it after a download (docs/flash_log.md): ``t_us`` and the IMU words
  the board logs every control period, ``sp sq sr`` (calibrated body rates, gyro LSB) and ``sax say saz``
  (calibrated body accelerations, accelerometer LSB), in the firmware's FRD body frame. They are turned back
  into the chip frame the filters take (docs/architecture.md: ``gx = sp, gy = -sq, gz = -sr``,
  ``ax = sax, ay = -say, az = -saz``) and into SI units (16.4 LSB per °/s, 16384 LSB per g). A new ``segment``
  (another recording in the same log) restarts the filter. The log's own angles (``phi theta psi``) are what
  the board's filter said in flight: a replay through the same filter reproduces them (tests do).

Any sample rate (dt from the time column, strictly increasing). The first row, and the first of each segment,
has no previous time: its dt is the next interval. Output: one row per input row with ``t, roll, pitch, yaw``
(rad) and ``qw, qx, qy, qz`` (body-to-earth, earth z up). A malformed file ends in one clear line (exit 2).
"""

from __future__ import annotations

import argparse
import csv
import gzip
import io
import math
import sys
import time
from collections.abc import Iterator
from typing import IO

from fcb_sim import params as P
from fcb_sim.errors import UsageError

from . import BEST, DESCRIPTIONS, FILTERS, has_fixed_point, make_filter

REQUIRED = ("t", "gx", "gy", "gz", "ax", "ay", "az")
FLASH_LOG = ("t_us", "sp", "sq", "sr", "sax", "say", "saz")  # the board's flash log (term's CSV of a download)
_G = 1.0 / P.RATE_LSB_PER_RAD_S
_A = 1.0 / P.ACC_LSB_PER_MS2
# chip-frame SI sample from the logged FRD words: (t, gx, gy, gz, ax, ay, az)
_FROM_LOG = (1e-6, _G, -_G, -_G, _A, -_A, -_A)
Sample = tuple[float, float, float, float, float, float, float]
_PROGRESS_EVERY = 100_000  # rows; progress only when stderr is a terminal


def _open_text(path: str) -> IO[str]:
    try:
        if path.endswith(".gz"):
            fh: IO[str] = gzip.open(path, "rt", newline="", encoding="utf-8")
            fh.read(0)
            return fh
        return open(path, newline="", encoding="utf-8")
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
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise UsageError(f"{path}: empty file; expected a CSV header with {', '.join(REQUIRED)}")
            names = [h.strip() for h in header]
            log = all(c in names for c in FLASH_LOG)
            cols = FLASH_LOG if log else REQUIRED
            missing = [c for c in REQUIRED if c not in names]
            if missing and not log:
                raise UsageError(
                    f"{path}: missing column(s) {', '.join(missing)}; the header needs {', '.join(REQUIRED)} "
                    f"(or, for the board's flash log, {', '.join(FLASH_LOG)})"
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


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def replay(path: str, out: IO[str], name: str = BEST, fixed_point: bool = False) -> int:
    """Run filter ``name`` over ``path`` and write the output CSV to ``out``; returns the number of rows."""
    filt = make_filter(name, fixed_point=fixed_point)
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["t", "roll", "pitch", "yaw", "qw", "qx", "qy", "qz"])
    rows = read_imu(path)
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
