"""Refit the fixed-point atan2 correction table on recorded accelerometer data (offline tool).

``python -m fcb_sim.estimation.atan2_fit FILE.csv[.gz] ...`` prints the table to paste into
``fixed.ATAN2_CORRECTION``: the least-squares fit (:func:`fixed.fit_atan2_correction`) of fix16_atan2's error
on the roll and pitch angles the filters compute from every accelerometer sample of the files (CSV with
``ax ay az`` columns, m/s²). The table in the code was fitted on the four BROAD trials.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence

from .fixed import fit_atan2_correction


def _accel_angle_pairs(paths: Sequence[str]) -> list[tuple[float, float]]:
    import csv
    import gzip

    pairs: list[tuple[float, float]] = []
    for path in paths:
        opener = gzip.open if path.endswith(".gz") else open
        with opener(path, "rt", newline="") as fh:
            for row in csv.DictReader(fh):
                ax, ay, az = float(row["ax"]), float(row["ay"]), float(row["az"])
                pairs.append((ay, az))
                pairs.append((-ax, math.sqrt(ay * ay + az * az)))
    return pairs


def main(argv: Sequence[str] | None = None) -> int:
    paths = list(sys.argv[1:] if argv is None else argv)
    if not paths:
        print("usage: python -m fcb_sim.estimation.atan2_fit FILE.csv[.gz] ...", file=sys.stderr)
        return 2
    print(tuple(fit_atan2_correction(_accel_angle_pairs(paths))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
