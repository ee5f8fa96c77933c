"""Controllers and mixing: integer square root, motor differentials and their physical signs, step responses."""

from __future__ import annotations

import math

import pytest

from fcb_sim.board import control as C
from fcb_sim.lab.scenarios import run_scenario
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World


def test_isqrt_max_error_is_1_over_0_to_1e6():
    worst = max(abs(C.isqrt_nr(s) - math.isqrt(s)) for s in range(1_000_001))
    assert worst <= 1


def test_the_appendix_as_printed_is_off_by_2_somewhere():
    # the report claims max error 1; its two iterations from a clz guess reach 2 (hence isqrt_nr's correction)
    assert C.isqrt_appendix(506925) - math.isqrt(506925) == 2
    assert C.isqrt_appendix(0) == 0 and C.isqrt_appendix(160000) == 400


def test_mix_hover_and_limits():
    assert C.mix(-4 * 400 * 400, 0, 0, 0) == (400, 400, 400, 400)
    assert C.mix(-4 * 2000 * 2000, 0, 0, 0) == (1000, 1000, 1000, 1000)
    assert C.mix(0, 0, 0, 0) == (P.AE_IDLE,) * 4  # armed: idle
    assert C.mix(0, 0, 0, 0, armed=False) == (0, 0, 0, 0)
    assert C.mix(-4 * 100 * 100, 500_000, 0, 0, armed=False)[1] == 0  # a negative square clamps to 0


def test_mixing_inverts_the_design_equations():
    z, l, m, n = -640_000, 40_000, -24_000, 60_000
    a1, a2, a3, a4 = (v * v for v in C.mix(z, l, m, n))
    assert -(a1 + a2 + a3 + a4) == pytest.approx(z, rel=0.01)
    assert a4 - a2 == pytest.approx(l, rel=0.02)
    assert a1 - a3 == pytest.approx(m, rel=0.02)
    assert -a1 + a2 - a3 + a4 == pytest.approx(n, rel=0.02)


def test_positive_roll_error_spins_the_left_motor_up_and_rolls_right():
    # phi_sp = +5 deg, level, not rotating: L > 0, ae4 (left) > ae2 (right)
    lm = C.cascade(5 * 182.0, 0.0, 0.0, 0.4, 111.0)
    assert lm > 0
    ae = C.mix(-4 * 400 * 400, lm, 0, 0)
    assert ae[3] > ae[1] and ae[0] == ae[2]
    w = World(1, height=5.0, airborne=True)
    w.set_motors(*ae)
    w.advance_to(0.1)
    assert w.truth.p > 0 and w.truth.phi > 0  # right side goes down: the error shrinks


def test_positive_pitch_error_spins_the_front_motor_up_and_pitches_nose_up():
    mm = C.cascade(5 * 182.0, 0.0, 0.0, 0.4, 111.0)
    ae = C.mix(-4 * 400 * 400, 0, mm, 0)
    assert ae[0] > ae[2] and ae[1] == ae[3]
    w = World(1, height=5.0, airborne=True)
    w.set_motors(*ae)
    w.advance_to(0.1)
    assert w.truth.q > 0 and w.truth.theta > 0


def test_rate_term_damps_and_yaw_rate_sign():
    # rolling right (p > 0) with no angle error asks for a negative moment
    assert C.cascade(0.0, 0.0, 500.0, 0.4, 111.0) < 0
    # a nose-right rate demand (r_sp > r) asks for positive N: motors 2 and 4 up
    nm = C.yaw_rate(1000.0, 0.0, 800.0)
    ae = C.mix(-4 * 400 * 400, 0, 0, nm)
    assert ae[1] > ae[0] and ae[3] > ae[2]


def test_height_pd_signs():
    zb = -640_000
    assert C.height_pd(zb, 1000.0, 900.0, 0.0, 250.0, 200.0) < zb  # below the set point: more lift
    assert C.height_pd(zb, 1000.0, 1000.0, 100.0, 250.0, 200.0) > zb  # climbing: less lift


def test_lift_stick_mapping_round_trips():
    for lift in (0, 1000, 16384, 32767):
        assert abs(C.lift_to_z(C.z_to_lift(C.lift_to_z(lift))) - C.lift_to_z(lift)) <= 4 * 2 * 800 + 4


def test_roll_step_settles():
    m = run_scenario("step-roll", 9.0, seed=2)
    assert m["settle_time_s"] < 1.5
    # P-only: the drag of the sideways flight a 10 deg roll starts leaves a small offset
    assert m["final_roll_deg"] == pytest.approx(10.0, abs=2.5)


def test_yaw_rate_step_settles():
    m = run_scenario("step-yaw", 9.0, seed=2)
    assert m["settle_time_s"] < 1.5
    assert m["final_yaw_rate_dps"] == pytest.approx(45.0, abs=4.5)
