"""Flash-log compression on real and simulated flights: the report's scheme, ours, and zlib on the same data.
Prints a table and one JSON line.

Data:
- real IMU data: the four BROAD trials (Laidig et al., Data 6(7), 2021, CC BY 4.0; /work/shared/data/broad or
  $BROAD_DIR), converted to the board's units and axes (gyro 16.4 LSB per °/s, accelerometer 16384 LSB per g,
  chip-to-body remap of docs/architecture.md, angles from the optical ground truth in 0.01°), at 285.7 Hz;
- a simulated flight: the board in RAW mode at 400 Hz (take-off, roll and pitch steps, yaw, landing) with
  logging on, the records captured as the board logs them.

Codecs, all on the same records (fcb_sim.board.flash_log.LOG_VARS):
- ``delta8``: the report's one-byte scaled deltas with the error term, at the board's scales;
- ``rice``: predictor plus adaptive Rice code at the same scales (so the same error bound, scale/2, always);
- ``delta8-wide`` and ``rice-wide``: both at scales widened per variable until the report's byte never
  overloads on this data (what the report's scheme needs to keep its bound), i.e. a larger error bound;
- ``zlib``: zlib level 9 on the uncompressed 39-byte records (lossless), and ``zlib-q`` on the records
  quantised to the board's scales (the same error bound as ``rice``).
The ratio is against the uncompressed records (39 bytes). Worst error is given in units of each variable's
bound (scale/2): <= 1 means the bound held everywhere.

Run: `python -m bench.log_compression [--rows N]` (N records per BROAD trial, default 12000).
"""

from __future__ import annotations

import argparse
import csv
import gzip
import json
import math
import os
import struct
import time
import zlib
from pathlib import Path

from fcb_sim.board.flash_log import FLASH_BYTES, LOG_VARS, LogVar, encode_log
from term.core.logformat import decode_log

BROAD_DIR = Path(os.environ.get("BROAD_DIR", "/work/shared/data/broad"))
RAW = struct.Struct("<iB3h3h3h4Hhih")  # the uncompressed record: 39 bytes
GYRO = 180.0 / math.pi * 16.4
ACC = 16384.0 / 9.80665
ENCODE_US = {"delta8": 49, "rice": 89}  # the board's cost model: encoding, plus 15 µs per programmed byte


def _clip16(v: float) -> int:
    return max(-32768, min(32767, round(v)))


def broad_rows(path: Path, limit: int) -> list[tuple[int, ...]]:
    rows = []
    roll = pitch = yaw = 0.0
    with gzip.open(path, "rt") as f:
        for i, d in enumerate(csv.DictReader(f)):
            if i >= limit:
                break
            if d["qw"]:
                w, x, y, z = (float(d[k]) for k in ("qw", "qx", "qy", "qz"))
                roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
                pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
                yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
            gx, gy, gz, ax, ay, az = (float(d[k]) for k in ("gx", "gy", "gz", "ax", "ay", "az"))
            cd = 18000.0 / math.pi
            rows.append((round(float(d["t"]) * 1e6), 5, _clip16(roll * cd), _clip16(-pitch * cd), _clip16(-yaw * cd),
                         _clip16(gx * GYRO), _clip16(-gy * GYRO), _clip16(-gz * GYRO),
                         _clip16(ax * ACC), _clip16(-ay * ACC), _clip16(-az * ACC),
                         0, 0, 0, 0, 0, 101325, 1180))
    return rows


def simulated_rows(seconds: float = 20.0, seed: int = 1) -> list[tuple[int, ...]]:
    """A RAW-mode flight through the board's own bytes, the records captured as the board logs them."""
    from fcb_sim.board import control as C
    from fcb_sim.board.board import Board, BoardConfig
    from fcb_sim.lab.profile import BytePilot
    from term.core.protocol import Joystick, Mode, Op

    board = Board(BoardConfig(seed=seed))
    rows: list[tuple[int, ...]] = []
    append = board.log.append

    def capture(row):  # type: ignore[no-untyped-def]
        rows.append(tuple(row))
        return append(row)

    board.log.append = capture  # type: ignore[method-assign]
    pilot = BytePilot(board, seed)
    pilot.command(Op.MODE, Mode.CALIBRATION)
    pilot.run(1.3)
    pilot.command(Op.MODE, Mode.RAW)
    pilot.command(Op.LOG_START)
    hover = C.z_to_lift(-4.0 * 400**2)
    script = [(1.5, 0, 0, 0, 1.12), (2.0, 0, 0, 0, 1.0), (1.5, 6000, 0, 0, 1.0), (1.5, -6000, 0, 0, 1.0),
              (1.5, 0, 6000, 0, 1.0), (1.5, 0, -6000, 0, 1.0), (2.0, 0, 0, 9000, 1.0)]
    t = sum(s[0] for s in script)
    script.append((max(1.0, seconds - t), 0, 0, 0, 0.8))
    for dur, roll, pitch, yaw, lift in script:
        pilot.sticks = Joystick(roll, pitch, yaw, int(hover * lift), 0)
        pilot.run(dur)
    return rows


def worst_error(rows: list[tuple[int, ...]], data: bytes, scales: list[int]) -> tuple[float, int]:
    """Worst |error| over all variables in units of the bound (scale/2; exact variables count 0 or more), and
    the number of records with some variable outside its bound."""
    dec = decode_log(data)[0].rows
    assert len(dec) == len(rows)
    worst, bad = 0.0, 0
    for got, want in zip(dec, rows, strict=True):
        out = False
        for g, w, s in zip(got, want, scales, strict=True):
            bound = max(s // 2, 0.5)  # scale 1 is exact: an error of 1 counts as 2 bounds
            e = abs(g - w) / bound
            if e > worst:
                worst = e
            if abs(g - w) > s // 2:
                out = True
        bad += out
    return worst, bad


def wide_scales(rows: list[tuple[int, ...]], base: list[int]) -> list[int]:
    """Per variable, the smallest scale >= the board's at which no delta needs more than one byte."""
    out = []
    for i, s in enumerate(base):
        biggest = max((abs(b[i] - a[i]) for a, b in zip(rows, rows[1:], strict=False)), default=0)
        out.append(max(s, math.ceil(biggest / 127)))
    return out


def measure(name: str, rows: list[tuple[int, ...]]) -> dict:
    base = [v.scale for v in LOG_VARS]
    wide = wide_scales(rows, base)
    raw = b"".join(RAW.pack(*r) for r in rows)
    res: dict = {"data": name, "records": len(rows), "raw_bytes": len(raw), "wide_scales": dict(
        zip([v.name for v in LOG_VARS], wide, strict=True))}
    for label, scheme, scales in (("delta8", "delta8", base), ("rice", "rice", base),
                                  ("delta8-wide", "delta8", wide), ("rice-wide", "rice", wide)):
        variables = tuple(LogVar(v.name, s) for v, s in zip(LOG_VARS, scales, strict=True))
        data = encode_log(rows, scheme, variables)
        worst, bad = worst_error(rows, data, base)  # errors against the board's bound
        per = len(data) / len(rows)
        res[label] = {"bytes": len(data), "ratio": round(len(raw) / len(data), 2), "bytes_per_record": round(per, 2),
                      "worst_error_in_bounds": round(worst, 2), "records_outside_bound": bad,
                      "seconds_in_128k_at_400hz": round(FLASH_BYTES / per / 400, 1),
                      "logging_us_per_record": round(ENCODE_US[scheme] + 15 * per)}
    zl = zlib.compress(raw, 9)
    quant = b"".join(RAW.pack(*[(x + s // 2) // s * s for x, s in zip(r, base, strict=True)]) for r in rows)
    zq = zlib.compress(quant, 9)
    res["zlib"] = {"bytes": len(zl), "ratio": round(len(raw) / len(zl), 2), "worst_error_in_bounds": 0.0}
    res["zlib-q"] = {"bytes": len(zq), "ratio": round(len(raw) / len(zq), 2), "worst_error_in_bounds": 1.0}
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=12000, help="records per BROAD trial (default 12000)")
    ap.add_argument("--sim-seconds", type=float, default=20.0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    sets = []
    trials = sorted(BROAD_DIR.glob("*.csv.gz")) if BROAD_DIR.is_dir() else []
    for path in trials:
        sets.append(measure(f"broad/{path.name.removesuffix('.csv.gz')}", broad_rows(path, args.rows)))
    sets.append(measure("simulated RAW flight", simulated_rows(args.sim_seconds)))
    cols = ("delta8", "rice", "delta8-wide", "rice-wide", "zlib", "zlib-q")
    print(f"{'data':44s} " + " ".join(f"{c:>19s}" for c in cols))
    print(f"{'':44s} " + " ".join(f"{'ratio worst/bound':>19s}" for _ in cols))
    for r in sets:
        cells = [f"{r[c]['ratio']:8.2f} {r[c]['worst_error_in_bounds']:10.2f}" for c in cols]
        print(f"{r['data'][:44]:44s} " + " ".join(f"{c:>19s}" for c in cells))
    for r in sets:
        print(f"  {r['data']}: {r['delta8']['bytes_per_record']} B/record (report) vs {r['rice']['bytes_per_record']}"
              f" (ours): {r['delta8']['seconds_in_128k_at_400hz']} s vs {r['rice']['seconds_in_128k_at_400hz']} s of"
              f" 400 Hz logging in 128 KB; {r['delta8']['records_outside_bound']} records outside the bound with"
              f" the report's scheme, {r['rice']['records_outside_bound']} with ours")

    def total(label: str) -> float:
        return sum(r["raw_bytes"] for r in sets) / sum(r[label]["bytes"] for r in sets)

    summary = {"bench": "log_compression", "wall_s": round(time.perf_counter() - t0, 1),
               "ratio": {c: round(total(c), 2) for c in cols},
               "worst_error_in_bounds": {c: max(r[c]["worst_error_in_bounds"] for r in sets) for c in cols},
               "sets": sets}
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
