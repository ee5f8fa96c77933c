"""Attitude and height estimation for the simulated board (chip z-up convention, docs/architecture.md).

``make_filter(name, fixed_point=False)`` builds an attitude filter by name; ``FILTERS`` lists the names and
``BEST`` is the one to use when nobody says. Every filter follows :class:`AttitudeFilter`:
``update(gx, gy, gz, ax, ay, az, dt)`` with gyro in rad/s and specific force in m/s² (z up, +9.81 when level),
then ``roll``, ``pitch``, ``yaw`` (rad, ZYX) and ``quaternion()`` (w, x, y, z, body-to-earth, earth z up).

The report's RAW-path filters come in float and in Q16.16 fixed point (``fixed_point=True``, libfixmath's semantics):
``complementary`` (K_gyro 0.999, as flown), ``complementary-0.9`` (Table 2), ``kalman`` ([13], Table 2),
``kalman-cov`` (TKJ with noise covariance, Table 2). Beyond the report: ``ikf`` (the default, ``BEST``;
float, and in fixed point the variant cut to fit the Cortex-M0, :mod:`.ikf_lite`) tracks gravity with a small
Kalman filter in an almost-inertial frame (:mod:`.ikf`, docs/attitude.md); ``qgate`` is the earlier quaternion
filter with an earth-frame accelerometer low-pass and gate.
The DMP path is :mod:`.dmp`, the height estimator :mod:`.height`.
"""

from __future__ import annotations

from collections.abc import Callable

from .base import AttitudeFilter, euler_to_quaternion
from .complementary import K_GYRO_FLOWN, K_GYRO_TABLE2, ComplementaryFilter, ComplementaryFilterQ16
from .dmp import quaternion_to_euler
from .height import HeightEstimator
from .ikf import InertialKalmanFilter
from .ikf_lite import InertialKalmanFilterQL
from .kalman import KalmanFilter, KalmanFilterQ16
from .kalman_cov import KalmanCovFilter, KalmanCovFilterQ16
from .qgate import QGateFilter

_FLOAT: dict[str, Callable[[], AttitudeFilter]] = {
    "complementary": lambda: ComplementaryFilter(K_GYRO_FLOWN),
    "complementary-0.9": lambda: ComplementaryFilter(K_GYRO_TABLE2),
    "kalman": KalmanFilter,
    "kalman-cov": KalmanCovFilter,
    "qgate": QGateFilter,
    "ikf": InertialKalmanFilter,
}


def _ikf(fixed_point: bool, native: bool | None) -> AttitudeFilter:
    """ikf: the C of firmware/board/ikf_f.c (doubles) or ikf_q.c (fixed point) where it builds
    (fcb_sim.estimation.native), the same bits as the Python class, which runs otherwise or with ``native=False``. In
    fixed point it is the variant that fits the Cortex-M0 (:mod:`.ikf_lite`; the exact twin is
    :class:`.ikf_fixed.InertialKalmanFilterQ`)."""
    if native is not False:
        from . import native as c  # late: the C twin is built on first use, not when a filter module is imported

        if c.library() is not None:
            return c.NativeIKFQL() if fixed_point else c.NativeIKF()
        if native:
            raise RuntimeError(f"the C filter is not available: {c.why_not()}")
    return InertialKalmanFilterQL() if fixed_point else InertialKalmanFilter()


_FIXED: dict[str, Callable[[], AttitudeFilter]] = {
    "complementary": lambda: ComplementaryFilterQ16(K_GYRO_FLOWN),
    "complementary-0.9": lambda: ComplementaryFilterQ16(K_GYRO_TABLE2),
    "kalman": KalmanFilterQ16,
    "kalman-cov": KalmanCovFilterQ16,
}

FILTERS: tuple[str, ...] = tuple(_FLOAT)
BEST: str = "ikf"

DESCRIPTIONS: dict[str, str] = {
    "complementary": "report eq. 1, K_gyro 0.999 (as flown)",
    "complementary-0.9": "report eq. 1, K_gyro 0.9 (Table 2)",
    "kalman": "QR Controller Theory filter [13], C1 10, C2 100 (Table 2)",
    "kalman-cov": "TKJ Kalman with noise covariance, Q_angle 0.01, Q_bias 0.001, R 1 (Table 2)",
    "qgate": "quaternion, earth-frame accelerometer low-pass and gate, gyro bias in motion and at rest "
    "(float only)",
    "ikf": "gravity by a Kalman filter in an almost-inertial frame, rest bias, latency prediction",
}


def make_filter(name: str, *, fixed_point: bool = False, native: bool | None = None) -> AttitudeFilter:
    """A fresh filter by name; ``fixed_point=True`` for the fixed-point variant (ikf in C where it builds;
    ``native=False`` for the Python reference, ``True`` to insist on C). Raises KeyError for an unknown name,
    ValueError if the filter has no fixed-point variant."""
    if name not in _FLOAT:
        raise KeyError(f"unknown filter {name!r}; known: {', '.join(FILTERS)}")
    if name == "ikf":
        return _ikf(fixed_point, native)
    if fixed_point:
        if name not in _FIXED:
            raise ValueError(f"filter {name!r} has no fixed-point variant")
        return _FIXED[name]()
    return _FLOAT[name]()


def has_fixed_point(name: str) -> bool:
    return name in _FIXED or name == "ikf"


__all__ = [
    "BEST",
    "DESCRIPTIONS",
    "FILTERS",
    "AttitudeFilter",
    "HeightEstimator",
    "euler_to_quaternion",
    "has_fixed_point",
    "make_filter",
    "quaternion_to_euler",
]
