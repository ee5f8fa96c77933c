"""The one calibration (fcb_sim/board/calibration.py): unbounded integer sums, rounded means, the means the flight core
applies; the board's and the scenarios' CALIBRATION both go through it."""

from __future__ import annotations

import pytest

from fcb_sim.board.calibration import DMP_ANGLE_LSB, CalibrationSums
from fcb_sim.estimation import quaternion_to_euler
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World


def test_calibration_sums_are_unbounded_and_means_rounded() -> None:
    c = CalibrationSums(("gx", "pressure"))
    big = 2**62
    for _ in range(8):
        c.add({"gx": big})  # a 64-bit sum would overflow here
    c.add({"pressure": 3})
    c.add({"pressure": 4})
    assert c.sums["gx"] == 8 * big
    assert c.means() == {"gx": big, "pressure": 4}  # 3.5 rounds up
    assert c.count == 8


def test_an_unknown_variable_is_refused() -> None:
    with pytest.raises(KeyError, match="not calibrated"):
        CalibrationSums(("gx",)).add({"gy": 1})


def test_calibration_means_of_a_board_at_rest() -> None:
    sums = CalibrationSums()
    w = World(3)
    last_q = None
    for i in range(1, 401):
        w.advance_to(i * 0.0025)
        sums.add_imu(*w.imu())
        q = w.dmp()
        if q is not None:
            sums.add_dmp(*q)
            last_q = q
        if i % 20 == 0:
            sums.add_baro(w.baro()[0])
    cal = sums.result()
    assert cal.gyro[0] == pytest.approx(w.mpu.gyro_bias[0], abs=3.0)
    assert cal.accel[2] == pytest.approx(16384 + w.mpu.acc_bias[2], abs=10.0)
    assert cal.pressure == pytest.approx(P.P0, abs=3.0)
    assert all(float(v).is_integer() for v in (*cal.gyro, *cal.accel, cal.pressure))  # integer means
    roll, pitch, _ = quaternion_to_euler(*last_q)
    assert cal.dmp_phi == pytest.approx(roll, abs=2 / DMP_ANGLE_LSB + 0.01)
    assert cal.dmp_theta == pytest.approx(-pitch, abs=2 / DMP_ANGLE_LSB + 0.01)  # FRD: theta = -pitch


def test_without_samples_the_neutral_values_and_the_given_pressure() -> None:
    sums = CalibrationSums()
    with pytest.raises(ValueError, match="no IMU samples"):
        sums.result()
    sums.add_imu(1, 2, 3, 4, 5, 16390)
    cal = sums.result(pressure=100_000.0)
    assert (cal.dmp_phi, cal.dmp_theta, cal.pressure) == (0.0, 0.0, 100_000.0)  # RAW path: no DMP, no baro yet
