"""`fcb-sim replay-imu`: run an attitude filter over recorded IMU data (CSV or CSV.gz).

Input: a header naming at least ``t`` (s), ``gx gy gz`` (rad/s) and ``ax ay az`` (m/s², specific force, z up);
other columns are ignored; any sample rate (dt from t, strictly increasing). The first row has no previous
time: its dt is taken equal to the second row's. Output: one row per input row with ``t, roll, pitch, yaw``
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

from fcb_sim.errors import UsageError

from . import BEST, DESCRIPTIONS, FILTERS, has_fixed_point, make_filter

REQUIRED = ("t", "gx", "gy", "gz", "ax", "ay", "az")
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


def read_imu(path: str) -> Iterator[tuple[float, float, float, float, float, float, float]]:
    """Yield (t, gx, gy, gz, ax, ay, az) rows, raising UsageError with the line number on bad input."""
    fh = _open_text(path)
    with fh:
        try:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise UsageError(f"{path}: empty file; expected a CSV header with {', '.join(REQUIRED)}")
            names = [h.strip() for h in header]
            missing = [c for c in REQUIRED if c not in names]
            if missing:
                raise UsageError(
                    f"{path}: missing column(s) {', '.join(missing)}; the header needs {', '.join(REQUIRED)}"
                )
            idx = [names.index(c) for c in REQUIRED]
            last_t = -math.inf
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue  # blank line
                line = reader.line_num
                try:
                    vals = tuple(float(row[i]) for i in idx)
                except IndexError:
                    raise UsageError(f"{path}:{line}: too few fields ({len(row)} for {len(names)} columns)") from None
                except ValueError:
                    col, i = next((c, i) for c, i in zip(REQUIRED, idx, strict=True) if not _is_float(row[i]))
                    raise UsageError(f"{path}:{line}: column {col} is not a number: {row[i]!r}") from None
                if not all(math.isfinite(v) for v in vals):
                    raise UsageError(f"{path}:{line}: non-finite value (nan or inf)")
                if vals[0] <= last_t:
                    raise UsageError(f"{path}:{line}: time t={vals[0]} does not increase (previous {last_t})")
                last_t = vals[0]
                yield vals  # type: ignore[misc]
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
    first = next(rows, None)
    if first is None:
        raise UsageError(f"{path}: no data rows")
    second = next(rows, None)
    pending = [first] if second is None else [first, second]
    # dt of the first row: the first interval (a lone row has none: assume the report's 400 Hz)
    prev_t = first[0] - (second[0] - first[0] if second is not None else 0.0025)
    progress = sys.stderr.isatty()
    n = 0
    t_start = time.monotonic()

    def step(r: tuple[float, ...]) -> None:
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

    for r in pending:
        step(r)
    for r in rows:
        step(r)
    if progress and n >= _PROGRESS_EVERY:
        print(file=sys.stderr)
    return n


def cmd_replay(args: argparse.Namespace) -> int:
    """The `fcb-sim replay-imu` subcommand."""
    if args.list_filters:
        for name in FILTERS:
            tags = ["default"] if name == BEST else []
            tags.append("float, Q16.16" if has_fixed_point(name) else "float")
            print(f"{name:18s} {DESCRIPTIONS.get(name, '')} [{'; '.join(tags)}]")
        return 0
    if not args.input:
        raise UsageError("replay-imu needs an input CSV (IN.csv or IN.csv.gz); see --help")
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
    print(f"{n} rows -> {args.out} ({name}{', Q16.16' if args.fixed_point else ''})", file=sys.stderr)
    return 0
