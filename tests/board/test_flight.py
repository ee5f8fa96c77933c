"""FlightCore: per-mode control laws, calibration, gains, HEIGHT set point, PANIC, RAW flight."""

from __future__ import annotations

import pytest

from fcb_sim.board.flight import Calibration, FlightCore
from fcb_sim.lab.scenarios import run_scenario
from fcb_sim.world import constants as P
from term.core.protocol import Mode


def _calibrated() -> FlightCore:
    fc = FlightCore()
    fc.set_calibration(Calibration(gyro=(40.0, -30.0, 10.0), accel=(200.0, -100.0, 16500.0), pressure=101300.0))
    return fc


@pytest.mark.parametrize("mode", [Mode.SAFE, Mode.CALIBRATION, Mode.WIRELESS])
def test_motors_off_outside_flight_modes(mode):
    fc = _calibrated()
    assert fc.control(mode, 5000, -3000, 2000, 20000) == (0, 0, 0, 0)


def test_calibration_offsets_are_subtracted_in_the_body_frame():
    fc = _calibrated()
    fc.imu_sample(40 + 164, -30 + 328, 10 - 492, 200, -100, 16500, 0.0025)
    assert (fc.sp, fc.sq, fc.sr) == (164.0, -328.0, 492.0)  # p = gx, q = -gy, r = -gz
    assert (fc.sax, fc.say, fc.saz) == (0.0, 0.0, -P.ACC_LSB_PER_G)  # gravity kept, saz about -16384


def test_manual_maps_sticks_to_moments():
    fc = _calibrated()
    hover = 16384  # lift stick for ae 400 on every motor
    assert fc.control(Mode.MANUAL, 0, 0, 0, hover) == (400, 400, 400, 400)
    ae = fc.control(Mode.MANUAL, 10000, 0, 0, hover)
    assert ae[3] > 400 > ae[1]  # roll right: left motor up
    ae = fc.control(Mode.MANUAL, 0, 10000, 0, hover)
    assert ae[0] > 400 > ae[2]  # stick back: nose up, front motor up
    ae = fc.control(Mode.MANUAL, 0, 0, 10000, hover)
    assert ae[1] > 400 > ae[0]  # twist right: motors 2 and 4 up
    assert fc.control(Mode.MANUAL, 0, 0, 0, 0) == (P.AE_IDLE,) * 4  # armed idle


def test_yaw_mode_closes_the_yaw_rate_loop():
    fc = _calibrated()
    fc.imu_sample(40, -30, 10 - 500, 200, -100, 16500, 0.0025)  # turning nose right at 500 LSB
    ae = fc.control(Mode.YAW, 0, 0, 0, 16384)
    assert ae[0] > ae[1]  # asks for a negative N to stop the turn


def test_gains_settable_and_key_steps():
    fc = FlightCore()
    assert (fc.gains.yaw_p, fc.gains.p1, fc.gains.p2) == (800.0, 0.4, 111.0)  # Table 1 magnitudes
    assert fc.adjust_gain("p1", 2) == pytest.approx(0.5)
    assert fc.adjust_gain("p2", -100) == 0.0
    fc.gains.yaw_p = 500.0
    fc.imu_sample(0, 0, -100, 0, 0, 16384, 0.0025)
    a = fc.control(Mode.YAW, 0, 0, 0, 16384)
    fc.gains.yaw_p = 1000.0
    b = fc.control(Mode.YAW, 0, 0, 0, 16384)
    assert b[0] - b[1] > a[0] - a[1] > 0


def test_panic_descends_from_the_level_it_found_senses_the_ground_and_ramps():
    fc = FlightCore()
    fc.ae = (400,) * 4  # hovering
    fc.vz, fc.height = 0.0, 5.0
    fc.enter_mode(Mode.PANIC)
    out = fc.control(Mode.PANIC, 0, 0, 0, 0)
    assert len(set(out)) == 1 and 300 < out[0] < 400  # a little less than it ran at: the descent starts
    assert P.PANIC_AE < P.AE_HOVER_NOMINAL
    fc.vz = -1.0  # descending at the rate it wants near the ground: the level holds
    held = [fc.control(Mode.PANIC, 0, 0, 0, 0)[0] for _ in range(40)]
    assert max(held) - min(held) <= 1
    fc.vz, fc.height = 0.0, 0.0  # on the floor: it stopped, the loop asks for ever less until the ground is sensed
    for _ in range(int(4.0 / 0.0025)):
        fc.control(Mode.PANIC, 0, 0, 0, 0)
    assert fc.panic_landed
    level = fc.ae[0]
    fc.panic_scale = 0.5  # the board's ramp
    assert fc.control(Mode.PANIC, 0, 0, 0, 0) == (level // 2,) * 4
    assert fc.panic_motors(0.0) == (0, 0, 0, 0)
    fc.enter_mode(Mode.SAFE)
    fc.control(Mode.SAFE, 0, 0, 0, 0)
    fc.enter_mode(Mode.PANIC)
    assert fc.control(Mode.PANIC, 0, 0, 0, 0) == (0, 0, 0, 0)  # motors were off: PANIC never spins them up
    assert fc.panic_scale == 1.0 and not fc.panic_landed  # entering PANIC restarts the descent


def test_height_mode_captures_the_set_point_and_the_stick_moves_it():
    fc = _calibrated()
    fc.height = 1.2
    fc.enter_mode(Mode.HEIGHT, 16384)
    fc.control(Mode.HEIGHT, 0, 0, 0, 16384)
    assert fc.setpoint == pytest.approx(1.2)
    for _ in range(400):
        fc.control(Mode.HEIGHT, 0, 0, 0, 32767, 0.0025)  # lift stick pushed up for 1 s
    assert fc.setpoint > 1.4
    ae_high = fc.control(Mode.HEIGHT, 0, 0, 0, 16384)
    assert min(ae_high) > 400  # below the raised set point: more lift


def test_raw_mode_hovers_on_the_on_board_filter():
    m = run_scenario("raw-hover", 9.0, seed=4)
    assert m["attitude_rms_deg"] < 1.0


def test_height_hold_keeps_its_height():
    m = run_scenario("height-hold", 12.0, seed=5)
    assert m["height_rms_m"] < 0.3


def test_height_entered_from_raw_flies_on_the_filter():
    fc = _calibrated()
    for _ in range(400):  # tilted 10 deg to the right according to the accelerometer
        fc.imu_sample(40, -30, 10, 200, 2845 - 100, 16135 + 116, 0.0025)
    fc.dmp_phi = 0.0  # a stale DMP says level

    def fly(mode: Mode, lift: int) -> tuple[int, int, int, int]:
        fc.enter_mode(mode, lift)
        return fc.control(mode, 0, 0, 0, lift)

    fly(Mode.RAW, 16384)
    a = fly(Mode.HEIGHT, 16384)
    assert a[1] > a[3]  # corrects the filter's right roll (right motor up), not the stale DMP's level
    fly(Mode.SAFE, 0)
    fly(Mode.FULL, 16384)
    b = fly(Mode.HEIGHT, 16384)
    assert b[1] == b[3]  # from FULL: the DMP path


def test_entering_calibration_clears_the_dmp_offsets():
    fc = FlightCore()
    fc.set_calibration(Calibration(dmp_phi=0.02, dmp_theta=-0.01))
    fc.dmp_sample(1.0, 0.0, 0.0, 0.0)
    assert fc.dmp_phi == pytest.approx(-0.02)
    fc.enter_mode(Mode.CALIBRATION)
    fc.dmp_sample(1.0, 0.0, 0.0, 0.0)
    assert (fc.dmp_phi, fc.dmp_theta) == (0.0, 0.0)
