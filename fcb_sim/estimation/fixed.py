"""Q16.16 fixed point with libfixmath's semantics, and the report's corrected fixed-point atan2 (section 3.10).

A fix16 is a Python int holding the 32-bit two's-complement Q16.16 value: resolution 2^-16, range
[-32768, 32768 - 2^-16]. The operations follow libfixmath (P. Aimonen, https://github.com/PetteriAimonen/
libfixmath, the report's [5]) as built by default (rounding on, overflow detection on, 64-bit multiply):

* ``fix16.c``: ``fix16_add``/``fix16_sub`` return ``fix16_overflow`` (0x80000000) on signed overflow;
  ``fix16_sadd``/``fix16_ssub``/``fix16_smul``/``fix16_sdiv`` saturate to ``fix16_maximum``/``fix16_minimum``;
  ``fix16_mul`` is the 64-bit product rounded half away from zero ("product--" for negatives, then
  + bit 15), overflow when the top 17 bits of the product are not all equal; ``fix16_div`` is the 32-bit
  long division of (|a| << 17) / |b|, then +1 and >> 1 (round half up in magnitude), ``fix16_minimum`` on
  division by zero, ``fix16_overflow`` when the quotient does not fit.
* ``fix16_sqrt.c``: bit-by-bit square root of the magnitude rounded to nearest, sign of the input kept
  (sqrt(-x) = -sqrt(x)). We compute the same rounded result with ``math.isqrt``.
* ``fix16_trig.c``: ``fix16_atan2`` evaluates ``0.1963 r³ - 0.9817 r + π/4`` (constants 0x3240 and 0xFB50)
  with ``r = (x - |y|) / (x + |y|)`` (or the mirrored form for x < 0 around 3π/4), sign from y. Its result
  cache changes speed, not values, so it is left out.
* ``fix16_from_float`` rounds half away from zero; we also saturate out-of-range input (libfixmath leaves it
  undefined).

The filters use the saturating forms (``sadd``, ``ssub``, ``smul``, ``sdiv``) so a wild sample clips instead
of wrapping; ``add``/``sub``/``mul``/``div`` are here for the tests that pin libfixmath's overflow flags.

**atan2 error correction** (report 3.10: errors "up to 10 %" at small angles, "a piecewise linear function was
fit on the error, which reduced the error to 2 %"). ``atan2_corrected`` adds a piecewise-linear function of
|angle| (``ATAN2_KNOTS`` evenly spaced knots on [0, π]) to ``fix16_atan2``. The table ``ATAN2_CORRECTION``
was fitted by :func:`fit_atan2_correction`: a least-squares fit of hat functions at the knots to the error
(math.atan2 - fix16_atan2, in fix16 units) of the roll and pitch angles (atan2(ay, az) and
atan2(-ax, sqrt(ay² + az²)), the two calls the filters make) computed from all accelerometer samples of
the four BROAD trials in ``../shared/data/broad/`` (about 216 000 samples, 432 000 angles; real data of an
IMU moved by hand, as the report logged its board moved around). Regenerate with
``python -m fcb_sim.estimation.atan2_fit ../shared/data/broad/*.csv.gz``.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Iterable

ONE = 0x00010000
MAXIMUM = 0x7FFFFFFF
MINIMUM = -0x80000000
OVERFLOW = -0x80000000  # libfixmath's fix16_overflow shares the bit pattern of fix16_minimum
PI = 205887
PI_DIV_4 = 0x0000C90F
THREE_PI_DIV_4 = 0x00025B2F
RESOLUTION = 1.0 / ONE

_ATAN_C3 = 0x00003240  # 0.1963
_ATAN_C1 = 0x0000FB50  # 0.9817


def wrap32(a: int) -> int:
    """Two's-complement wrap to int32, as the C arithmetic would."""
    return ((a + 0x80000000) & 0xFFFFFFFF) - 0x80000000


def from_float(x: float) -> int:
    """fix16_from_float: round half away from zero; saturating (beyond libfixmath, which is undefined)."""
    t = x * 65536.0
    if t >= 0.0:
        return int(t + 0.5) if t < 2147483647.0 else MAXIMUM
    return int(t - 0.5) if t > -2147483648.0 else MINIMUM


def to_float(a: int) -> float:
    return a / 65536.0


def add(a: int, b: int) -> int:
    """fix16_add: ``OVERFLOW`` on signed overflow."""
    s = a + b
    return OVERFLOW if s > MAXIMUM or s < MINIMUM else s


def sub(a: int, b: int) -> int:
    """fix16_sub: ``OVERFLOW`` on signed overflow."""
    s = a - b
    return OVERFLOW if s > MAXIMUM or s < MINIMUM else s


def sadd(a: int, b: int) -> int:
    """fix16_sadd: saturating add."""
    s = a + b
    return MAXIMUM if s > MAXIMUM else MINIMUM if s < MINIMUM else s


def ssub(a: int, b: int) -> int:
    """fix16_ssub: saturating subtract."""
    s = a - b
    return MAXIMUM if s > MAXIMUM else MINIMUM if s < MINIMUM else s


def mul(a: int, b: int) -> int:
    """fix16_mul: rounded product; ``OVERFLOW`` when it does not fit."""
    p = a * b
    if p < 0:
        if (p >> 47) != -1:
            return OVERFLOW
        p -= 1  # libfixmath: "required in order to round -1/2 correctly"
    elif p >> 47:
        return OVERFLOW
    return wrap32((p >> 16) + ((p & 0x8000) >> 15))


def smul(a: int, b: int) -> int:
    """fix16_smul: rounded product, saturating (fix16_mul inlined: this is the filters' hot path)."""
    p = a * b
    if p < 0:
        if (p >> 47) != -1:
            return MAXIMUM if (a >= 0) == (b >= 0) else MINIMUM
        p -= 1
    elif p >> 47:
        return MAXIMUM if (a >= 0) == (b >= 0) else MINIMUM
    r = (p >> 16) + ((p & 0x8000) >> 15)
    # Rounding up past the top (r == 2**31) wraps in fix16_mul to 0x80000000, which is the overflow flag, so
    # fix16_smul saturates it.
    return r if r <= MAXIMUM else MAXIMUM


def div(a: int, b: int) -> int:
    """fix16_div: rounded quotient; ``MINIMUM`` for b == 0, ``OVERFLOW`` when it does not fit."""
    if b == 0:
        return MINIMUM
    q = (abs(a) << 17) // abs(b)
    if q >= 0xFFFFFFFF:  # the quotient's bits would not fit the 32-bit register (or the +1 wraps)
        return OVERFLOW
    r = (q + 1) >> 1
    return -r if (a < 0) != (b < 0) else r


def sdiv(a: int, b: int) -> int:
    """fix16_sdiv: saturating divide (libfixmath's: division by zero gives ``MINIMUM``, as fix16_div)."""
    if b == 0:
        return MINIMUM
    q = ((a if a >= 0 else -a) << 17) // (b if b >= 0 else -b)
    if q >= 0xFFFFFFFF:
        return MAXIMUM if (a >= 0) == (b >= 0) else MINIMUM
    r = (q + 1) >> 1
    return -r if (a < 0) != (b < 0) else r


def sqrt(a: int) -> int:
    """fix16_sqrt: rounded square root of |a|, with the sign of a."""
    n = abs(a) << 16
    r = math.isqrt(n)
    if n - r * r > r:  # the next bit would have been 1: round up
        r += 1
    return -r if a < 0 else r


def atan2(y: int, x: int) -> int:
    """fix16_atan2: libfixmath's cubic approximation; max error 0.0102 rad (0.58°) about 7° from each
    multiple of π/2, and -21 % relative error at small angles."""
    ay = -y if y < 0 else y
    if x >= 0:
        r = div(x - ay, x + ay)
        r3 = mul(mul(r, r), r)
        angle = mul(_ATAN_C3, r3) - mul(_ATAN_C1, r) + PI_DIV_4
    else:
        r = div(x + ay, ay - x)
        r3 = mul(mul(r, r), r)
        angle = mul(_ATAN_C3, r3) - mul(_ATAN_C1, r) + THREE_PI_DIV_4
    angle = wrap32(angle)
    return -angle if y < 0 else angle


# --- the report's piecewise-linear correction of fix16_atan2 -------------------------------------------
#
# fix16_atan2's error depends on the angle only through r, and r repeats every π/2: with θ = |angle| and
# φ = θ mod π/2, the error at φ is minus the error at π/2 - φ, and it is 0 at φ = 0 and π/4. So one table
# over u = min(φ, π/2 - φ) in [0, π/4] (sign flipped on the mirrored half) covers all angles. The error is
# steepest near u = 0 (the cubic's slope there is 0.79 of atan's: -21 % relative error at small angles), so
# the knots are denser there. Both ends are pinned to 0.

ATAN2_KNOTS_DEG: tuple[float, ...] = (
    0.0, 0.5, 1.0, 1.75, 2.5, 3.5, 4.75, 6.25, 8.0, 10.0, 12.5, 15.5, 19.0, 23.0, 28.0, 33.5, 39.0, 45.0,
)
ATAN2_KNOTS: tuple[int, ...] = tuple(from_float(math.radians(d)) for d in ATAN2_KNOTS_DEG)
# Correction (fix16 units, added to the magnitude of fix16_atan2's result) at each knot, fitted on BROAD
# (see the module docstring and fit_atan2_correction).
ATAN2_CORRECTION: tuple[int, ...] = (
    0, 147, 260, 396, 494, 585, 647, 670, 647, 582, 468, 313, 139, -24, -149, -181, -122, 0,
)
_HALF_PI = PI // 2 + 1  # 102944
_QUARTER_PI = PI_DIV_4
_LAST_SEGMENT = len(ATAN2_KNOTS) - 2


def _fold(m: int) -> tuple[int, bool]:
    """|angle| (fix16) to (u in [0, π/4], mirrored?)."""
    phi = m % _HALF_PI
    if phi > _QUARTER_PI:
        return _HALF_PI - phi, True
    return phi, False


def atan2_corrected(y: int, x: int) -> int:
    """fix16_atan2 plus the fitted piecewise-linear error correction (the report's section 3.10)."""
    a = atan2(y, x)
    m = -a if a < 0 else a
    u = m % _HALF_PI
    mirrored = u > _QUARTER_PI
    if mirrored:
        u = _HALF_PI - u
    i = bisect_right(ATAN2_KNOTS, u) - 1
    if i >= _LAST_SEGMENT:
        i = _LAST_SEGMENT
    k0 = ATAN2_KNOTS[i]
    c0 = ATAN2_CORRECTION[i]
    c = c0 + (ATAN2_CORRECTION[i + 1] - c0) * (u - k0) // (ATAN2_KNOTS[i + 1] - k0)
    if mirrored:
        c = -c
    return a - c if a < 0 else a + c


def fit_atan2_correction(pairs: Iterable[tuple[float, float]]) -> list[int]:
    """Least-squares piecewise-linear fit of the fix16_atan2 error on the folded angle (see above).

    ``pairs`` are (y, x) arguments in any consistent unit. Returns the correction at each knot in fix16
    units, ends pinned to 0. Offline tool: uses numpy, which only the analysis extra installs.
    """
    try:
        import numpy as np
    except ImportError:
        raise ImportError("fit_atan2_correction is an offline fit that needs numpy: "
                          "pip install 'quadrupel[analysis]'") from None

    knots = np.array(ATAN2_KNOTS, dtype=float)
    us: list[float] = []
    errs: list[float] = []
    for y, x in pairs:
        fy, fx = from_float(y), from_float(x)
        if fx == 0 and fy == 0:
            continue
        a = atan2(fy, fx)
        truth = math.atan2(to_float(fy), to_float(fx))
        e = (abs(truth) * 65536.0) - abs(a)
        u, mirrored = _fold(abs(a))
        us.append(u)
        errs.append(-e if mirrored else e)
    u_arr = np.array(us, dtype=float)
    err = np.array(errs, dtype=float)
    idx = np.clip(np.searchsorted(knots, u_arr, side="right") - 1, 0, len(knots) - 2)
    frac = (u_arr - knots[idx]) / (knots[idx + 1] - knots[idx])
    design = np.zeros((len(u_arr), len(knots)))
    rows = np.arange(len(u_arr))
    design[rows, idx] += 1.0 - frac
    design[rows, idx + 1] += frac
    inner = design[:, 1:-1]  # ends pinned to 0
    lam = 1e-6 * len(u_arr)  # a tiny ridge keeps knots without data at 0
    coef = np.linalg.solve(inner.T @ inner + lam * np.eye(inner.shape[1]), inner.T @ err)
    return [0, *(int(round(c)) for c in coef), 0]


def accel_roll_pitch(ax: int, ay: int, az: int, corrected: bool = True) -> tuple[int, int]:
    """Roll and pitch (fix16 rad) from a fix16 specific force, as the RAW-mode firmware computes them."""
    f = atan2_corrected if corrected else atan2
    return f(ay, az), f(-ax, sqrt(sadd(smul(ay, ay), smul(az, az))))


def wrap_pi(a: int) -> int:
    """Wrap a fix16 angle into (-π, π]."""
    if a > PI:
        return a - 2 * PI
    if a <= -PI:
        return a + 2 * PI
    return a
