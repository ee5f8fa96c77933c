"""The height estimator's thrust model (issue 35, an experiment off by default): the motors' commands predict the
specific force, so the vibration is not integrated; a force the model does not know (the floor) is taken from the
accelerometer at once; off, the filter is the one the C board twins (the thrust hint changes nothing)."""

from __future__ import annotations

import math
import random

from fcb_sim.estimation.height import THRUST_MODEL, HeightKalman, pa_per_metre

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
    kf.thrust_hint = u_of_t(0.0)  # flying already: the motors at their level
    kf.reset(P0)
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


def test_off_by_default_and_the_hint_changes_nothing_then() -> None:
    assert THRUST_MODEL is False
    a, b = HeightKalman(), HeightKalman()
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
    assert abs(kf.thrust_c * 0.8 * HOVER_U - G) < 0.3
    assert _rms(rows, 1, 1.0) < 0.1


def test_near_the_floor_the_accelerometer_is_integrated() -> None:
    # the legs may carry it there (a take-off, a touch-down with the motors running): the model waits
    kf = HeightKalman(thrust_model=True)
    _fly(kf, 1.0, u_of_t=lambda t: 0.8 * HOVER_U, support=0.2 * G, floor=0.0)
    assert not kf.model_on and kf.thrust_c == 0.0
