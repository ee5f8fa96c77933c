"""The height estimator in contact (issue 35): a jolt against the motion is a hard stop (the speed zero, the height
unsure until the barometer pulls it in); a braking by the motors, longer than a surface's stop, is not; on the floor
it was calibrated on the height is 0 at once and the barometer's offset there goes into its reference."""

from __future__ import annotations

import random

from fcb_sim.estimation.height import (
    GROUND_REST_S,
    STOP_DOWN,
    STOP_UP,
    HeightKalman,
    pa_per_metre,
)

G = 9.80665
DT = 0.0025
P0 = 101325.0


def _run(kf: HeightKalman, rnd: random.Random, seconds: float, acc: float, h_true: float, *, n0: int = 0,
         baro_offset_m: float = 0.0, vib: float = 0.3) -> int:
    """Feed ``seconds`` of IMU samples of earth-up acceleration ``acc`` (level) and 20 Hz barometer at ``h_true``."""
    k = pa_per_metre(P0)
    n = n0
    for _ in range(round(seconds / DT)):
        kf.update_imu(rnd.gauss(0, vib), rnd.gauss(0, vib), G + acc + rnd.gauss(0, vib), 1, 0, 0, 0, DT)
        n += 1
        if n % 20 == 0:
            kf.update_baro(P0 - k * (h_true + baro_offset_m) + rnd.gauss(0, 1.2), 20 * DT)
    return n


def _flying_up(speed: float) -> tuple[HeightKalman, random.Random, int]:
    kf = HeightKalman()
    kf.reset(P0)
    rnd = random.Random(4)
    n = _run(kf, rnd, 0.2, 0.0, 0.0)  # thrust on (motors_off False): no ground state
    kf.vz = speed  # climbing at 'speed' (the filter's own state, as after a climb)
    return kf, rnd, n


def test_a_jolt_against_a_climb_is_a_stop_at_the_ceiling() -> None:
    kf, rnd, n = _flying_up(0.8)
    n = _run(kf, rnd, 0.01, -3 * G, 0.0, n0=n)  # 10 ms clipped at -2 g: the ceiling stopped it
    n = _run(kf, rnd, 0.01, 0.0, 0.0, n0=n)
    assert kf.stops == 1 and kf.stop_kind == STOP_UP
    assert 0.5 < kf.stop_speed < 0.9
    assert kf.vz == 0.0
    assert kf.unsure
    _run(kf, rnd, 2.0, 0.0, 0.0, n0=n)
    assert abs(kf.vz) < 0.1
    assert not kf.unsure


def test_braking_by_the_motors_is_no_stop() -> None:
    kf, rnd, n = _flying_up(1.0)
    _run(kf, rnd, 0.1, -G - 3.0, 0.0, n0=n)  # 100 ms beyond the threshold: no surface stops that slowly
    assert kf.stops == 0


def test_a_jolt_while_still_is_no_stop() -> None:
    kf, rnd, n = _flying_up(0.0)
    _run(kf, rnd, 0.01, 2 * G, 0.0, n0=n)  # a knock, the craft not moving
    assert kf.stops == 0


def test_a_landing_is_a_stop_down_and_the_floor_is_zero_at_once() -> None:
    kf, rnd, n = _flying_up(-0.6)
    kf.height = 0.3  # the estimate 0.3 m high at the touch-down (what issue 35 saw)
    n = _run(kf, rnd, 0.01, G, 0.0, n0=n)
    n = _run(kf, rnd, 0.01, 0.0, 0.0, n0=n)
    assert kf.stops == 1 and kf.stop_kind == STOP_DOWN
    kf.motors_off = True
    n = _run(kf, rnd, GROUND_REST_S + 0.1, 0.0, 0.0, n0=n, vib=0.02)
    assert kf.on_ground and kf.height == 0.0 and kf.vz == 0.0 and not kf.unsure


def test_on_the_floor_the_reference_follows_the_barometers_offset() -> None:
    """The barometer reads 0.25 m low on the floor: after the anchor the height is still 0 and a climb to 1 m reads
    1 m (the offset went into the reference), not 0.75 m."""
    kf = HeightKalman()
    kf.reset(P0)
    kf.motors_off = True
    rnd = random.Random(5)
    n = _run(kf, rnd, 2.5, 0.0, 0.0, baro_offset_m=-0.25, vib=0.02)
    assert kf.on_ground and kf.anchored and kf.height == 0.0
    kf.motors_off = False
    n = _run(kf, rnd, 0.3, 2.0, 0.0, n0=n, baro_offset_m=-0.25)  # lift-off (the accelerometer sees thrust)
    kf.height, kf.vz = 0.09, 0.6  # (the profile here is not integrated: put the filter on the climb)
    for i in range(200):  # 1 m/s² then hold: a simple ramp to 1 m read by the barometer
        h = min(1.0, 0.09 + 0.6 * (i + 1) * DT * 2)
        n = _run(kf, rnd, DT, 0.0, h, n0=n, baro_offset_m=-0.25)
    n = _run(kf, rnd, 3.0, 0.0, 1.0, n0=n, baro_offset_m=-0.25)
    assert abs(kf.height - 1.0) < 0.12


def test_a_table_the_estimate_missed_is_not_taken_for_the_floor() -> None:
    """Set down (motors off) on a 0.8 m table while the estimate still read 0.2 m: snapped to the floor at first,
    but the barometer disagrees by more than GROUND_SNAP_M, so its height stands and the reference is untouched."""
    kf = HeightKalman()
    kf.reset(P0)
    rnd = random.Random(6)
    n = _run(kf, rnd, 0.2, 0.0, 0.8)
    kf.height, kf.vz = 0.2, 0.0
    p_ref = kf.p_ref
    kf.motors_off = True
    _run(kf, rnd, 2.5, 0.0, 0.8, n0=n, vib=0.02)
    assert kf.on_ground and kf.anchored
    assert abs(kf.height - 0.8) < 0.1 and kf.p_ref == p_ref
