"""Leave-one-trial-out scoring: for each trial the setting best on the others, scored on it (bench.filters and
the estimation tests)."""

from __future__ import annotations

import numpy as np


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
