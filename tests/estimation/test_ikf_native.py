"""ikf in C (firmware/board/ikf_q.c in fixed point, ikf_f.c in doubles, through fcb_sim.estimation.native) against the
Python classes they translate (fcb_sim/estimation/ikf_fixed.py, ikf.py: the references): fed the same samples,
every integer (every double) of the state is the same after every sample checked, on recorded BROAD data and on
the worst inputs a sample can carry."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fcb_sim.estimation import make_filter
from fcb_sim.estimation.ikf import InertialKalmanFilter
from fcb_sim.estimation.ikf_fixed import Formats, InertialKalmanFilterQ
from fcb_sim.estimation.native import NativeIKF, NativeIKFQ, library, python_state, why_not
from tests.support.imu_data import _rows, _sample
from tests.support.paths import BROAD, EXCERPT


@pytest.fixture(autouse=True)
def _needs_c() -> None:
    if library() is None:
        pytest.skip(f"the C filter is not built here: {why_not()}")


def _float_state(f: InertialKalmanFilter) -> dict[str, float]:
    out = {k: getattr(f, k) for k in NativeIKF._STATE[:20]}
    out.update(gl0=f._gl[0], gl1=f._gl[1], gl2=f._gl[2], al0=f._al[0], al1=f._al[1], al2=f._al[2], rest_t=f._rest_t)
    return out


def _same_run(samples: list[tuple[float, ...]], every: int = 1, **kw: object) -> None:
    """The fixed-point pair and the float pair, side by side."""
    pairs = [(InertialKalmanFilterQ(**kw), NativeIKFQ(**kw), python_state)]  # type: ignore[arg-type]
    if "formats" not in kw and kw.get("decimation", 1) == 1:  # ikf_f.c has no decimation
        pairs.append((InertialKalmanFilter(**kw), NativeIKF(**kw), _float_state))  # type: ignore[arg-type]
    for py, c, state in pairs:
        for i, s in enumerate(samples):
            py.update(*s)
            c.update(*s)
            if i % every == 0 or i == len(samples) - 1:
                a, b = state(py), c.state()  # type: ignore[operator]
                assert a == b, (type(c).__name__, i, s, {k: (a[k], b[k]) for k in a if a[k] != b[k]})
                assert py.quaternion() == c.quaternion(), (type(c).__name__, i)
                assert py.at_rest == c.at_rest
        assert (py.roll, py.pitch, py.yaw) == (c.roll, c.pitch, c.yaw)


def test_the_excerpt_gives_the_same_bits() -> None:
    """BROAD trial 07's excerpt (in the repository): still, then fast rotation; every state after every sample."""
    _same_run(_rows(EXCERPT, 10**6))


def test_every_broad_trial_gives_the_same_bits() -> None:
    """The first 2500 samples of each of the 17 trials of ../shared/data/broad, compared every 10th sample."""
    paths = sorted(BROAD.glob("*.csv.gz")) if BROAD.is_dir() else []
    if not paths:
        pytest.skip(f"the BROAD trials are not at {BROAD} (the team's shared data beside the checkout)")
    for path in paths:
        _same_run(_rows(path, 2500), every=10)


def test_other_formats_and_parameters_give_the_same_bits() -> None:
    """All-Q16.16 and a filter at rest sooner with no latency: the constants are derived the same way."""
    rows = _rows(EXCERPT, 3000)
    _same_run(rows, every=7, formats=Formats.all_q16())
    _same_run(rows, every=7, latency=0.0, rest_time=0.2, tau=2.0, bias_max=0.5)


def test_decimation_gives_the_same_bits() -> None:
    """The gravity part every 4th (every 3rd) sample, the strapdown every one: C and Python agree on every sample."""
    rows = _rows(EXCERPT, 10**6)
    _same_run(rows, decimation=4)
    _same_run(rows[2000:3500], every=3, decimation=3, formats=Formats.all_q16())


def test_decimation_one_is_the_filter_of_before() -> None:
    """decimation=1 runs the gravity part every sample, with the constants of dt: the same states as the default."""
    rows = _rows(EXCERPT, 3000)[:2600]
    a, b = InertialKalmanFilterQ(), InertialKalmanFilterQ(decimation=1)
    fa, fb = InertialKalmanFilter(), InertialKalmanFilter(decimation=1)
    for r in rows:
        a.update(*r), b.update(*r), fa.update(*r), fb.update(*r)
        assert python_state(a) == python_state(b) and fa.quaternion() == fb.quaternion()


def test_decimation_is_checked_and_the_float_c_filter_refuses_it() -> None:
    for bad in (0, -1, 65, 2.0):
        with pytest.raises(ValueError):
            InertialKalmanFilter(decimation=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        NativeIKF(decimation=4)


def test_a_decimated_filter_from_the_integers_alone_runs_the_same() -> None:
    """The table carries the decimation (ikfq_consts_t.decim): ikfq_init_q gives the same states."""
    from fcb_sim.estimation.ikf_fixed import to_q

    rows = _rows(EXCERPT, 3000)[2400:2700]
    a, b = NativeIKFQ(decimation=4), NativeIKFQ()
    consts = a.consts(rows[0][6])
    assert consts["decim"] == 4
    b.init_from_consts(consts)
    for r in rows:
        g, acc = tuple(to_q(v, 16) for v in r[:3]), tuple(to_q(v, 16) for v in r[3:6])
        assert a.step_q(g, acc, r[6]) == b.step_q(g, acc, r[6])  # type: ignore[arg-type]
    assert a.state() == b.state()


@settings(max_examples=40, deadline=None)
@given(st.lists(_sample, min_size=1, max_size=40), st.integers(0, 300), st.sampled_from([1, 1, 4]))
def test_the_worst_samples_give_the_same_bits(wild: list[tuple[float, ...]], start: int, decimation: int) -> None:
    """Saturating rates, huge and non-finite values, zero and negative dt, mixed into real motion: the paths
    beyond 32 bits (products of unsaturated sums) agree too, decimated or not."""
    rows = _rows(EXCERPT, 4000)[3400 + start:3400 + start + 60]
    _same_run(rows[:30] + wild + rows[30:], decimation=decimation)


def test_a_huge_finite_sample_saturates() -> None:
    """1e305 m/s² is finite, but scaled to Q16.16 it is inf: the Python twin raised OverflowError (found by the
    property above); both saturate it now."""
    _same_run([(0.0, 0.0, 0.0, 0.0, 0.0, 9.81, 0.0025), (0.0, 0.0, 0.0, 1e305, -1e305, 9.81, 0.0025)])


def test_the_float_filter_skips_what_no_sensor_gives() -> None:
    """Finite but huge samples made the Python float filter raise (sin of an infinite half angle: ValueError; a
    division by zero) or turn NaN for ever (a dt of 1e300); found by the property above. They are skipped now."""
    for wild in [(1e300, 0, 0, 0, 0, 9.81, 0.0025), (0, 0, 0, 1e300, 1e300, 9.81, 0.0025),
                 (1.0, 0, 0, 0, 0, 9.81, 1e300)]:
        f = InertialKalmanFilter()
        f.update(0, 0, 0, 0, 0, 9.81, 0.0025)
        f.update(*wild)
        f.update(0.1, 0, 0, 0, 0, 9.81, 0.0025)
        assert all(math.isfinite(v) for v in f.quaternion())
    _same_run([(0, 0, 0, 0, 0, 9.81, 0.0025), (9999.0, 0, 0, 0, 0, 9.81, 0.0025), (0, 0, 0, 0, 99999.0, 0, 0.0025),
               (1.0, 0, 0, 0, 0, 9.81, 59.0), (0.1, 0, 0, 0, 0, 9.81, 0.0025)])


def test_upside_down_start() -> None:
    """The start's quaternion for a sensor hanging upside down (its saturating branch)."""
    _same_run([(0.0, 0.0, 0.0, 0.0, 1e-3, -9.81, 0.0025), (0.1, 0.0, 0.0, 0.0, 0.0, -9.81, 0.0025)] * 5)
    _same_run([(0.0, 0.0, 0.0, 0.0, 0.0, -9.81, 0.0025)] * 5)


def test_make_filter_picks_the_c_filter_and_the_reference_on_request() -> None:
    # the lite variant (tests/estimation/test_ikf_lite.py)
    assert isinstance(make_filter("ikf", fixed_point=True), NativeIKFQ)
    assert isinstance(make_filter("ikf", fixed_point=True, native=False), InertialKalmanFilterQ)
    f = make_filter("ikf")
    assert isinstance(f, NativeIKF) and (f.tau, f.latency) == (4.5, 0.0025)  # the parameters read through
    assert type(make_filter("ikf", native=False)) is InertialKalmanFilter


def test_without_the_c_filter_the_python_one_runs() -> None:
    """QUADRUPEL_PURE_PYTHON (as a machine without a compiler): the Python twin, and why."""
    code = ("from fcb_sim.estimation import make_filter; from fcb_sim.estimation.native import why_not; "
            "print(type(make_filter('ikf', fixed_point=True)).__name__, type(make_filter('ikf')).__name__, '|', "
            "why_not())")
    env = {**os.environ, "QUADRUPEL_PURE_PYTHON": "1"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "InertialKalmanFilterQL InertialKalmanFilter | QUADRUPEL_PURE_PYTHON is set"


def test_a_filter_set_up_from_the_integers_alone_runs_the_same() -> None:
    """ikfq_init_q with the constants ikfq_consts gives (what a board without doubles takes from a table): the same
    states as ikfq_init on the same Q.io samples."""
    from fcb_sim.estimation.ikf_fixed import to_q
    from fcb_sim.estimation.native import constants_c

    rows = _rows(EXCERPT, 3000)[2400:2700]
    a, b = NativeIKFQ(), NativeIKFQ()
    b.init_from_consts(a.consts(rows[0][6]))
    for r in rows:
        g, acc = tuple(to_q(v, 16) for v in r[:3]), tuple(to_q(v, 16) for v in r[3:6])
        assert a.step_q(g, acc, r[6]) == b.step_q(g, acc, r[6])  # type: ignore[arg-type]
    assert a.state() == b.state()
    assert ".dtq = 10737418" in constants_c(0.0025)  # 4 x 0.0025 in Q2.30: the lite filter's gravity step
    assert ".decim = 4, .lite = 1" in constants_c(0.0025)
