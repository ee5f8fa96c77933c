"""The default attitude filter (ikf): it never diverges (every BROAD trial, adversarial inputs), its fixed-point twin
stays with it, its parts do what docs/attitude.md says, and the bench's leave-one-out picks on other trials only."""

from __future__ import annotations

import gzip
import math
import random
from pathlib import Path

import pytest

from fcb_sim.estimation import BEST, make_filter
from fcb_sim.estimation.ikf import InertialKalmanFilter
from fcb_sim.estimation.ikf_fixed import Formats, InertialKalmanFilterQ, div, mul, sqrt, to_q
from tests.support.paths import BROAD, EXCERPT

G = 9.81
DT = 0.0025


def read_trial(path: Path, every: int = 1) -> tuple[list[tuple[float, ...]], list[tuple[float, ...] | None]]:
    """(t, gx..az) rows and the true quaternion of the scored rows (None elsewhere)."""
    rows, truth = [], []
    with gzip.open(path, "rt", newline="") as fh:
        next(fh)
        for i, line in enumerate(fh):  # (plain numbers, no quoting: split is a third cheaper than csv here)
            row = line.split(",")
            rows.append((float(row[0]), float(row[1]), float(row[2]), float(row[3]), float(row[4]), float(row[5]),
                         float(row[6])))
            scored = i % every == 0 and row[11].strip() == "1" and row[7] != ""
            truth.append((float(row[7]), float(row[8]), float(row[9]), float(row[10])) if scored else None)
    return rows, truth


def up(q: tuple[float, ...]) -> tuple[float, float, float]:
    w, x, y, z = q
    v = (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)
    n = math.sqrt(sum(c * c for c in v))
    return v[0] / n, v[1] / n, v[2] / n


def tilt_between(qa: tuple[float, ...], qb: tuple[float, ...]) -> float:
    c = sum(a * b for a, b in zip(up(qa), up(qb), strict=True))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def replay_errors(f, rows, truth) -> list[float]:
    """Inclination errors (deg) of filter f over the scored rows; asserts a finite unit quaternion throughout."""
    errs = []
    prev = rows[0][0] - (rows[1][0] - rows[0][0])
    update = f.update
    for (t, gx, gy, gz, ax, ay, az), q_true in zip(rows, truth, strict=True):
        update(gx, gy, gz, ax, ay, az, t - prev)
        prev = t
        if q_true is not None:
            q = f.quaternion()
            assert abs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0) < 1e-6
            errs.append(tilt_between(q, q_true))
    return errs


def rms(v: list[float]) -> float:
    return math.sqrt(sum(x * x for x in v) / len(v))


def specific_force(roll: float, pitch: float) -> tuple[float, float, float]:
    return -G * math.sin(pitch), G * math.sin(roll) * math.cos(pitch), G * math.cos(roll) * math.cos(pitch)


def level_tilt_deg(f) -> float:
    """The filter's tilt from level (deg)."""
    return math.degrees(math.acos(max(-1.0, min(1.0, up(f.quaternion())[2]))))


def make(fixed: bool):
    return make_filter(BEST, fixed_point=fixed)


# --- it never diverges: real data --------------------------------------------------------------------------


@pytest.mark.parametrize("fixed", [False, True])
def test_excerpt_fast_rotation(fixed: bool) -> None:
    """BROAD trial 07, 22 s excerpt (8.5 s still, then fast hand-held rotation): 0.52° RMS, 1.6° at worst (VQF
    offline scores 0.96° on the whole trial). Bounds 0.8° and 3°."""
    rows, truth = read_trial(EXCERPT)
    errs = replay_errors(make(fixed), rows, truth)
    assert len(errs) > 3000
    assert rms(errs) < 0.8
    assert max(errs) < 3.0


def test_fixed_point_twin_on_real_data() -> None:
    """The exact fixed-point twin within 0.01° RMS of the float ikf (measured 0.0002° on every trial); the variant
    that fits the M0, which make_filter gives in fixed point, within 0.25° RMS on this fast rotation (measured
    0.17°; its gravity part spread over 4 samples: bench.filters scores it 0.5115° mean against 0.5108°)."""
    from fcb_sim.estimation.ikf_fixed import InertialKalmanFilterQ

    rows, truth = read_trial(EXCERPT)
    a, b, c = make(False), InertialKalmanFilterQ(), make(True)
    prev = rows[0][0] - 0.0035
    diffs, lite = [], []
    for (t, *s), q_true in zip(rows, truth, strict=True):
        for f in (a, b, c):
            f.update(*s, t - prev)
        prev = t
        if q_true is not None:
            diffs.append(tilt_between(a.quaternion(), b.quaternion()))
            lite.append(tilt_between(a.quaternion(), c.quaternion()))
    assert rms(diffs) < 0.01
    assert 0.0 < max(diffs) < 0.05  # different arithmetic, not the same code
    assert rms(lite) < 0.25


def test_every_broad_trial_has_a_bounded_error() -> None:
    """The default filter over all 17 trials of ../shared/data/broad (every 4th scored row compared): no trial
    over 1.5° RMS (the issue's bound; the worst is 1.09°, trial 08) nor 6° at any instant. The filter is the one the
    board flies: ikf_f.c where it builds (the same doubles as ikf.py, tests/estimation/test_ikf_native.py); its
    920,000 updates cost under half the Python reference's CPU."""
    paths = sorted(BROAD.glob("*.csv.gz")) if BROAD.is_dir() else []
    if not paths:
        pytest.skip(f"the BROAD trials are not at {BROAD} (the team's shared data beside the checkout)")
    worst = {}
    for path in paths:
        rows, truth = read_trial(path, every=4)
        errs = replay_errors(make_filter(BEST), rows, truth)
        worst[path.name[:2]] = (rms(errs), max(errs))
    assert len(worst) == 17
    assert max(r for r, _ in worst.values()) < 1.5, worst
    assert max(m for _, m in worst.values()) < 6.0, worst


# --- it never diverges: adversarial inputs ------------------------------------------------------------------


def _shaken(seconds: float, seed: int = 1, sat: float | None = None, bias_step: tuple[float, float] | None = None):
    """A body swinging in roll and pitch (±40°, 0.5-0.8 Hz) while thrown sideways (±1.5 g), as a quad flying
    hard: yields (gyro, accel, dt, true roll, true pitch). ``sat`` clips each accelerometer axis; ``bias_step``
    (time, rad/s) adds a gyro bias on x from that time on."""
    rnd = random.Random(seed)
    t = 0.0
    while t < seconds:
        r = math.radians(40) * math.sin(2 * math.pi * 0.5 * t)
        p = math.radians(30) * math.sin(2 * math.pi * 0.8 * t + 1)
        dr = math.radians(40) * 2 * math.pi * 0.5 * math.cos(2 * math.pi * 0.5 * t)
        dp = math.radians(30) * 2 * math.pi * 0.8 * math.cos(2 * math.pi * 0.8 * t + 1)
        # body rates of a ZYX (yaw 0) attitude: p = dr - sin(pitch) dyaw; q = cos(r) dp; r = -sin(r) dp
        gx, gy, gz = dr, math.cos(r) * dp, -math.sin(r) * dp
        # earth-frame acceleration: 1.5 g sideways at 1.3 Hz, 0.5 g fore-aft at 0.9 Hz (bounded velocity)
        aex = 0.5 * G * math.sin(2 * math.pi * 0.9 * t)
        aey = 1.5 * G * math.sin(2 * math.pi * 1.3 * t)
        cr, sr, cp, sp = math.cos(r), math.sin(r), math.cos(p), math.sin(p)
        # specific force in body = R^T (a + g z); R = Ry(p) Rx(r) (yaw 0)
        fx_e, fy_e, fz_e = aex, aey, G
        ax = cp * fx_e - sp * fz_e
        ay = sr * sp * fx_e + cr * fy_e + sr * cp * fz_e
        az = cr * sp * fx_e - sr * fy_e + cr * cp * fz_e
        if sat is not None:
            ax, ay, az = (max(-sat, min(sat, v)) for v in (ax, ay, az))
        if bias_step is not None and t >= bias_step[0]:
            gx += bias_step[1]
        n = rnd.gauss
        yield (gx + n(0, 0.01), gy + n(0, 0.01), gz + n(0, 0.01), ax + n(0, 0.2), ay + n(0, 0.2), az + n(0, 0.2),
               DT, r, p)
        t += DT


def _tilt_error(f, r: float, p: float) -> float:
    from fcb_sim.estimation.base import euler_to_quaternion

    return tilt_between(f.quaternion(), euler_to_quaternion(r, p, 0.0))


@pytest.mark.parametrize("fixed", [False, True])
def test_thrown_side_to_side(fixed: bool) -> None:
    """±1.5 g sideways while swinging ±40°: the accelerometer alone would be 56° off; after 10 s the filter stays
    within 2.5° (measured 1.55°; RMS 0.69°, bound 1°). This synthetic sensor has no delay, so the latency
    prediction costs here (0.49° without it)."""
    f = make(fixed)
    errs = []
    for k, (*s, dt, r, p) in enumerate(_shaken(30.0)):
        f.update(*s, dt)
        if k * DT > 10.0:
            errs.append(_tilt_error(f, r, p))
    assert rms(errs) < 1.0
    assert max(errs) < 2.5


@pytest.mark.parametrize("fixed", [False, True])
def test_saturated_accelerometer(fixed: bool) -> None:
    """The same flight read by an accelerometer clipping at ±2 g (the MPU6050's range on the board): a sensor
    lying about the force; the error stays bounded (5°) and shrinks once the clipping stops."""
    f = make(fixed)
    worst = 0.0
    for k, (*s, dt, r, p) in enumerate(_shaken(20.0, sat=2 * G * 0.75)):  # clipping most swings
        f.update(*s, dt)
        if k * DT > 5.0:
            worst = max(worst, _tilt_error(f, r, p))
    assert worst < 5.0
    last = (0.0, 0.0)
    for *s, dt, r, p in _shaken(20.0, seed=2):
        f.update(*s, dt)
        last = (r, p)
    assert _tilt_error(f, *last) < 1.5


@pytest.mark.parametrize("fixed", [False, True])
def test_gyro_bias_step_in_motion_and_at_rest(fixed: bool) -> None:
    """A 1 °/s gyro bias step in continuous motion: the filter has no bias state in motion, the gravity estimate
    absorbs it with a lag, sqrt 2 * bias * tau / sqrt 2 = 4.5 s * 1 °/s in the worst case; it stays under 5°.
    Once still, rest detection learns the new bias within seconds."""
    step = math.radians(1.0)
    f = make(fixed)
    worst = 0.0
    for k, (*s, dt, r, p) in enumerate(_shaken(40.0, bias_step=(10.0, step))):
        f.update(*s, dt)
        if k * DT > 5.0:
            worst = max(worst, _tilt_error(f, r, p))
    assert worst < 5.0
    ax, ay, az = specific_force(0.2, -0.1)
    for _ in range(int(15.0 / DT)):
        f.update(step, 0.0, 0.0, ax, ay, az, DT)
    assert f.bias[0] == pytest.approx(step, abs=math.radians(0.02))
    assert _tilt_error(f, 0.2, -0.1) < 0.5


@pytest.mark.parametrize("fixed", [False, True])
def test_thirty_seconds_of_free_fall(fixed: bool) -> None:
    """30 s with the accelerometer at zero (free fall) while tumbling: no gravity, nothing to correct with, so
    the filter coasts on the gyro (the attitude integrates exactly) and picks gravity up again afterwards."""
    f = make(fixed)
    ax, ay, az = specific_force(0.0, 0.0)
    for _ in range(int(2.0 / DT)):
        f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
    roll = 0.0
    for k in range(int(30.0 / DT)):
        rate = 0.5 * math.sin(2 * math.pi * 0.2 * k * DT)
        roll += rate * DT
        f.update(rate, 0.0, 0.0, 0.0, 0.0, 0.0, DT)
    assert math.degrees(abs(f.roll - roll)) < 0.5  # pure integration of a known rate
    for _ in range(int(20.0 / DT)):
        f.update(0.0, 0.0, 0.0, *specific_force(roll, 0.0), DT)
    assert _tilt_error(f, roll, 0.0) < 0.5


@pytest.mark.parametrize("fixed", [False, True])
def test_zeros_and_garbage_never_make_nan(fixed: bool) -> None:
    """All-zero samples from the start (a dead sensor), then NaN, inf, a zero and a negative dt, then a huge rate
    and force: every output stays finite and the quaternion a unit one."""
    f = make(fixed)
    for _ in range(1000):
        f.update(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, DT)
    assert f.quaternion() == (1.0, 0.0, 0.0, 0.0)
    assert (f.roll, f.pitch, f.yaw) == (0.0, 0.0, 0.0)
    ax, ay, az = specific_force(0.3, 0.2)
    for _ in range(100):
        f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
    bad = [(math.nan, 0, 0, ax, ay, az, DT), (0, 0, 0, math.inf, ay, az, DT), (0, 0, 0, ax, ay, az, 0.0),
           (0, 0, 0, ax, ay, az, -1.0), (0, 0, 0, ax, ay, az, math.nan), (35.0, -35.0, 35.0, 1e3, -1e3, 1e3, DT),
           (0, 0, 0, 0, 0, 0, 10.0), (1e3, 1e3, 1e3, 0, 0, 0, DT)]
    for _ in range(200):
        for s in bad:
            f.update(*s)
            q = f.quaternion()
            assert all(math.isfinite(c) for c in q)
            assert abs(sum(c * c for c in q) - 1.0) < 1e-5
            assert all(math.isfinite(a) for a in (f.roll, f.pitch, f.yaw))
    for _ in range(int(30.0 / DT)):
        f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
    assert _tilt_error(f, 0.3, 0.2) < 0.5  # and it recovers


# --- the parts ----------------------------------------------------------------------------------------------


def test_still_it_is_vqfs_butterworth() -> None:
    """Without rotation the filter is a 2nd-order Butterworth of time constant tau on the accelerometer (VQF's):
    a small tilt step in the accelerometer alone is followed with a 4 % overshoot (the Butterworth's 4.3 %)."""
    f = InertialKalmanFilter(rest_r=1.0)  # rest's faster settling off: the plain filter
    ax, ay, az = specific_force(0.0, 0.0)
    for _ in range(int(20.0 / DT)):
        f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
    step = math.radians(2.0)
    ax, ay, az = specific_force(step, 0.0)
    peak = 0.0
    for _ in range(int(30.0 / DT)):
        f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
        peak = max(peak, f.roll)
    assert peak / step == pytest.approx(1.043, abs=0.01)
    assert f.roll == pytest.approx(step, rel=0.01)


def test_rest_settles_faster() -> None:
    """Held still, the velocity is known to be zero: a 10° tilt is taken up in about a third of the time."""

    def settle(rest_r: float) -> float:
        f = InertialKalmanFilter(rest_r=rest_r)
        ax, ay, az = specific_force(0.0, 0.0)
        for _ in range(int(5.0 / DT)):
            f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
        ax, ay, az = specific_force(math.radians(10.0), 0.0)
        t = 0.0
        while f.roll < math.radians(9.0):
            f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
            t += DT
        return t

    assert settle(0.01) < 0.4 * settle(1.0)


def test_latency_prediction() -> None:
    """The output runs `latency` s ahead along the current rate; the state itself does not."""
    a, b = InertialKalmanFilter(latency=0.0), InertialKalmanFilter(latency=0.01)
    ax, ay, az = specific_force(0.0, 0.0)
    for f in (a, b):
        for _ in range(400):
            f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
        for _ in range(40):
            f.update(1.0, 0.0, 0.0, ax, ay, az, DT)
    assert (a.w, a.x, a.y, a.z) == (b.w, b.x, b.y, b.z)
    assert math.degrees(b.roll - a.roll) == pytest.approx(math.degrees(0.01), abs=1e-6)


def test_drift_state_learns_a_drift_per_turn() -> None:
    """A gyro whose x axis reads 1 % of |rate| too much (a rectified error: the drift grows with the turning
    whichever way it goes, as BROAD's IMU shows in motion) makes gravity drift in proportion to the turn; D
    takes it up: 0.27° RMS against 1.8° without it (drift_init = 0)."""

    def run(drift_init: float) -> float:
        f = InertialKalmanFilter(drift_init=drift_init, latency=0.0)
        errs = []
        for k, (gx, gy, gz, ax, ay, az, dt, r, p) in enumerate(_shaken(60.0)):
            f.update(gx + 0.01 * abs(gx), gy, gz, ax, ay, az, dt)
            if k * DT > 30.0:
                errs.append(_tilt_error(f, r, p))
        return rms(errs)

    assert run(1e-3) < 0.3 * run(0.0)


def test_parameters_are_checked() -> None:
    with pytest.raises(ValueError):
        InertialKalmanFilter(tau=0.0)
    with pytest.raises(ValueError):
        InertialKalmanFilter(latency=-1.0)


def test_fixed_point_primitives() -> None:
    """mul/div/sqrt are fix16_mul/fix16_div/fix16_sqrt for 16 fractional bits, rounded and saturated."""
    one = 1 << 16
    assert mul(3 * one, one // 2, 16) == 3 * one // 2
    assert mul(-3, 1 << 15, 16) == -2  # -1.5 LSB rounds away from zero
    assert mul(1 << 30, 1 << 30, 16) == 0x7FFFFFFF
    assert div(one, 3 * one, 16) == 21845
    assert div(5, 0, 16) == 0x7FFFFFFF and div(-5, 0, 16) == -0x80000000
    assert sqrt(4 * one, 16) == 2 * one
    assert to_q(1.0, 30) == 1 << 30 and to_q(-1e12, 16) == -0x80000000


def test_all_q16_loses_the_small_steps() -> None:
    """Every state in Q16.16 (the report's format throughout): a 6 °/s turn, 8.6 LSB of quaternion per step,
    integrates visibly wrong; the chosen formats integrate it within 0.01°."""
    ax, ay, az = specific_force(0.0, 0.0)
    ends = {}
    for name, fmt in (("chosen", Formats()), ("q16", Formats.all_q16())):
        f = InertialKalmanFilterQ(fmt, latency=0.0)
        f.update(0.0, 0.0, 0.0, ax, ay, az, DT)
        for _ in range(int(10.0 / DT)):
            # 6 °/s about z: above the 5 °/s a rest may hold (so not learnt as a bias); yaw, which the
            # accelerometer cannot correct
            f.update(0.0, 0.0, math.radians(6.0), ax, ay, az, DT)
        ends[name] = math.degrees(f.yaw)
    assert ends["chosen"] == pytest.approx(60.0, abs=0.01)
    assert abs(ends["q16"] - 60.0) > 0.5


def test_leave_one_out_never_uses_the_scored_trial() -> None:
    """bench.filters' LOO: the pick for a trial is the best grid point on the others only."""
    np = pytest.importorskip("numpy")
    from tests.support.scoring import leave_one_out

    grid = np.array([[1.0, 2.0, 0.1],  # trial 0 alone loves point 2
                     [1.0, 1.0, 5.0],
                     [1.0, 1.0, 5.0]])
    picks, scores = leave_one_out(grid)
    assert picks[0] in (0, 1) and scores[0] in (1.0, 2.0)  # not point 2, which only trial 0 likes
    assert picks[1] == 0 and picks[2] == 0


# --- in the simulator ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("fixed", [False, True])
def test_raw_path_holds_attitude_with_the_stick_thrown_side_to_side(fixed: bool) -> None:
    """The raw-throw scenario (RAW, roll stick +-20° reversing every 0.6 s): the on-board filter's attitude
    against the simulator's truth stays under 1° RMS (measured 0.64°, 0.67° fixed point; the DMP in the same
    flight, FULL, 1.7°)."""
    from fcb_sim.lab.scenarios import run_scenario

    m = run_scenario("raw-throw", 20.0, seed=1, fixed_point=fixed)
    assert m["attitude_max_deg"] > 15.0  # it did swing
    assert m["estimate_rms_deg"] < 1.0
    assert m["estimate_max_deg"] < 2.0


@pytest.mark.parametrize("fixed", [False, True])
def test_decimated_gravity_part_on_real_data(fixed: bool) -> None:
    """The gravity part every 4th sample, the gyro every one (docs/attitude.md, "Decimation"): on the fast-rotation
    excerpt as accurate as every sample within 0.05° RMS (BROAD, all 17 trials: 0.513° against 0.511°)."""
    rows, truth = read_trial(EXCERPT)
    cls = InertialKalmanFilterQ if fixed else InertialKalmanFilter
    every = rms(replay_errors(cls(), rows, truth))
    fourth = replay_errors(cls(decimation=4), rows, truth)
    assert abs(rms(fourth) - every) < 0.05
    assert max(fourth) < 3.0
