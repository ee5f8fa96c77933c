"""The variant of the fixed-point ikf cut to fit the Cortex-M0 (fcb_sim/estimation/ikf_lite.py, ikf_q.c with
``lite`` set; docs/attitude.md, "The variant that fits"): Python and C give the same integers after every sample,
on recorded BROAD data and on the worst samples; its cheap products and angles stay within their stated errors;
the gravity part is spread, and it stays as accurate as the float filter."""

from __future__ import annotations

import ctypes
import math
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fcb_sim.estimation import make_filter
from fcb_sim.estimation.ikf import InertialKalmanFilter
from fcb_sim.estimation.ikf_fixed import Formats, mul
from fcb_sim.estimation.ikf_lite import (
    LITE_DECIMATION,
    PIECES,
    InertialKalmanFilterQL,
    angles_lite,
    atan2_q15,
    qmul,
    worst_atan_error_deg,
)
from fcb_sim.estimation.native import NativeIKFQL, library, python_state, why_not
from tests.support.imu_data import _rows, _sample
from tests.support.paths import EXCERPT


@pytest.fixture(autouse=True)
def _needs_c() -> None:
    if library() is None:
        pytest.skip(f"the C filter is not built here: {why_not()}")


def _same_run(samples: list[tuple[float, ...]], every: int = 1, **kw: int) -> None:
    py, c = InertialKalmanFilterQL(**kw), NativeIKFQL(**kw)  # type: ignore[arg-type]
    for i, s in enumerate(samples):
        py.update(*s)
        c.update(*s)
        if i % every == 0 or i == len(samples) - 1:
            a, b = python_state(py), c.state()
            assert a == b, (i, s, {k: (a[k], b[k]) for k in a if a[k] != b[k]})
            assert py.quaternion() == c.quaternion(), i


@pytest.mark.parametrize("n", [1, 2, 3, LITE_DECIMATION, 8])
def test_python_and_c_give_the_same_bits(n: int) -> None:
    """BROAD trial 07's excerpt (still, then fast rotation), the gravity part spread over n samples."""
    _same_run(_rows(EXCERPT, 10**6), every=1 if n == LITE_DECIMATION else 7, decimation=n)


@settings(max_examples=40, deadline=None)
@given(st.lists(_sample, min_size=1, max_size=40), st.integers(0, 300), st.sampled_from([1, 4, 4, 8]))
def test_the_worst_samples_give_the_same_bits(wild: list[tuple[float, ...]], start: int, decimation: int) -> None:
    """Saturating rates, huge and non-finite values, zero and negative dt mixed into real motion: the guarded
    exact paths (a wild half step, force or swing) agree too."""
    rows = _rows(EXCERPT, 4000)[3400 + start:3400 + start + 60]
    _same_run(rows[:30] + wild + rows[30:], decimation=decimation)


def test_it_takes_the_default_formats_only() -> None:
    with pytest.raises(ValueError):
        InertialKalmanFilterQL(Formats.all_q16())
    assert InertialKalmanFilterQL().ref.decimation == LITE_DECIMATION


def test_make_filter_gives_the_lite_variant_in_fixed_point() -> None:
    assert type(make_filter("ikf", fixed_point=True)) is NativeIKFQL
    assert type(make_filter("ikf", fixed_point=True, native=False)) is InertialKalmanFilterQL


@settings(max_examples=300, deadline=None)
@given(st.integers(-(1 << 30), 1 << 30), st.integers(-(1 << 30), 1 << 30))
def test_qmul_is_within_six_units_below_the_exact_product(a: int, b: int) -> None:
    """The dropped low halves' product (under 4 units of 2^-30) and two floors: under 6 units below."""
    exact = (a * b) >> 30
    assert exact - 6 < qmul(a, b) <= exact


def test_the_gravity_part_is_in_pieces_one_a_sample() -> None:
    """With N = 4 each sample of a gravity step runs one piece: the phase cycles and each piece has its own."""
    n = LITE_DECIMATION
    assert sorted(p * n // PIECES for p in range(PIECES)) == list(range(n))


def test_the_atan2_is_within_its_stated_error() -> None:
    assert worst_atan_error_deg() < 0.011
    assert atan2_q15(0, 0) == 0 and atan2_q15(0, 5) == 0 and atan2_q15(0, -5) == 102944  # pi
    assert atan2_q15(5, 0) == 51472 and atan2_q15(-5, 0) == -51472


def test_the_angles_are_within_a_twentieth_of_a_degree() -> None:
    """Roll and pitch from the quaternion's top 16 bits against the float formulas, away from the pitch's
    +-90 deg where roll has no meaning (up to 80 deg of pitch; 0.03 deg up to 70)."""
    rng = random.Random(3)
    worst = 0.0
    for _ in range(5000):
        r, p, y = rng.uniform(-3.1, 3.1), rng.uniform(-1.4, 1.4), rng.uniform(-3.1, 3.1)
        cr, sr, cp, sp, cy, sy = (math.cos(r / 2), math.sin(r / 2), math.cos(p / 2), math.sin(p / 2),
                                  math.cos(y / 2), math.sin(y / 2))
        q = (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
             cr * cp * sy - sr * sp * cy)
        phi, theta = angles_lite(tuple(round(v * 2**30) for v in q))  # type: ignore[arg-type]
        w, x, yy, z = q
        phi_f = math.atan2(2 * (w * x + yy * z), 1 - 2 * (x * x + yy * yy))
        theta_f = -math.asin(2 * (w * yy - x * z))
        worst = max(worst, abs(math.remainder(phi / 65536 - phi_f, 2 * math.pi)), abs(theta / 65536 - theta_f))
    assert math.degrees(worst) < 0.05


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(-(1 << 31), (1 << 31) - 1), min_size=4, max_size=4),
       st.integers(-(1 << 31), (1 << 31) - 1), st.integers(-(1 << 31), (1 << 31) - 1))
def test_the_c_angles_are_the_python_ones(q: list[int], y: int, x: int) -> None:
    """ctlq_angles_lite and ctlq_atan2_q15 (ctl_q.c) against the Python twins on any unit quaternion's
    neighbourhood and any pair of int32."""
    lib = library()
    assert lib is not None
    assert lib.ctlq_atan2_q15(y, x) == atan2_q15(y, x)
    n = math.sqrt(sum(float(v) * v for v in q)) or 1.0
    qi = tuple(int(v / n * (1 << 30)) for v in q)
    phi, theta = ctypes.c_int32(), ctypes.c_int32()
    lib.ctlq_angles_lite((ctypes.c_int32 * 4)(*qi), ctypes.byref(phi), ctypes.byref(theta))
    assert (phi.value, theta.value) == angles_lite(qi)  # type: ignore[arg-type]


def test_it_stays_with_the_float_filter_on_fast_rotation() -> None:
    """On the excerpt's fast hand-held rotation the lite filter's vertical stays within 0.2 deg RMS (0.12) of the
    float filter's (bench.filters scores all BROAD trials: 0.5115 against 0.5108 deg mean)."""
    rows = _rows(EXCERPT, 10**6)
    lite, flt = InertialKalmanFilterQL(), InertialKalmanFilter()
    sq = 0.0
    for s in rows:
        lite.update(*s)
        flt.update(*s)
        a, b = lite.quaternion(), flt.quaternion()
        ua = (2 * (a[1] * a[3] - a[0] * a[2]), 2 * (a[2] * a[3] + a[0] * a[1]), 1 - 2 * (a[1] ** 2 + a[2] ** 2))
        ub = (2 * (b[1] * b[3] - b[0] * b[2]), 2 * (b[2] * b[3] + b[0] * b[1]), 1 - 2 * (b[1] ** 2 + b[2] ** 2))
        c = sum(p * q for p, q in zip(ua, ub, strict=True)) / math.sqrt(sum(p * p for p in ua) * sum(q * q for q in ub))
        sq += math.degrees(math.acos(max(-1.0, min(1.0, c)))) ** 2
    assert math.sqrt(sq / len(rows)) < 0.2


def test_mul_is_what_qmul_approximates() -> None:
    """The exact product it replaces: rounded, so within half a unit of (a b) / 2^30."""
    assert abs(mul(3 << 28, 5 << 27, 30) - qmul(3 << 28, 5 << 27)) <= 6


def test_a_run_gives_each_latency_the_filters_own_output() -> None:
    """NativeIKFQL.run (ikfq_run, bench.filters' latency grid in one C run): after every sample, the attitude at each
    latency is what a filter built with that latency gives."""
    rows = _rows(EXCERPT, 3000)[2000:3000]
    lats = (0.0, 0.0015, 0.0035)
    out = NativeIKFQL(tau=5.5).run(rows, lats)
    apart = [NativeIKFQL(tau=5.5, latency=lat) for lat in lats]
    for i, s in enumerate(rows):
        for j, f in enumerate(apart):
            f.update(*s)
            assert tuple(out[(i * len(lats) + j) * 4:(i * len(lats) + j) * 4 + 4]) == f.quaternion(), (i, j)
