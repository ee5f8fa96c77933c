"""Sensor models: scales and chip axes, saturation, determinism per seed, DMP rate and latency, barometer spikes."""

from __future__ import annotations

import math
import random
import statistics

import pytest

from fcb_sim.estimation import quaternion_to_euler
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World


def _mean_imu(w: World, n: int = 400) -> list[float]:
    sums = [0.0] * 6
    for _ in range(n):
        for i, v in enumerate(w.imu()):
            sums[i] += v
    return [s / n for s in sums]


def test_at_rest_the_accelerometer_reads_one_g_up_and_the_gyro_only_its_offset():
    w = World(1)
    w.advance_to(0.1)
    gx, gy, gz, ax, ay, az = _mean_imu(w)
    assert az == pytest.approx(16384, abs=0.05 * 16384)
    assert abs(ax) < 0.05 * 16384 and abs(ay) < 0.05 * 16384
    offset = P.GYRO_BIAS_DPS * P.GYRO_LSB_PER_DPS
    assert max(abs(gx), abs(gy), abs(gz)) < offset + 5
    assert all(isinstance(v, int) for v in w.imu())  # quantised words


@pytest.mark.parametrize(("axis", "rate", "chip", "sign"), [("p", 1.0, 0, 1), ("q", 0.5, 1, -1), ("r", -0.25, 2, -1)])
def test_gyro_scale_and_chip_axes(axis, rate, chip, sign):
    def mean_gyro(value: float) -> float:
        w = World(2, height=50.0, airborne=True, ground=False, drag=False)
        w.set_motors(0, 0, 0, 0)
        w.w1 = w.w2 = w.w3 = w.w4 = 0.0
        setattr(w, axis, value)  # rad/s, body FRD; one axis at a time: no gyroscopic coupling
        xs = []
        for i in range(1, 81):
            w.advance_to(0.05 + i * 0.0025)  # the DLPF has settled after 50 ms
            xs.append(w.imu()[chip])
        return statistics.mean(xs)

    k = P.RATE_LSB_PER_RAD_S  # 939.65 LSB per rad/s = 16.4 per deg/s
    # chip x forward, y left, z up: q and r read with the opposite sign
    assert mean_gyro(rate) - mean_gyro(0.0) == pytest.approx(sign * rate * k, rel=0.02)


def test_saturation_at_the_int16_limits():
    w = World(3, height=5.0, airborne=True, ground=False)
    w.p = 50.0  # 2865 deg/s, beyond the +-2000 deg/s range
    w.mpu.reset_filter(50.0 * P.RATE_LSB_PER_RAD_S, 0, 0, 0, 0, 0)
    assert w.imu()[0] == 32767
    w.p = -50.0
    w.mpu.reset_filter(-50.0 * P.RATE_LSB_PER_RAD_S, 0, 0, 0, 0, 0)
    assert w.imu()[0] == -32768


def test_vibration_grows_with_rotor_speed():
    def spread(cmd: int) -> float:
        w = World(4, height=20.0, airborne=True, ground=False)
        w.set_motors(cmd, cmd, cmd, cmd)
        w.advance_to(0.3)
        xs = [w.imu()[3] for _ in range(400)]
        return statistics.pstdev(xs)

    assert spread(600) > 1.8 * spread(300)


def _trace(seed: int) -> list:
    w = World(seed, height=1.0, airborne=True)
    out = []
    for i in range(1, 201):
        w.advance_to(i * 0.0025)
        out.append((w.imu(), w.dmp(), w.baro(), w.battery()))
    return out


def test_the_same_seed_gives_the_same_samples():
    assert _trace(7) == _trace(7)
    assert _trace(7) != _trace(8)


def test_a_noise_table_drawn_again_is_the_same_as_a_fresh_draw(monkeypatch: pytest.MonkeyPatch):
    """A table taken from the memo gives the same samples, and leaves the generator where a fresh draw leaves it."""
    from fcb_sim.world import sensors

    fresh_rng = random.Random(11)
    monkeypatch.setattr(sensors, "_DRAWN", {})
    fresh = sensors.NoiseTable(fresh_rng, bits=10)
    again_rng = random.Random(11)
    again = sensors.NoiseTable(again_rng, bits=10)  # from the memo
    assert again.tab == fresh.tab and len(fresh.tab) == 1024
    assert [again_rng.random() for _ in range(5)] == [fresh_rng.random() for _ in range(5)]
    assert sensors.NoiseTable(random.Random(12), bits=10).tab != fresh.tab
    monkeypatch.setattr(sensors, "_DRAWN", {})
    assert sensors.NoiseTable(random.Random(11), bits=10).tab == fresh.tab  # (and drawn anew: the same)


def test_dmp_rate_latency_and_convention():
    w = World(5, height=5.0, airborne=True, ground=False)
    got = []
    for i in range(1, 401):
        w.advance_to(i * 0.0025)
        q = w.dmp()
        if q is not None:
            got.append((w.t, q))
    assert 99 <= len(got) <= 101  # 100 Hz
    # a roll starts at t = 1 s: the DMP shows it one latency later
    w.p = 1.0
    w.advance_to(1.0 + P.DMP_LATENCY - 0.002)
    w.dmp()
    w.advance_to(1.0 + P.DMP_LATENCY + 0.011)
    q = w.dmp()
    assert q is not None
    roll, pitch, _ = quaternion_to_euler(*q)
    assert roll > 0.005  # right side down reads positive roll in the chip's z-up frame
    w2 = World(5, height=5.0, airborne=True, theta=math.radians(10))
    w2.advance_to(0.05)
    q = w2.dmp()
    _, pitch, _ = quaternion_to_euler(*q)
    assert pitch == pytest.approx(-math.radians(10), abs=math.radians(0.5))  # nose up = negative z-up pitch


def test_barometer_scale_resolution_and_spikes():
    w = World(6, baro_spikes=False)
    p0 = statistics.mean(w.baro()[0] for _ in range(50))
    w.d = -1.0  # one metre up
    p1 = statistics.mean(w.baro()[0] for _ in range(50))
    assert p0 - p1 == pytest.approx(11.8, abs=1.0)  # Pa per metre near sea level
    assert w.baro()[1] == 2500  # 25.00 degC

    def worst_excursion(spikes: bool) -> tuple[float, int]:
        w = World(9, baro_spikes=spikes)
        xs = []
        for i in range(1, 4001):  # 200 s at 20 Hz
            w.advance_to(i * 0.05)
            xs.append(w.baro()[0])
        worst = 0.0
        for i in range(10, len(xs) - 10):
            worst = max(worst, abs(xs[i] - statistics.median(xs[i - 10:i + 11])))
        return worst, w.baro_model.spike_count

    quiet, n_quiet = worst_excursion(False)
    spiky, n_spiky = worst_excursion(True)
    assert n_quiet == 0 and quiet < 7.0
    assert n_spiky >= 5 and spiky > 8.0


def test_battery_adc_in_10mv_units():
    w = World(7, soc=1.0)
    assert w.battery() == pytest.approx(1260, abs=8)
