"""The heading at rest (issue 35.2): a still craft does not turn, so the drift of a path's heading on the pad is
frozen out and its rate learnt; in flight the rate is taken out."""

from __future__ import annotations

import math
import random

from fcb_sim.estimation.heading import RATE_MIN_S, HeadingHold, wrap

DEG = math.pi / 180.0
DT = 0.01


def test_still_the_heading_is_frozen_and_the_drift_rate_learnt() -> None:
    rnd = random.Random(1)
    hold = HeadingHold()
    drift = -0.02 * DEG  # the DMP's yaw drift in the simulator
    psi = 0.0
    for k in range(int(30 / DT)):
        psi = 0.3 + drift * k * DT + rnd.gauss(0, 0.1 * DEG)
        out = hold.update(psi, True, DT)
    assert abs(out - hold.update(psi, True, 0.0)) < 1e-12
    assert abs(wrap(out - 0.3)) < 0.5 * DEG  # where it was when it stopped (the first sample's noise)
    assert abs(hold.rate - drift) < 0.001 * DEG
    assert abs(hold.offset - drift * 30) < 0.5 * DEG  # the drift since reset: 0.6°


def test_in_flight_the_learnt_rate_is_taken_out() -> None:
    hold = HeadingHold()
    drift = 0.03 * DEG
    t = 0.0
    for _ in range(int((RATE_MIN_S + 5) / DT)):
        t += DT
        hold.update(drift * t, True, DT)
    turn = 0.0
    for _ in range(int(300 / DT)):  # five minutes of flight, turning 10°/s for 9 s
        t += DT
        turn += 10 * DEG * DT if t < 20 else 0.0
        out = hold.update(wrap(turn + drift * t), False, DT)
    assert abs(wrap(out - turn)) < 0.05 * DEG


def test_without_a_still_stretch_nothing_is_learnt() -> None:
    hold = HeadingHold()
    for k in range(400):
        out = hold.update(k * 0.001, k % 2 == 0 and k < 100, DT)
    assert hold.rate == 0.0 and abs(out - 399 * 0.001 + hold.offset) < 1e-12


def test_the_board_freezes_the_heading_on_the_pad() -> None:
    """Ten minutes... here two, in SAFE after calibration: the DMP's heading would drift 2.4°; the one shown stays
    within 0.3° of the truth, on both paths."""
    from fcb_sim.lab.scenarios import Sim
    from term.core.protocol import Mode

    sim = Sim(5)
    sim.set_mode(Mode.CALIBRATION)
    sim.run_until(1.0)
    sim.set_mode(Mode.SAFE)
    sim.run_until(121.0)
    truth = sim.world.truth.psi
    assert abs(math.degrees(sim.fc.dmp_psi - truth)) > 2.0  # the DMP itself drifts
    assert abs(math.degrees(wrap(sim.fc.psi_dmp - truth))) < 0.3
    assert abs(math.degrees(wrap(sim.fc.psi_raw - truth))) < 0.3
    assert abs(math.degrees(sim.fc.heading_dmp.rate)) > 0.015  # 0.02 °/s learnt
    assert abs(sim.fc.heading_drift_cdeg()) > 200
