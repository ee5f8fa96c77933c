"""Inclination accuracy of every attitude filter on real data (four BROAD trials), beside reference packages.

For each trial of ``../shared/data/broad/`` (BROAD, Laidig et al., Data 6(7), 2021, CC BY 4.0; see the
README there) every filter of ``fcb_sim.estimation`` runs over the whole recording, in float and, where it
has one, in Q16.16; the score is the RMS of the inclination error (angle between the estimated and the true
vertical, heading ignored) over the rows with movement = 1 that have optical ground truth, in degrees.
The ``vqf`` package (6D VQF, online) and ``ahrs``'s Madgwick (default gain) run on the same data as reference
baselines only. Also printed: each filter's mean update time in microseconds (this machine, one core).

Run: ``python -m bench.filters [--data DIR] [--no-fixed] [--no-reference]``. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import json
import math
import time
from pathlib import Path

import numpy as np

from fcb_sim.estimation import BEST, FILTERS, has_fixed_point, make_filter

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"


def load_trial(path: Path) -> dict[str, np.ndarray]:
    with gzip.open(path, "rt", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        rows = [[float(v) if v else math.nan for v in row] for row in reader]
    arr = np.array(rows, dtype=float)
    return {name: arr[:, i] for i, name in enumerate(header)}


def inclination_rmse_deg(q_est: np.ndarray, trial: dict[str, np.ndarray]) -> float:
    """RMS inclination error (deg) over movement rows with ground truth. Quaternions (N, 4) w, x, y, z."""
    q_true = np.stack([trial["qw"], trial["qx"], trial["qy"], trial["qz"]], axis=1)
    mask = (trial["movement"] == 1) & np.isfinite(q_true[:, 0])

    def up_in_body(q: np.ndarray) -> np.ndarray:  # third row of R(q): earth z in body coordinates
        w, x, y, z = q.T
        v = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], axis=1)
        return v / np.linalg.norm(v, axis=1)[:, None]

    c = np.clip(np.sum(up_in_body(q_est[mask]) * up_in_body(q_true[mask]), axis=1), -1.0, 1.0)
    return float(np.sqrt(np.mean(np.degrees(np.arccos(c)) ** 2)))


def run_filter(name: str, fixed_point: bool, trial: dict[str, np.ndarray]) -> tuple[np.ndarray, float]:
    """Quaternions (N, 4) and the mean update time in µs."""
    f = make_filter(name, fixed_point=fixed_point)
    t = trial["t"].tolist()
    cols = [trial[k].tolist() for k in ("gx", "gy", "gz", "ax", "ay", "az")]
    out = np.empty((len(t), 4))
    prev = t[0] - (t[1] - t[0])
    update, quat = f.update, f.quaternion
    spent = 0.0
    clock = time.perf_counter
    for i, (gx, gy, gz, ax, ay, az) in enumerate(zip(*cols, strict=True)):
        t0 = clock()
        update(gx, gy, gz, ax, ay, az, t[i] - prev)
        spent += clock() - t0
        prev = t[i]
        out[i] = quat()
    return out, spent / len(t) * 1e6


def run_vqf(trial: dict[str, np.ndarray]) -> np.ndarray:
    from vqf import VQF

    gyr = np.ascontiguousarray(np.stack([trial["gx"], trial["gy"], trial["gz"]], axis=1))
    acc = np.ascontiguousarray(np.stack([trial["ax"], trial["ay"], trial["az"]], axis=1))
    ts = float(np.median(np.diff(trial["t"])))
    return np.asarray(VQF(ts).updateBatch(gyr, acc)["quat6D"])  # the causal (online) filter, as ours


def run_madgwick(trial: dict[str, np.ndarray]) -> np.ndarray:
    from ahrs.filters import Madgwick

    gyr = np.stack([trial["gx"], trial["gy"], trial["gz"]], axis=1)
    acc = np.stack([trial["ax"], trial["ay"], trial["az"]], axis=1)
    freq = 1.0 / float(np.median(np.diff(trial["t"])))
    return np.asarray(Madgwick(gyr=gyr, acc=acc, frequency=freq).Q)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="directory with the BROAD *.csv.gz trials")
    ap.add_argument("--no-fixed", action="store_true", help="skip the Q16.16 variants (the slow part)")
    ap.add_argument("--no-reference", action="store_true", help="skip the vqf and ahrs baselines")
    args = ap.parse_args()
    paths = sorted(args.data.glob("*.csv.gz"))
    if not paths:
        raise SystemExit(f"bench.filters: no *.csv.gz trials in {args.data}; pass --data DIR")
    t_start = time.perf_counter()
    variants = [(n, False) for n in FILTERS]
    if not args.no_fixed:
        variants += [(n, True) for n in FILTERS if has_fixed_point(n)]
    per_trial: dict[str, dict[str, float]] = {}
    timing: dict[str, list[float]] = {}
    for path in paths:
        trial_name = path.name.removesuffix(".csv.gz")
        trial = load_trial(path)
        scores: dict[str, float] = {}
        for name, fixed in variants:
            key = name + ("/q16" if fixed else "")
            q, us = run_filter(name, fixed, trial)
            scores[key] = round(inclination_rmse_deg(q, trial), 3)
            timing.setdefault(key, []).append(us)
        if not args.no_reference:
            scores["ref:vqf"] = round(inclination_rmse_deg(run_vqf(trial), trial), 3)
            scores["ref:ahrs-madgwick"] = round(inclination_rmse_deg(run_madgwick(trial), trial), 3)
        per_trial[trial_name] = scores
        print(trial_name, json.dumps(scores), flush=True)
    keys = list(next(iter(per_trial.values())))
    mean = {k: round(sum(s[k] for s in per_trial.values()) / len(per_trial), 3) for k in keys}
    result = {
        "bench": "filters",
        "metric": "inclination RMSE (deg), movement phases, BROAD trials",
        "trials": [p.name.removesuffix(".csv.gz") for p in paths],
        "best": BEST,
        "best_mean_deg": mean[BEST],
        "goal_deg": 1.0,
        "mean_deg": mean,
        "per_trial_deg": per_trial,
        "update_us": {k: round(sum(v) / len(v), 2) for k, v in timing.items()},
        "wall_seconds": round(time.perf_counter() - t_start, 1),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
