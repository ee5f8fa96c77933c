"""The height estimator's thrust model (issue 35, on by default on both boards): the motors' commands, scaled by the
pack's voltage, predict the specific force, so the vibration is not integrated; a force the model does not know (a
surface) is taken from the accelerometer at once; on the pad with the motors running the legs carry the craft until
the modelled thrust passes the weight, and the climb is integrated from the floor at once; off, the thrust hint
changes nothing."""

from __future__ import annotations

import math
import random

import pytest

from fcb_sim.estimation.height import DRAG_PER_S, THRUST_C0, THRUST_MODEL, V_REF, HeightKalman, pa_per_metre

G = 9.80665
DT = 0.0025
P0 = 101325.0
HOVER_U = 4 * 400.0**2  # ae² of four motors at 400
VIB = 0.15 * G  # m/s² rms per sample: the motors' vibration at hover


def _fly(kf: HeightKalman, seconds: float, *, seed: int = 3, u_of_t=lambda t: HOVER_U,
         support: float = 0.0, floor: float = -1.0) -> list[tuple[float, float, float]]:
    """Level flight where the specific force is G * u / HOVER_U (+ ``support``, a surface's push, m/s²), the true
    height integrated from it, ``floor`` m below the reset point (1 m up: the model's height); returns
    (t, estimated vz - true vz, estimated h - true h) per sample."""
    rnd = random.Random(seed)
    k = pa_per_metre(P0)
    kf.thrust_hint = u_of_t(0.0)
    kf.reset(P0)
    kf._u = kf._u_fast = kf.thrust_hint  # flying already: the rotors at their level
    kf.ground_ref = floor
    h = v = 0.0
    out = []
    for n in range(round(seconds / DT)):
        t = n * DT
        u = u_of_t(t)
        kf.thrust_hint = u
        f = G * u / HOVER_U + support
        acc = f - G if support == 0.0 else 0.0
        v += acc * DT
        h += v * DT
        kf.update_imu(rnd.gauss(0, VIB), rnd.gauss(0, VIB), f + rnd.gauss(0, VIB), 1, 0, 0, 0, DT)
        if n % 20 == 19:
            kf.update_baro(P0 - k * h + rnd.gauss(0, 1.2), 20 * DT)
        out.append((t, kf.vz - v, kf.height - h))
    return out


def _rms(rows: list[tuple[float, float, float]], i: int, after: float) -> float:
    xs = [r[i] for r in rows if r[0] >= after]
    return math.sqrt(sum(x * x for x in xs) / len(xs))


def test_on_by_default_and_off_the_hint_changes_nothing() -> None:
    assert THRUST_MODEL is True and HeightKalman().thrust_model
    a, b = HeightKalman(thrust_model=False), HeightKalman(thrust_model=False)
    ra = _fly(a, 3.0)
    b.thrust_hint = 0.0
    rb = _fly(b, 3.0, u_of_t=lambda t: HOVER_U)  # the same flight: the hint is set, the model is off
    assert not a.model_on and not b.model_on
    assert ra == rb


def test_at_hover_the_model_lowers_the_vz_noise() -> None:
    off = _rms(_fly(HeightKalman(thrust_model=False), 20.0), 1, 2.0)
    on_kf = HeightKalman(thrust_model=True)
    on = _rms(_fly(on_kf, 20.0), 1, 2.0)
    assert on_kf.model_on
    assert on < 0.8 * off, (on, off)  # 0.050 against 0.067 m/s rms


def test_a_push_the_model_does_not_know_is_taken_from_the_accelerometer() -> None:
    # standing on a surface with 80 % of the hover thrust: the accelerometer reads 1 g; the model alone would fall
    kf = HeightKalman(thrust_model=True)
    rows = _fly(kf, 3.0, u_of_t=lambda t: 0.8 * HOVER_U, support=0.2 * G)
    assert not kf.model_on  # the gate: the accelerometer's mean is 2 m/s² off the model's
    assert kf.thrust_c == THRUST_C0  # and the gain learnt nothing from the push (the craft did not change)
    assert _rms(rows, 1, 1.0) < 0.1


def test_near_the_floor_the_accelerometer_is_integrated() -> None:
    # the legs may carry it there (a take-off, a touch-down with the motors running): the model waits
    kf = HeightKalman(thrust_model=True)
    _fly(kf, 1.0, u_of_t=lambda t: 0.8 * HOVER_U, support=0.2 * G, floor=0.0)
    assert not kf.model_on and not kf.on_legs  # not from a pad it stood on: nothing says the legs carry it


def _take_off(kf: HeightKalman, *, supply_v: float = V_REF, seed: int = 5, ramp_s: float = 2.0,
              seconds: float = 4.0, told: bool = True) -> list[tuple[float, float, float, float]]:
    """Calibrated on the pad (motors off, at rest), then the lift ramps from 60 % to 130 % of the hover thrust over
    ``ramp_s`` (a held key) and stays; the ESCs' speed follows the pack, so the thrust is G u (v / V_REF)² / HOVER_U
    (u the commands lagged by the rotors' 30 ms);
    the floor carries what the thrust does not; ``told``: the filter is told the pack's voltage. Returns (t, true
    h, estimated h, estimated vz) per sample."""
    rnd = random.Random(seed)
    k = pa_per_metre(P0)
    told_sq = (supply_v / V_REF) ** 2 if told else 1.0  # what the flight core scales the hint by
    kf.reset(P0)
    kf.motors_off = True
    for n in range(400):  # 1 s at rest: the ground state, anchored
        kf.update_imu(rnd.gauss(0, 0.03), rnd.gauss(0, 0.03), G + rnd.gauss(0, 0.03), 1, 0, 0, 0, DT)
        if n % 20 == 19:
            kf.update_baro(P0 + rnd.gauss(0, 1.2), 20 * DT)
    assert kf.on_ground
    kf.motors_off = False
    h = v = 0.0
    u = 0.6 * HOVER_U  # the motors spun up on the pad (where the ramp starts)
    out = []
    s2 = (supply_v / V_REF) ** 2
    for n in range(round(seconds / DT)):
        t = n * DT
        cmd = HOVER_U * (0.6 + 0.7 * min(1.0, t / ramp_s))
        kf.thrust_hint = cmd * told_sq
        u += (cmd - u) * DT / (0.03 + DT)  # the rotors follow in 30 ms
        f = G * u * s2 / HOVER_U - DRAG_PER_S * v
        acc = f - G
        if h <= 0.0 and acc < 0.0:
            acc, f = 0.0, G  # on the floor: it carries the rest
        v += acc * DT
        h = max(0.0, h + v * DT)
        vib = VIB * min(1.0, u / HOVER_U)
        kf.update_imu(rnd.gauss(0, vib), rnd.gauss(0, vib), f + rnd.gauss(0, vib), 1, 0, 0, 0, DT)
        if n % 20 == 19:
            kf.update_baro(P0 - k * h + rnd.gauss(0, 1.2), 20 * DT)
        out.append((t, h, kf.height, kf.vz))
    return out


def _errors(rows: list[tuple[float, float, float, float]]) -> tuple[float, float, float]:
    """When it lifts (s), the largest |estimate| on the pad before, the largest error over the first 0.1 m."""
    lift = next(t for t, h, _e, _v in rows if h > 0.0)
    pad = max(abs(e) for t, _h, e, _v in rows if t < lift - 0.05)
    early = max(abs(e - h) for _t, h, e, _v in rows if 0.0 < h < 0.1)
    return lift, pad, early


@pytest.mark.parametrize("seed", [5, 6])
def test_on_the_legs_the_height_is_held_and_the_climb_is_followed_from_the_floor(seed: int) -> None:
    kf = HeightKalman()
    rows = _take_off(kf, seed=seed)
    lift, pad, early = _errors(rows)
    assert 1.1 < lift < 1.3  # the thrust passes the weight at 1.14 s of the ramp (40 % of its 70 % over 2 s)
    assert pad == 0.0  # the legs carry it: no vibration integrated, no barometer noise
    assert early < 0.025, early  # the climb from the floor at once (0.012-0.021 m): the pilot's 0.05 m seen in time
    climb = [(h, e) for _t, h, e, _v in rows if 0.0 < h < 1.0]
    assert max(abs(e - h) for h, e in climb) < 0.1
    assert not kf.on_legs and kf.model_on


@pytest.mark.parametrize("seed", [5, 6])
def test_without_the_legs_the_estimate_wanders_on_the_pad_and_lags_the_lift_off(seed: int) -> None:
    # the same take-off, the accelerometer integrated (the thrust model off): what the legs fix
    _lift, pad, early = _errors(_take_off(HeightKalman(thrust_model=False), seed=seed))
    assert pad > 0.025 and early > 0.03, (pad, early)  # 0.042-0.058 m and 0.031-0.055 m


def test_the_packs_voltage_scales_the_model() -> None:
    # a full pack (12.4 V) makes more thrust of the same commands: the lift-off comes earlier, and the model knows
    lift, pad, early = _errors(_take_off(HeightKalman(), supply_v=12.4))
    assert lift < 0.8  # at 0.73 s: (12.4 / 11.4)² = 1.18, the weight at 85 % of the hover commands
    assert pad == 0.0 and early < 0.025, early
    # not told the voltage, the model waits for the nominal pack's thrust: the estimate stays on the pad too long
    _lift, _pad, blind = _errors(_take_off(HeightKalman(), supply_v=12.4, told=False))
    assert blind > 0.05, blind
