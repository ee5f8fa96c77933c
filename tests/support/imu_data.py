"""The BROAD excerpt the estimation tests read (tests/fixtures/), its rows, and wild samples for properties."""

from __future__ import annotations

import csv
import functools
import gzip
import math
from pathlib import Path

from hypothesis import strategies as st


def _rows(path: Path, n: int) -> list[tuple[float, ...]]:
    """(gx, gy, gz, ax, ay, az, dt) of the first ``n`` rows of a BROAD trial (gyro rad/s, specific force m/s²): a
    new list each call, of rows read once per process (the properties take a slice of them for every example)."""
    return list(_read_rows(path, n))


@functools.lru_cache(maxsize=32)
def _read_rows(path: Path, n: int) -> tuple[tuple[float, ...], ...]:
    out: list[tuple[float, ...]] = []
    with gzip.open(path, "rt", newline="") as fh:
        reader = csv.DictReader(fh)
        t_prev = None
        for row in reader:
            t = float(row["t"])
            if t_prev is not None:
                out.append((*(float(row[k]) for k in ("gx", "gy", "gz", "ax", "ay", "az")), t - t_prev))
            t_prev = t
            if len(out) >= n:
                break
    return tuple(out)


_wild = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                  st.sampled_from([0.0, -0.0, 1e-9, 35.0, -35.0, 1e4, -1e4, 32767.9, -32768.0, 1e300]))


_sample = st.tuples(_wild, _wild, _wild, _wild, _wild, _wild,
                    st.sampled_from([0.0025, 0.0025, 0.001, 0.05, 0.0, -1.0, 1.0, math.nan, 1e-7]))
