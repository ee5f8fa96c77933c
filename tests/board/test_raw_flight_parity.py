"""The C board's RAW flight is the Python board's, over seeds (issue 35.5). On seed 1 alone the C board's tilt was
0.41° rms against 0.15°, which looked like a fault of the C board: it is not. Both run the same filter bit for bit on
the same samples (the C board's qb_ikf_update against the Python board's NativeIKFQL: checked), read the IMU at the
same instants at 400 Hz, and fly identically up to RAW's entry; from there the closed loops differ in timing: the
Python board writes the motors about 1 ms after the IMU read (its cost model charges the tasks' durations), the C
host's tasks take no time (and its calibration window, the command arriving without the UART's byte time, holds one
sample more). A hover is chaotic enough that the trajectories part, and each seed's tilt is one draw: seeds 1-5
gave 0.151 / 0.412, 0.293 / 0.229, 0.681 / 0.746, 0.737 / 0.485, 0.458 / 0.449 (Python / C), means 0.464 / 0.464."""

from __future__ import annotations

import shutil
import statistics

import pytest

from fcb_sim.hosts.cboard import fly_board

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make")


def test_over_seeds_the_c_boards_raw_tilt_is_the_python_boards() -> None:
    py, c = ([fly_board(k, "raw-hover", seed=s, duration=12.0)["attitude_rms_deg"] for s in (1, 2, 4, 5)]
             for k in ("python", "c"))
    assert abs(statistics.fmean(c) - statistics.fmean(py)) < 0.15 * statistics.fmean(py), (py, c)
