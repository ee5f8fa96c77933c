"""The HEIGHT loop's integral (control.height_integral, FlightCore.height_i): anti-windup and the battery's sag."""

from __future__ import annotations

import pytest

from fcb_sim.board import control as C
from fcb_sim.board.flight import HEIGHT_I, Calibration, FlightCore
from fcb_sim.lab.scenarios import Sim, height_hold
from term.core.protocol import Mode


def test_integral_accumulates_below_the_set_point_and_is_clamped() -> None:
    i = 0.0
    for _ in range(400):  # 1 s, 100 mm below the set point
        i = C.height_integral(i, 1000.0, 900.0, 100.0, 0.0025)
    assert i == pytest.approx(100.0 * 100.0 * 1.0)  # ki * error * time: asks for more lift
    for _ in range(100 * 400):
        i = C.height_integral(i, 1000.0, 0.0, 100.0, 0.0025)
    assert i == C.HEIGHT_I_LIMIT  # never beyond the bound, however long the error lasts


def test_integral_freezes_while_saturated_but_unwinds() -> None:
    assert C.height_integral(5000.0, 1000.0, 900.0, 100.0, 0.0025, saturated=True) == 5000.0
    assert C.height_integral(5000.0, 900.0, 1000.0, 100.0, 0.0025, saturated=True) < 5000.0


def test_flight_core_integral_is_reset_on_entering_height() -> None:
    fc = FlightCore()
    fc.set_calibration(Calibration())
    fc.height = 1.0
    for mode in (Mode.FULL, Mode.HEIGHT):
        fc.enter_mode(mode, 16384)
        fc.control(mode, 0, 0, 0, 16384)
    fc.height = 0.9  # 10 cm low for 2 s: the integral adds lift
    first = fc.control(Mode.HEIGHT, 0, 0, 0, 16384)
    for _ in range(800):
        later = fc.control(Mode.HEIGHT, 0, 0, 0, 16384)
    assert min(later) > min(first)
    for mode in (Mode.FULL, Mode.HEIGHT):
        fc.enter_mode(mode, 16384)
        fc.control(mode, 0, 0, 0, 16384)
    assert fc._z_int == 0.0


def _hold_on_truth(height_i: float, seconds: float) -> float:
    """HEIGHT on the true height (a perfect estimator): what is left is the controller's own error."""

    class Truth:
        def __init__(self, sim: Sim) -> None:
            self.sim, self.height, self.vz, self.h0 = sim, 0.0, 0.0, 0.0

        def reset(self, pressure_pa: float) -> None:
            self.h0 = -self.sim.world.d

        def update_baro(self, pressure_pa: float, dt: float) -> None:
            pass

        def update_imu(self, *sample: float) -> None:
            self.height, self.vz = -self.sim.world.d - self.h0, -self.sim.world.vd

    sim = Sim(1)
    sim.fc.height_est = Truth(sim)
    sim.fc.height_i = height_i
    return height_hold(1, seconds, sim)["height_rms_m"]


def test_integral_takes_out_the_battery_sag() -> None:
    """On the true height over 60 s of HEIGHT, the PD alone sinks as the battery sags; the integral holds."""
    pd_only = _hold_on_truth(0.0, 60.0)
    with_i = _hold_on_truth(HEIGHT_I, 60.0)
    assert pd_only > 0.015
    assert with_i < 0.01
