"""Physics sanity: hover equilibrium, free fall, energy, ground contact, symmetric responses, battery."""

from __future__ import annotations

import math

import pytest

from fcb_sim.world import constants as P
from fcb_sim.world.physics import World


def test_ae_400_hovers_at_the_reference_voltage():
    # Z = -b sum(ae²) with the firmware b: four motors at 400 carry the weight
    assert 4 * P.B_FW * 400**2 == pytest.approx(P.MASS * P.G, rel=1e-9)


def test_hover_equilibrium_holds_height_and_attitude():
    w = World(1, height=2.0, airborne=True)
    w.advance_to(1.0)
    tr = w.truth
    assert abs(tr.vd) < 0.1
    assert abs(tr.h - 2.0) < 0.05
    assert abs(tr.phi) < 1e-9 and abs(tr.theta) < 1e-9
    # the command that hovers is near 400 (the battery is above V_REF at 90 %)
    assert 360 <= w.cmd[0] <= 420


def test_free_fall_follows_g_and_the_accelerometer_reads_zero():
    w = World(2, height=10.0, airborne=True, drag=False)
    w.set_motors(0, 0, 0, 0)
    w.w1 = w.w2 = w.w3 = w.w4 = 0.0  # rotors stopped at once
    w.advance_to(1.0)
    assert w.truth.h == pytest.approx(10.0 - 0.5 * P.G, abs=0.01)
    assert w.truth.vd == pytest.approx(P.G, abs=1e-6)
    az = w.imu()[5]
    assert abs(az) < 0.12 * P.ACC_LSB_PER_G  # specific force ~0 in free fall (bias and noise aside)


def test_energy_is_conserved_without_drag_and_thrust():
    w = World(3, height=50.0, airborne=True, drag=False, ground=False)
    w.set_motors(0, 0, 0, 0)
    w.w1 = w.w2 = w.w3 = w.w4 = 0.0
    w.p, w.q, w.r = 2.0, -1.5, 1.0  # tumbling: exercises the gyroscopic term
    w.vn, w.ve = 3.0, -2.0
    e0 = w.energy()
    w.advance_to(2.0)
    assert w.energy() == pytest.approx(e0, rel=2e-3)
    assert w.vn == pytest.approx(3.0) and w.ve == pytest.approx(-2.0)


def test_rests_on_the_floor_takes_off_lands_and_never_falls_through():
    w = World(4)
    w.advance_to(1.0)
    assert w.truth.h == 0.0 and w.on_ground
    assert w.imu()[5] == pytest.approx(P.ACC_LSB_PER_G, abs=0.1 * P.ACC_LSB_PER_G)  # the floor pushes up
    w.set_motors(600, 600, 600, 600)
    lowest = 0.0
    for i in range(1, 301):
        w.advance_to(1.0 + i * 0.01)
        lowest = min(lowest, w.truth.h)
    assert not w.on_ground and w.truth.h > 1.0
    w.set_motors(0, 0, 0, 0)
    for i in range(1, 501):
        w.advance_to(4.0 + i * 0.01)
        lowest = min(lowest, w.truth.h)
    assert w.on_ground and w.truth.h == 0.0
    assert lowest == 0.0
    assert len(w.landings) == 1 and w.landings[0][1] > 1.0  # touched down falling


@pytest.mark.parametrize("axis", ["roll", "pitch"])
def test_left_right_responses_are_mirror_images(axis):
    def fly(sign: int) -> tuple[float, float, float]:
        w = World(5, height=5.0, airborne=True)
        c = w.cmd[0]
        if axis == "roll":
            w.set_motors(c, c - 20 * sign, c, c + 20 * sign)  # left faster: right side down for sign = +1
        else:
            w.set_motors(c + 20 * sign, c, c - 20 * sign, c)  # front faster: nose up for sign = +1
        w.advance_to(0.3)
        tr = w.truth
        return (tr.phi if axis == "roll" else tr.theta), tr.e, tr.n

    a, b = fly(+1), fly(-1)
    assert a[0] > 0.05
    assert b[0] == pytest.approx(-a[0], rel=1e-9)
    assert b[1] == pytest.approx(-a[1], abs=1e-12)
    assert b[2] == pytest.approx(-a[2], abs=1e-12)
    if axis == "roll":
        assert a[1] > 0  # right side down: drifts east (right)
    else:
        assert a[2] < 0  # nose up: drifts backwards


def test_yaw_moment_sign_follows_the_mixing():
    w = World(6, height=5.0, airborne=True)
    c = w.cmd[0]
    w.set_motors(c - 30, c + 30, c - 30, c + 30)  # N = d(-a1 + a2 - a3 + a4) > 0: nose right
    w.advance_to(0.5)
    assert w.truth.r > 0.1 and w.truth.psi > 0.0


def test_battery_sags_under_load_and_discharges():
    w = World(7)
    w.advance_to(0.5)
    v_idle, soc0 = w.volts, w.soc
    w.set_motors(700, 700, 700, 700)
    w.advance_to(2.5)
    assert w.volts < v_idle - 0.5  # sag
    assert w.soc < soc0
    assert 1000 <= w.battery() <= 1270  # 10 mV units of a 3S pack


def test_disturbances_push_and_stuck_motor():
    w = World(8, height=5.0, airborne=True)
    w.push(0.0, 5.0, 0.0, 0.2)
    w.advance_to(0.5)
    assert w.truth.ve > 0.5
    w.stick_motor(3, 100)
    w.set_motors(500, 500, 500, 500)
    assert w.cmd == [500, 500, 100, 500]
    w.stick_motor(3, None)
    assert w.cmd[2] == 500


def test_wind_drags_the_quadrotor_along():
    w = World(9, height=5.0, airborne=True)
    w.set_wind(3.0, 0.0, 0.0, gust_std=0.5, gust_tau=0.5)
    w.advance_to(2.0)
    assert w.truth.vn > 0.3


def test_fixed_step_is_at_least_1khz_and_stable_at_higher_rates():
    with pytest.raises(ValueError):
        World(1, physics_hz=500)
    a = World(10, height=3.0, airborne=True)
    b = World(10, height=3.0, airborne=True, physics_hz=4000)
    for w in (a, b):
        w.set_motors(450, 380, 420, 400)
        w.advance_to(0.5)
    assert a.truth.phi == pytest.approx(b.truth.phi, abs=0.01)
    assert a.truth.h == pytest.approx(b.truth.h, abs=0.01)
    assert math.isfinite(a.truth.psi)


def test_a_torque_push_acts_for_its_duration_only():
    w = World(11, height=5.0, airborne=True, drag=False)
    w.push(duration=0.1, tx=0.05)
    w.advance_to(0.2)
    p_after = w.truth.p
    assert p_after > 0.5  # 0.05 N m for 0.1 s on 7.5e-3 kg m²: about 0.67 rad/s
    w.advance_to(0.3)
    assert w.ext == (0.0,) * 6
    assert w.truth.p == pytest.approx(p_after, rel=0.05)  # no torque left (motors balanced, no drag)
