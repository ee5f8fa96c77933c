"""Scoring attitude filters on the BROAD trials (bench.filters and the estimation tests): a trial's columns, the
inclination error against the optical truth, and leave-one-trial-out picking of tuned settings."""

from __future__ import annotations

import csv
import gzip
import math
from pathlib import Path

import numpy as np


def load_trial(path: Path, stop: int | None = None) -> dict[str, np.ndarray]:
    """The columns of a BROAD trial (``*.csv.gz``; its README names them) by name, the first ``stop`` rows (all
    without it); empty fields (no truth) are NaN."""
    with gzip.open(path, "rt", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        rows = []
        for row in reader:
            rows.append([float(v) if v else math.nan for v in row])
            if stop is not None and len(rows) >= stop:
                break
    arr = np.array(rows, dtype=float)
    return {name: arr[:, i] for i, name in enumerate(header)}


def up_in_body(q: np.ndarray) -> np.ndarray:
    """Earth z in body coordinates (third row of R(q)) for quaternions (N, 4) w, x, y, z, normalised."""
    w, x, y, z = q.T
    v = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], axis=1)
    return v / np.linalg.norm(v, axis=1)[:, None]


def inclination_rmse_deg(q_est: np.ndarray, trial: dict[str, np.ndarray]) -> float:
    """RMS inclination error (deg: the angle between the estimated and the true vertical) over the rows with
    movement = 1 and optical ground truth."""
    q_true = np.stack([trial["qw"], trial["qx"], trial["qy"], trial["qz"]], axis=1)
    mask = (trial["movement"] == 1) & np.isfinite(q_true[:, 0])
    c = np.clip(np.sum(up_in_body(q_est[mask]) * up_in_body(q_true[mask]), axis=1), -1.0, 1.0)
    return float(np.sqrt(np.mean(np.degrees(np.arccos(c)) ** 2)))


def leave_one_out(grid: np.ndarray) -> tuple[list[int], np.ndarray]:
    """grid: (trials, points) scores. For each trial the point best on the others, and its score there."""
    n = grid.shape[0]
    picks, scores = [], np.empty(n)
    for i in range(n):
        others = np.delete(grid, i, axis=0).mean(axis=0)
        j = int(np.argmin(others))
        picks.append(j)
        scores[i] = grid[i, j]
    return picks, scores
