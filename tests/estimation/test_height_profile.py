"""The height estimate stays true on the ground and after landing (issue 10.3): the height-profile scenario
(climb, hold at 2, 10 and 30 m, descend, land, 30 s on the ground) against the simulator's truth, and the
estimator on its own after a hard impact (the report of a -17 m, then -32.77 m estimate with vz stuck at
-22.75 m/s for 10 s in SAFE)."""

from __future__ import annotations

import math

import pytest

from fcb_sim.estimation.height import GROUND_REST_S, HeightKalman
from fcb_sim.lab.scenarios import height_profile
from fcb_sim.world import constants as P


@pytest.mark.parametrize("seed", [1, 2])
def test_height_profile_estimate_against_the_truth(seed: int) -> None:
    m = height_profile(seed)
    assert m["landing_speed_m_s"] < 0.5  # a landing, not a crash
    assert m["height_flight_rms_m"] <= 0.15
    assert m["height_touchdown_err_m"] <= 0.2
    assert m["height_ground_drift_m"] <= 0.05


def _still(est: HeightKalman, seconds: float, pressure: float, *, motors_off: bool = True,
           acc: float = P.G) -> None:
    """The board at rest (specific force ``acc`` up), the barometer reading ``pressure``, 400 Hz and 20 Hz."""
    est.motors_off = motors_off
    for i in range(int(seconds * 400)):
        est.update_imu(0.0, 0.0, acc, 1.0, 0.0, 0.0, 0.0, 0.0025)
        if i % 20 == 19:
            est.update_baro(pressure, 0.05)


def test_after_a_hard_impact_the_estimate_reanchors_to_the_barometer() -> None:
    est = HeightKalman()
    est.reset(P.P0)
    est.motors_off = True
    # a fall the estimate got wrong: -20 m/s and 17 m below the floor by the time of the impact
    est.height, est.vz = -17.0, -20.0
    for _ in range(4):  # the impact: the accelerometer clips at its 2 g for 10 ms
        est.update_imu(0.0, 0.0, 2 * P.G, 1.0, 0.0, 0.0, 0.0, 0.0025)
    _still(est, GROUND_REST_S + 0.2, P.P0)
    assert est.on_ground and est.vz == 0.0
    _still(est, 2.0, P.P0)
    assert abs(est.height) < 0.05 and est.vz == 0.0
    h0 = est.height
    _still(est, 30.0, P.P0 + 1.0)  # the barometer drifts by 1 Pa (8 cm): the craft did not move
    assert abs(est.height - h0) < 0.01 and est.vz == 0.0


def test_thrust_or_motion_is_not_the_ground() -> None:
    est = HeightKalman()
    est.reset(P.P0)
    _still(est, 3.0, P.P0, motors_off=False)  # hovering: the motors turn
    assert not est.on_ground
    _still(est, 3.0, P.P0, acc=0.0)  # falling: no specific force
    assert not est.on_ground
    _still(est, 3.0, P.P0)
    assert est.on_ground
    est.update_imu(0.0, 0.0, 3 * P.G, 1.0, 0.0, 0.0, 0.0, 0.0025)  # picked up: not at rest any more
    assert not est.on_ground and math.isfinite(est.height)
