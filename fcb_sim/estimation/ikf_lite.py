"""ikf in fixed point cut to fit the Cortex-M0 ("lite"): the algorithm of :mod:`.ikf_fixed` with cheaper arithmetic
where precision allows and the gravity part spread over the samples between two gravity steps.

Executed on the emulated M0 the exact twin costs 1668 µs a sample; the report's round robin leaves about 550 µs
beside its other tasks (docs/board.md, "Cycles from execution"). What this variant changes, each measured there:

- Quaternion products (strapdown, prediction, rebase, the force turned to the earth frame) are ``qmul``: a Q2.30
  product from three 16x16 MULS, the low halves' product dropped, no rounding or range test, inlined (about 12
  cycles against 70 for the rounded, saturated ``mul``), and a quaternion product's sums are 32-bit (``qprod``).
  It is under 6 units of 2^-30 (6e-9) below the exact product, harmless against the filter's 1e-3 rad. Its
  operands stay below 1 in magnitude: a wild rate or dt takes the exact path, a specific force is held within
  2048 m/s² (no sensor reads more) and a swing's |u| below 1.
- The strapdown's series to 2nd order while the half step is below 0.0625 rad (it is at most 0.044 rad at
  the gyro's 2000 °/s and 400 Hz), where the dropped 4th-order terms are below 1.3e-6 (1e-10 at the 200 °/s of
  hand-held motion); beyond (a long dt), the 4th order as the twin; renormalised at every gravity step.
- The turn rate by a 32-bit square root (of its square in Q16.16: 1/256 rad/s resolution; it scales the
  drift and the noise only), not the 64-bit one (1100 cycles).
- The rebase's swing to 2nd order, (1 - |u|²/8, u_y/2, -u_x/2, 0), without the two square roots and two
  divisions (3100 cycles): the exact swing is this plus terms of |u|³. A swing past 64° is clipped as before
  (the exact path, never in use); the normalisation after it is the twin's Newton step, two of them after
  such a clip (its norm is 1.01) and none of the twin's full normalisation (never in use: a wild norm is held
  within [1/2, 3/2] and converges over a few gravity steps).
- The three Kalman gains from one division (1 / den in Q8.24) and three products, not three 64-bit divisions.
- The velocity integrates the specific force of every sample, as the float filter's does, but turns it to the
  earth frame once a gravity step: the N samples' body-frame sum, turned at the step's last sample by q at their
  middle (the mean of the two middle samples' q, whose norm is 1 within 2e-4 even at 35 rad/s), as
  q (x) (0, sum) (x) q*, by the one quaternion product in the code (the C board's flash goal), not by the rotation
  matrix. (It took one sample's force times N dt before (issue 35): a tap's spike, one or two samples long, came
  in four times over or not at all, and trial 25, tapping, scored 0.44° against the float filter's 0.33°; turned
  by the last sample's q the sum lagged the turn, 0.56° against 0.48° on trial 07, fast rotation.)
- The gravity part in four pieces (rest detection and the turn rate; the Kalman prediction; its gains and update;
  the force into V and the rebase), piece p at phase p * N // 4 of N samples (the force at the last, N - 1): with
  N = 4 one piece a sample, so no sample carries the whole of it. The rebase is a rotation in the earth frame, so
  applying it to q a few samples after the strapdown it corrects is the same rotation:
  c (x) (q (x) dq) = (c (x) q) (x) dq.

The angles the control law reads come from ``angles_lite`` (ctl_q.c's ``ctlq_angles_lite``): the quaternion's top
16 bits, an atan2 from one 32-bit division and a 7th-order odd polynomial in Q15 (at most 0.011° off math.atan2,
``ATAN_COEFFS``), a 32-bit square root for the pitch's cosine (from the roll's two legs: sqrt(1 - sin²) lost
0.1° near ±90°).

Bit for bit firmware/board/ikf_q.c with ``lite`` set (tests/estimation/test_ikf_lite.py); N (``decimation``) is 4 by
default (``LITE_DECIMATION``). Accuracy on the BROAD trials, each trial scored with tau, k_rot and latency picked on the
others: bench.filters, docs/attitude.md ("The variant that fits", "Left out"); tests/estimation/test_lite_loo.py.
"""

from __future__ import annotations

import math

from .ikf_fixed import Formats, InertialKalmanFilterQ, _sat, div, mul, sqrt

LITE_DECIMATION = 4  # the gravity part's period in samples (spread over them)
PIECES = 4  # rest and rate; force and Kalman prediction; gains and update; rebase
SIXTH_Q30 = 178956971  # round(2^30 / 6)
C24_Q30 = 44739243  # round(2^30 / 24)
C120_Q30 = 8947849  # round(2^30 / 120)
_ONE = 1 << 30
_R28 = 1 << 28  # |half step| below 0.25 rad: qmul cannot overflow and the series holds
_R30 = 1 << 30
_R27 = 1 << 27


def qmul(a: int, b: int) -> int:
    """(a * b) >> 30 of two Q2.30 from three 16x16 products, the low halves' dropped (wrapped to int32, as the C)."""
    ah, bh = a >> 16, b >> 16
    r = ah * bh * 4 + ((ah * (b & 0xFFFF)) >> 14) + (((a & 0xFFFF) * bh) >> 14)
    return ((r + 0x80000000) & 0xFFFFFFFF) - 0x80000000


def _wrap(v: int) -> int:
    return ((v + 0x80000000) & 0xFFFFFFFF) - 0x80000000


def qprod(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """a (x) b by qmul, the sums wrapped to int32 as the C's 32-bit sums (of unit quaternions and steps they stay
    below 1.01 * 2^30, far from wrapping)."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return (
        _wrap(qmul(a0, b0) - qmul(a1, b1) - qmul(a2, b2) - qmul(a3, b3)),
        _wrap(qmul(a0, b1) + qmul(a1, b0) + qmul(a2, b3) - qmul(a3, b2)),
        _wrap(qmul(a0, b2) - qmul(a1, b3) + qmul(a2, b0) + qmul(a3, b1)),
        _wrap(qmul(a0, b3) + qmul(a1, b2) - qmul(a2, b1) + qmul(a3, b0)),
    )


def _half_step(wx: int, wy: int, wz: int, k: int) -> tuple[int, int, int]:
    """w k >> 24 (Q2.30 from a Q8.24 rate and a Q2.30 half step): qmul(w, k << 6) while k < 2^24 (dt under 31 ms)
    and |w| < 2^30 (64 rad/s), else the exact product."""
    if k < 1 << 24 and -_R30 < wx < _R30 and -_R30 < wy < _R30 and -_R30 < wz < _R30:
        k6 = k << 6
        return qmul(wx, k6), qmul(wy, k6), qmul(wz, k6)
    return mul(wx, k, 24), mul(wy, k, 24), mul(wz, k, 24)


class InertialKalmanFilterQL(InertialKalmanFilterQ):
    """:class:`~.ikf_fixed.InertialKalmanFilterQ` cut to fit the M0 (module docstring); the same parameters,
    ``decimation`` (the gravity part's period, spread over it) LITE_DECIMATION unless given."""

    lite = True

    def __init__(self, formats: Formats | None = None, **params: float) -> None:
        params.setdefault("decimation", LITE_DECIMATION)
        super().__init__(formats, **params)
        self.qm = (1 << 30, 0, 0, 0)
        if vars(self.f) != vars(Formats()):
            raise ValueError("the lite filter's products assume ikf_fixed.Formats(), the defaults")

    def _rotate(self, hx: int, hy: int, hz: int) -> tuple[int, int, int, int]:
        """q (x) (cos h, sin h * axis) for the half-angle vector h (Q2.30), by the 2nd-order series."""
        one = _ONE
        if -_R28 < hx < _R28 and -_R28 < hy < _R28 and -_R28 < hz < _R28:
            h2 = qmul(hx, hx) + qmul(hy, hy) + qmul(hz, hz)
        else:
            h2 = one  # a wild rate or dt: clipped below
        if h2 > one >> 4:  # a half step over 0.25 rad: clip it (the twin's exact path)
            h2 = mul(hx, hx, 30) + mul(hy, hy, 30) + mul(hz, hz, 30)
            k = div(one >> 2, sqrt(h2, 30), 30)
            hx, hy, hz = mul(hx, k, 30), mul(hy, k, 30), mul(hz, k, 30)
            h2 = one >> 4
        c = one - (h2 >> 1)
        s = one - qmul(h2, SIXTH_Q30)  # sin(h) / h
        if h2 > one >> 8:  # a half step over 0.0625 rad (80 rad/s at 400 Hz, or a long dt): 4th order too
            h4 = qmul(h2, h2)
            c, s = c + qmul(h4, C24_Q30), s + qmul(h4, C120_Q30)
        return qprod((self.qw, self.qx, self.qy, self.qz), (c, qmul(hx, s), qmul(hy, s), qmul(hz, s)))

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        if not (dt > 0.0) or not math.isfinite(gx + gy + gz + ax + ay + az + dt):
            return
        F = self.f
        io, bb = F.io, F.bias
        from .ikf_fixed import to_q

        gxq, gyq, gzq = to_q(gx, io), to_q(gy, io), to_q(gz, io)
        a = (to_q(ax, io), to_q(ay, io), to_q(az, io))
        if not self._started:
            self._start(gxq, gyq, gzq, *a)
            return
        dtq, dt2q, dthq, krq, kbq = self._dt(dt)
        up = bb - io
        g = tuple(_sat(v << up) for v in (gxq, gyq, gzq))
        n, ph = self.ref.decimation, self.phase
        here = [p * n // PIECES == ph for p in range(PIECES)]  # the pieces of the gravity part in this sample
        if here[0]:
            self._rest(g, a, krq, kbq, dtq)  # 1.
        wx, wy, wz = g[0] - self.bx, g[1] - self.by, g[2] - self.bz  # 2. strapdown, every sample
        self.rx, self.ry, self.rz = wx, wy, wz
        self.qw, self.qx, self.qy, self.qz = self._rotate(*_half_step(wx, wy, wz, dthq))
        self.phase = 0 if ph + 1 >= n else ph + 1
        if here[0]:
            self._rate(wx, wy, wz)
            m = self._bias_max
            self.bx = m if self.bx > m else -m if self.bx < -m else self.bx
            self.by = m if self.by > m else -m if self.by < -m else self.by
            self.bz = m if self.bz > m else -m if self.bz < -m else self.bz
        # 3. the velocity integrates every sample's force (one sample's times N dt let a tap's spike in four times
        # over or not at all: trial 25, tapping, 0.44° against the float filter's 0.33°): the body-frame sum of the
        # N samples (each held within 2048 m/s², no sensor reads more; the sum within 16384), turned to the earth
        # frame at the last by q at their middle, the mean of the middle samples' (by the last sample's q it lagged
        # the turn: trial 07, fast rotation, 0.56° against 0.48°)
        m, ms = _R27 - 1, _R30 - 1
        self.fx, self.fy, self.fz = (max(-ms, min(ms, s + max(-m, min(m, c))))
                                     for s, c in zip((self.fx, self.fy, self.fz), a, strict=True))
        if ph == (n - 1) // 2:
            self.qm = [self.qw, self.qx, self.qy, self.qz]
        if ph == n // 2:  # the same sample for an odd N
            self.qm = [(c >> 1) + (d >> 1) for c, d in zip(self.qm, (self.qw, self.qx, self.qy, self.qz), strict=True)]
        if here[1]:
            self._predict(0, 0, self.rate, dtq, dt2q)  # the force enters V at the last sample (below)
        if here[2]:
            self._correct(dtq)
        if ph == n - 1:
            self._force(dthq)
        if here[3]:
            self._rebase(self.qw, self.qx, self.qy, self.qz, self.gxh, self.gyh)  # 4.

    def _predicted(self) -> tuple[int, int, int, int]:
        if self._lat_half == 0 or (self.rx == 0 and self.ry == 0 and self.rz == 0):
            return self.qw, self.qx, self.qy, self.qz
        return self._rotate(*_half_step(self.rx, self.ry, self.rz, self._lat_half))

    def _rate(self, wx: int, wy: int, wz: int) -> None:
        """The turn rate (Q.io) by a 32-bit root of its square in Q16.16, kept for the Kalman filter's prediction."""
        io, bb = self.f.io, self.f.bias
        r2 = _sat(mul(wx, wx, 2 * bb - io) + mul(wy, wy, 2 * bb - io) + mul(wz, wz, 2 * bb - io))
        self.rate = math.isqrt(r2) << 8

    def _force(self, dthq: int) -> None:
        """V plus the earth-frame horizontal specific force integrated over the N samples: their body-frame sum
        turned by q at their middle, q (x) (0, sum) (x) q* (|q| is 1 within 2e-4 at 35 rad/s: the mean of two unit
        quaternions one sample apart), times dt. The sum restarts."""
        q = self.qm
        p = qprod(q, (0, self.fx, self.fy, self.fz))  # type: ignore[arg-type]
        e = qprod(p, (q[0], _wrap(-q[1]), _wrap(-q[2]), _wrap(-q[3])))
        sh = self.f.io + self.f.dt - self.f.vel - 1  # times dt = 2 dthq: Q.io * Q.dt -> Q.vel
        self.vx, self.vy = _sat(self.vx + mul(e[1], dthq, sh)), _sat(self.vy + mul(e[2], dthq, sh))
        self.fx = self.fy = self.fz = 0

    def _rebase(self, w: int, x: int, y: int, z: int, gxh: int, gyh: int) -> None:
        """Step 4: q turned in the earth frame by the 2nd-order swing that makes (gxh, gyh, g0) vertical, then the
        twin's Newton normalisation."""
        one = _ONE
        vb = self.f.vel
        m = _R30 - 1  # |u| below 1: qmul cannot overflow (a swing past 64° is clipped below anyway)
        ux, uy = (max(-m, min(m, mul(g, self._inv_g0, vb))) for g in (gxh, gyh))
        uh2 = qmul(ux, ux) + qmul(uy, uy)
        if uh2 > (81 * one) // 100:  # at most a 64° step (never in use): the twin's exact clip
            k = div(9 * one // 10, sqrt(uh2, 30), 30)
            ux, uy, uh2 = mul(ux, k, 30), mul(uy, k, 30), (81 * one) // 100
        swing = (one - (uh2 >> 3), uy >> 1, -(ux >> 1), 0)
        w, x, y, z = qprod(swing, (w, x, y, z))  # in the earth frame: swing (x) q
        n2 = qmul(w, w) + qmul(x, x) + qmul(y, y) + qmul(z, z)
        if n2 <= 0:  # never in use: a lost attitude starts level
            self.qw, self.qx, self.qy, self.qz = one, 0, 0, 0
            return
        # Newton steps of 1 / sqrt(n2) from 1, n2 held within [1/2, 3/2]: one (n2 is 1 within 1e-6), two after a
        # swing clipped at 64° (n2 1.01 from the 2nd-order swing) or a wilder norm
        for _ in range(2 if abs(n2 - one) > one >> 12 else 1):
            k = (3 * one - min(max(n2, one >> 1), one + (one >> 1))) >> 1
            w, x, y, z = qmul(w, k), qmul(x, k), qmul(y, k), qmul(z, k)
            n2 = qmul(w, w) + qmul(x, x) + qmul(y, y) + qmul(z, z)
        self.qw, self.qx, self.qy, self.qz = w, x, y, z


# --- the angles the control law reads, cheaply (ctl_q.c's ctlq_angles_lite) ------------------------------------

# atan(t) ~ t (c1 + c3 t^2 + c5 t^4 + c7 t^6) on [0, 1], Q15: a least-squares fit on Chebyshev nodes
# (`python -m fcb_sim.estimation.ikf_lite` refits and prints the error)
ATAN_COEFFS: tuple[int, ...] = (32744, -10533, 4804, -1282)
HALF_PI_Q15 = 51472
PI_Q15 = 102944


def atan2_q15(y: int, x: int) -> int:
    """atan2 of two integers in any common scale, Q15 radians: one 32-bit division and the odd polynomial."""
    ay, ax = abs(y), abs(x)
    mn, mx = (ay, ax) if ay <= ax else (ax, ay)
    if mx == 0:
        return 0
    while mx >= 1 << 16:
        mn, mx = mn >> 1, mx >> 1
    t = (mn << 15) // mx
    t2 = (t * t) >> 15
    c1, c3, c5, c7 = ATAN_COEFFS
    p = c5 + ((c7 * t2) >> 15)
    p = c3 + ((p * t2) >> 15)
    p = c1 + ((p * t2) >> 15)
    a = (p * t) >> 15
    if ay > ax:
        a = HALF_PI_Q15 - a
    if x < 0:
        a = PI_Q15 - a
    return -a if y < 0 else a


def angles_lite(q: tuple[int, int, int, int]) -> tuple[int, int]:
    """Roll and minus the z-up pitch (Q16.16 rad, as ctlq_angles) from a Q2.30 quaternion, from its top 16 bits."""
    w, x, y, z = (v >> 15 for v in q)
    sr = ((w * x) >> 14) + ((y * z) >> 14)
    cr = 32768 - ((x * x) >> 14) - ((y * y) >> 14)
    sp = ((w * y) >> 14) - ((x * z) >> 14)
    cp = math.isqrt(sr * sr + cr * cr)  # cos(pitch): from the roll's two legs, exact near ±90° where 1 - sp² is not
    return 2 * atan2_q15(sr, cr), -2 * atan2_q15(sp, cp)


def fit_atan() -> tuple[list[int], float]:
    """The polynomial's Q15 coefficients by least squares on Chebyshev nodes, and the worst error (deg) of
    atan2_q15 with them over a fine grid of angles."""
    import numpy as np

    t = 0.5 + 0.5 * np.cos(np.pi * (np.arange(4000) + 0.5) / 4000)
    design = np.stack([t ** (2 * k + 1) for k in range(4)], axis=1)
    coef = np.linalg.lstsq(design, np.arctan(t), rcond=None)[0]
    return [int(round(c * 32768)) for c in coef], worst_atan_error_deg()


def worst_atan_error_deg(n: int = 20000) -> float:
    worst = 0.0
    for i in range(n):
        ang = -math.pi + 2 * math.pi * (i + 0.5) / n
        y, x = round(30000 * math.sin(ang)), round(30000 * math.cos(ang))
        err = abs(math.remainder(atan2_q15(y, x) / 32768 - math.atan2(y, x), 2 * math.pi))
        worst = max(worst, err)
    return math.degrees(worst)


if __name__ == "__main__":
    print(fit_atan())
