"""The fixed-point twin of ``ikf`` (:mod:`.ikf`): the same algorithm in 32-bit integers, as the board would run it.

Every number is an int32 in a Q format (``Qm.n``: n fractional bits); a product is the exact 64-bit product
shifted right with rounding half away from zero and saturated to int32, a quotient the 64-bit dividend over
the divisor, rounded and saturated. That is libfixmath's ``fix16_mul``/``fix16_div`` with another shift: the
same instructions on the Cortex-M0 (a 32x32->64 multiply in software), so the cost per operation is
libfixmath's. Samples enter and the angles leave in Q16.16 (libfixmath's ``fix16_t``, as the report's RAW
path); inside, the states that take tiny steps need more fractional bits than Q16.16 has (``Formats``): dt and
the quaternion Q2.30, the bias and the rest low-pass Q8.24, V and G_h Q8.24, D Q4.28, covariances and gains
Q2.30. docs/attitude.md ("Fixed point") says why each, and measures the trade-off against all-Q16.16.

Non-linear functions: three square roots per sample (the turn rate and two in the swing, bit by bit like
``fix16_sqrt``), sin and cos of the half step by their Taylor series to 4th order (the step is at most 0.044 rad
at 2000 °/s and 400 Hz: error < 2e-10), normalisation by one Newton step, and five divisions (three Kalman gains,
two in the swing). Angles are read back as floats from the quaternion (on the board the corrected fix16_atan2 of
:mod:`.fixed` would add at most 0.06°). Per sample: 119 multiplies, 5 divisions, 3 square roots (26 multiplies
more for the predicted output); its price on the board: docs/board.md, "The RAW filter's price".
"""

from __future__ import annotations

import math

from fcb_sim.estimation.base import QuaternionAnglesMixin

from .ikf import G0, P_GG0, InertialKalmanFilter

_I32_MAX = 0x7FFFFFFF
_I32_MIN = -0x80000000


def _sat(v: int) -> int:
    return _I32_MAX if v > _I32_MAX else _I32_MIN if v < _I32_MIN else v


def mul(a: int, b: int, shift: int) -> int:
    """(a * b) >> shift, rounded half away from zero, saturated to int32 (fix16_mul is shift = 16)."""
    p = a * b
    h = 1 << (shift - 1)
    r = (p + h) >> shift if p >= 0 else -((h - p) >> shift)
    return _I32_MAX if r > _I32_MAX else _I32_MIN if r < _I32_MIN else r


def div(a: int, b: int, shift: int) -> int:
    """(a << shift) / b, rounded half away from zero, saturated to int32 (fix16_div is shift = 16)."""
    if b == 0:
        return _I32_MAX if a >= 0 else _I32_MIN
    n, d = abs(a) << shift, abs(b)
    r = (2 * n + d) // (2 * d)
    r = -r if (a < 0) != (b < 0) else r
    return _I32_MAX if r > _I32_MAX else _I32_MIN if r < _I32_MIN else r


def sqrt(a: int, frac: int) -> int:
    """Square root of a non-negative Q(32-frac).frac number in the same format, rounded (fix16_sqrt's result)."""
    if a <= 0:
        return 0
    n = a << frac
    r = math.isqrt(n)
    return r + 1 if n - r * r > r else r


def to_q(x: float, frac: int) -> int:
    """A float to Q.frac, rounded half away from zero, saturated (fix16_from_float for frac = 16)."""
    t = x * (1 << frac)
    if t >= 2147483647.0:  # also a finite x whose scaled value is inf (int() of it would raise)
        return _I32_MAX
    if t <= -2147483648.0:
        return _I32_MIN
    return int(t + 0.5) if t >= 0.0 else int(t - 0.5)


def _to_q_wide(x: float, frac: int) -> int:
    """A non-negative float to Q.frac, rounded, not saturated to 32 bits (held below 2**62, as ikf_q.c)."""
    t = x * (1 << frac) + 0.5
    return 1 << 62 if t >= 4.6e18 else int(t)


class Formats:
    """Fractional bits of each group of quantities (the table in the module docstring)."""

    def __init__(self, *, io: int = 16, dt: int = 30, quat: int = 30, bias: int = 24, vel: int = 24,
                 drift: int = 28, cov: int = 30) -> None:
        self.io, self.dt, self.quat, self.bias, self.vel, self.drift, self.cov = io, dt, quat, bias, vel, drift, cov

    @classmethod
    def all_q16(cls) -> Formats:
        """Everything in libfixmath's Q16.16 (the trade-off measurement of docs/attitude.md)."""
        return cls(io=16, dt=16, quat=16, bias=16, vel=16, drift=16, cov=16)


class InertialKalmanFilterQ(QuaternionAnglesMixin):
    """:class:`~.ikf.InertialKalmanFilter` in fixed point (module docstring). Same parameters, same outputs."""

    lite = False  # the variant cut to fit the Cortex-M0 is ikf_lite's subclass

    def __init__(self, formats: Formats | None = None, **params: float) -> None:
        self.f = formats or Formats()
        self.ref = InertialKalmanFilter(**params)  # holds the parameters (and validates them); never updated
        F = self.f
        p = self.ref
        # q_g0 is ~0.01 (tau 4.5 s): keep up to 5 more fractional bits while it fits (exact to 3e-9)
        self._qg_shift = next(s for s in range(5, -30, -1) if p.q_g0 * 2.0 ** (F.cov + s) < _I32_MAX)
        self._q_g0 = to_q(p.q_g0, F.cov + self._qg_shift)
        self._k_rot = to_q(p.k_rot, F.io)
        self._drift_noise = to_q(p.drift_noise, F.cov + 16)
        self._rest_r = to_q(p.rest_r, F.cov)
        self._rest_g2 = to_q(p.rest_gyro * p.rest_gyro, 2 * F.bias - 16)
        self._rest_a2 = to_q(p.rest_acc * p.rest_acc, F.io)
        self._bias_max = to_q(p.bias_max, F.bias)
        self._inv_g0 = to_q(1.0 / G0, F.quat)
        self._rest_time = _to_q_wide(p.rest_time, F.dt)  # the time at rest counts in Q.dt, as dt does
        self._dt_cache: tuple[float, int, int, int, int, int] | None = None
        self.reset()

    def reset(self) -> None:
        F = self.f
        one = 1 << F.quat
        self.qw, self.qx, self.qy, self.qz = one, 0, 0, 0
        self.vx = self.vy = 0
        self.dx = self.dy = 0
        self.pvv = self.pvg = self.pvd = self.pgd = 0
        self.pgg = to_q(P_GG0, F.cov)
        self.pdd = to_q(self.ref.drift_init, F.cov)
        self.bx = self.by = self.bz = 0
        self.rx = self.ry = self.rz = 0  # bias-corrected rate, Q.bias
        self.gl = [0, 0, 0]
        self.al = [0, 0, to_q(G0, F.io)]
        self.rest_t = 0  # time at rest, Q.dt (held at rest_time: it only has to reach it)
        self.at_rest = False
        self._started = False
        self.phase = 0  # samples since the last gravity step
        # between the pieces of a spread gravity step (ikf_lite): the body-frame specific force summed over the
        # step's samples (Q.io), q at their middle, the rate, and G_h
        self.fx = self.fy = self.fz = self.rate = self.gxh = self.gyh = 0
        self.qm = [1 << 30, 0, 0, 0]  # Q2.30: the lite variant's only format

    # --- outputs (floats read back from the fixed-point state) ---
    def quaternion(self) -> tuple[float, float, float, float]:
        F = self.f
        w, x, y, z = self._predicted()
        s = 1.0 / (1 << F.quat)
        return w * s, x * s, y * s, z * s

    def _predicted(self) -> tuple[int, int, int, int]:
        F = self.f
        lat = self._lat_half
        if lat == 0 or (self.rx == 0 and self.ry == 0 and self.rz == 0):
            return self.qw, self.qx, self.qy, self.qz
        sh = F.bias + F.dt - F.quat
        return self._rotate(mul(self.rx, lat, sh), mul(self.ry, lat, sh), mul(self.rz, lat, sh))

    @property
    def bias(self) -> tuple[float, float, float]:
        s = 1.0 / (1 << self.f.bias)
        return self.bx * s, self.by * s, self.bz * s

    # --- helpers ---
    @property
    def _lat_half(self) -> int:
        return to_q(0.5 * self.ref.latency, self.f.dt)

    def _rotate(self, hx: int, hy: int, hz: int) -> tuple[int, int, int, int]:
        """q (x) (cos h, sin h * axis) for the half-angle vector h (Q.quat), by the 4th-order series."""
        qb = self.f.quat
        one = 1 << qb
        h2 = mul(hx, hx, qb) + mul(hy, hy, qb) + mul(hz, hz, qb)
        if h2 > one >> 4:  # a half step over 0.25 rad (a wild rate or dt): beyond the series' 1e-6; clip it
            k = div(one >> 2, sqrt(h2, qb), qb)
            hx, hy, hz = mul(hx, k, qb), mul(hy, k, qb), mul(hz, k, qb)
            h2 = one >> 4
        h4 = mul(h2, h2, qb)
        c = one - (h2 >> 1) + h4 // 24
        s = one - h2 // 6 + h4 // 120  # sin(h) / h
        dx, dy, dz = mul(hx, s, qb), mul(hy, s, qb), mul(hz, s, qb)
        w, x, y, z = self.qw, self.qx, self.qy, self.qz
        return (
            _sat(mul(w, c, qb) - mul(x, dx, qb) - mul(y, dy, qb) - mul(z, dz, qb)),
            _sat(mul(w, dx, qb) + mul(x, c, qb) + mul(y, dz, qb) - mul(z, dy, qb)),
            _sat(mul(w, dy, qb) - mul(x, dz, qb) + mul(y, c, qb) + mul(z, dx, qb)),
            _sat(mul(w, dz, qb) + mul(x, dy, qb) - mul(y, dx, qb) + mul(z, c, qb)),
        )

    def _dt(self, dt: float) -> tuple[int, int, int, int, int]:
        """dt and the constants derived from it (the board's dt is fixed: it would hold these as constants)."""
        c = self._dt_cache
        if c is None or c[0] != dt:
            F = self.f
            dn = self.ref.decimation * dt  # the gravity part's step; the strapdown's half step is of dt
            self._dt_cache = c = (dt, to_q(dn, F.dt), to_q(dn * dn, F.dt), to_q(0.5 * dt, F.dt),
                                  to_q(dn / (self.ref.rest_tau + dn), F.cov),
                                  to_q(dn / (self.ref.rest_bias_tau + dn), F.cov))
        return c[1], c[2], c[3], c[4], c[5]

    # --- the filter (step for step the float one) ---
    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        if not (dt > 0.0) or not math.isfinite(gx + gy + gz + ax + ay + az + dt):
            return
        F = self.f
        io, qb, bb = F.io, F.quat, F.bias
        gxq, gyq, gzq = to_q(gx, io), to_q(gy, io), to_q(gz, io)
        axq, ayq, azq = to_q(ax, io), to_q(ay, io), to_q(az, io)
        if not self._started:
            self._start(gxq, gyq, gzq, axq, ayq, azq)
            return
        dtq, dt2q, dthq, krq, kbq = self._dt(dt)
        up = bb - io  # Q.io -> Q.bias
        g = tuple(_sat(v << up) if up >= 0 else v >> -up for v in (gxq, gyq, gzq))  # Q8.24 holds 128 rad/s
        last = self.phase + 1 >= self.ref.decimation  # the gravity part in this sample: every decimation-th
        if last:
            self._rest(g, (axq, ayq, azq), krq, kbq, dtq)  # 1.
        # 2. strapdown
        wx, wy, wz = g[0] - self.bx, g[1] - self.by, g[2] - self.bz
        self.rx, self.ry, self.rz = wx, wy, wz
        sh = bb + F.dt - qb
        w, x, y, z = self._rotate(mul(wx, dthq, sh), mul(wy, dthq, sh), mul(wz, dthq, sh))
        if not last:  # between gravity steps q is the strapdown alone
            self.phase += 1
            self.qw, self.qx, self.qy, self.qz = w, x, y, z
            return
        self.phase = 0
        rate = sqrt(_sat(mul(wx, wx, 2 * bb - io) + mul(wy, wy, 2 * bb - io) + mul(wz, wz, 2 * bb - io)), io)
        # 3. horizontal specific force (Q.io) and the Kalman filter
        two = 2
        r00 = (1 << qb) - two * (mul(y, y, qb) + mul(z, z, qb))
        r01 = two * (mul(x, y, qb) - mul(w, z, qb))
        r02 = two * (mul(x, z, qb) + mul(w, y, qb))
        r10 = two * (mul(x, y, qb) + mul(w, z, qb))
        r11 = (1 << qb) - two * (mul(x, x, qb) + mul(z, z, qb))
        r12 = two * (mul(y, z, qb) - mul(w, x, qb))
        fx = _sat(mul(r00, axq, qb) + mul(r01, ayq, qb) + mul(r02, azq, qb))
        fy = _sat(mul(r10, axq, qb) + mul(r11, ayq, qb) + mul(r12, azq, qb))
        gxh, gyh = self._gravity(fx, fy, rate, dtq, dt2q)
        self._rebase(w, x, y, z, gxh, gyh)  # 4.
        m = self._bias_max
        self.bx = m if self.bx > m else -m if self.bx < -m else self.bx
        self.by = m if self.by > m else -m if self.by < -m else self.by
        self.bz = m if self.bz > m else -m if self.bz < -m else self.bz

    def _rest(self, g: tuple[int, ...], a: tuple[int, int, int], krq: int, kbq: int, dtq: int) -> None:
        """Step 1: rest detection and the bias at rest (gyro ``g`` in Q.bias, accelerometer ``a`` in Q.io)."""
        F = self.f
        io, cb = F.io, F.cov
        gl, al = self.gl, self.al
        for i in range(3):
            gl[i] = _sat(gl[i] + mul(krq, g[i] - gl[i], cb))
        for i in range(3):
            al[i] = _sat(al[i] + mul(krq, a[i] - al[i], cb))
        m = self._bias_max
        dg = _sat(sum(mul(g[i] - gl[i], g[i] - gl[i], 16) for i in range(3)))  # Q(2*bias-16)
        da = _sat(sum(mul(a[i] - al[i], a[i] - al[i], io) for i in range(3)))
        still = dg < self._rest_g2 and da < self._rest_a2 and all(-m < v < m for v in gl)
        self.rest_t = min(self.rest_t + dtq, self._rest_time) if still else 0
        self.at_rest = self.rest_t >= self._rest_time
        if self.at_rest:
            self.bx = _sat(self.bx + mul(kbq, gl[0] - self.bx, cb))
            self.by = _sat(self.by + mul(kbq, gl[1] - self.by, cb))
            self.bz = _sat(self.bz + mul(kbq, gl[2] - self.bz, cb))

    def _gravity(self, fx: int, fy: int, rate: int, dtq: int, dt2q: int) -> tuple[int, int]:
        """Step 3: the Kalman filter on (V, G_h, D), fed the horizontal specific force (Q.io) and the turn rate
        (Q.io); returns G_h (Q.vel). In two halves (predict, correct) that a spread filter runs apart
        (:mod:`.ikf_lite`); between them the state holds the predicted V, G_h and covariance."""
        sh = self.f.io + self.f.dt - self.f.vel
        self._predict(mul(fx, dtq, sh), mul(fy, dtq, sh), rate, dtq, dt2q)
        self._correct(dtq)
        return self.gxh, self.gyh

    def _predict(self, dvx: int, dvy: int, rate: int, dtq: int, dt2q: int) -> None:
        """The Kalman filter's prediction: V (plus the force's integral over the step, ``dvx``, ``dvy`` in Q.vel),
        G_h and the covariance carried over the step, kept in the state."""
        F = self.f
        io, vb, db, cb = F.io, F.vel, F.drift, F.cov
        e = mul(rate, dtq, io + F.dt - cb)  # radians this step, Q.cov
        self.vx = _sat(self.vx + dvx)
        self.vy = _sat(self.vy + dvy)
        self.gxh = mul(self.dx, e, db + cb - vb)
        self.gyh = mul(self.dy, e, db + cb - vb)
        pvv, pvg, pvd, pgg, pgd, pdd = self.pvv, self.pvg, self.pvd, self.pgg, self.pgd, self.pdd
        sd = F.dt  # dt is Q.dt, covariances Q.cov: (P * dt) >> dt stays Q.cov
        self.pvv = _sat(pvv - 2 * mul(pvg, dtq, sd) + mul(pgg, dt2q, sd))
        self.pvg = _sat(pvg + mul(e, pvd, cb) - mul(pgg, dtq, sd) - mul(mul(e, pgd, cb), dtq, sd))
        self.pvd = _sat(pvd - mul(pgd, dtq, sd))
        q_dt = mul(self._q_g0, dtq, self._qg_shift + sd)  # Q.cov
        noise = _sat(q_dt + mul(mul(q_dt, self._k_rot, io), rate, io))
        self.pgg = _sat(pgg + 2 * mul(e, pgd, cb) + mul(mul(e, e, cb), pdd, cb) + noise)
        self.pgd = _sat(pgd + mul(e, pdd, cb))
        self.pdd = _sat(pdd + mul(self._drift_noise, e, cb + 16))

    def _correct(self, dtq: int) -> None:
        """The Kalman filter's update with the pseudo measurement V = 0, on the predicted state."""
        F = self.f
        vb, db, cb, sd = F.vel, F.drift, F.cov, F.dt
        vx, vy = self.vx, self.vy
        a_vv, a_vg, a_vd, a_gg, a_gd, a_dd = self.pvv, self.pvg, self.pvd, self.pgg, self.pgd, self.pdd
        # gain K = dt a / (dt a_vv + r), r = 1 (rest_r at rest): dt scaled so nothing exceeds the format
        r = self._rest_r if self.at_rest else 1 << cb
        den = _sat(mul(a_vv, dtq, sd) + r)
        if self.lite:  # one division (ikf_lite): 1 / den in Q8.24 (den >= rest_r), then three products
            inv = div(1 << cb, den, 24)
            kv, kg, kd = (mul(mul(a, dtq, sd), inv, 24) for a in (a_vv, a_vg, a_vd))
        else:
            kv = div(mul(a_vv, dtq, sd), den, cb)
            kg = div(mul(a_vg, dtq, sd), den, cb)
            kd = div(mul(a_vd, dtq, sd), den, cb)
        self.gxh = _sat(self.gxh - mul(kg, vx, cb))
        self.gyh = _sat(self.gyh - mul(kg, vy, cb))
        self.dx = _sat(self.dx - mul(kd, vx, cb + vb - db))
        self.dy = _sat(self.dy - mul(kd, vy, cb + vb - db))
        self.vx = _sat(vx - mul(kv, vx, cb))
        self.vy = _sat(vy - mul(kv, vy, cb))
        self.pvv = _sat(a_vv - mul(kv, a_vv, cb))
        self.pvg = _sat(a_vg - mul(kv, a_vg, cb))
        self.pvd = _sat(a_vd - mul(kv, a_vd, cb))
        self.pgg = _sat(a_gg - mul(kg, a_vg, cb))
        self.pgd = _sat(a_gd - mul(kg, a_vd, cb))
        self.pdd = _sat(a_dd - mul(kd, a_vd, cb))

    def _rebase(self, w: int, x: int, y: int, z: int, gxh: int, gyh: int) -> None:
        """Step 4: the swing that makes (gxh, gyh, g0) vertical, VQF's form (sqrt((1+uz)/2), uy/2c, -ux/2c, 0),
        applied to q (Q.quat), which is then normalised and kept."""
        F = self.f
        qb, vb = F.quat, F.vel
        one = 1 << qb
        ux = mul(gxh, self._inv_g0, vb)  # Q.quat
        uy = mul(gyh, self._inv_g0, vb)
        uh2 = mul(ux, ux, qb) + mul(uy, uy, qb)
        if uh2 > (81 * one) // 100:  # at most a 64° step, as the float filter
            k = div(9 * one // 10, sqrt(uh2, qb), qb)
            ux, uy, uh2 = mul(ux, k, qb), mul(uy, k, qb), (81 * one) // 100
        uz = sqrt(one - uh2, qb)
        cw = sqrt((one >> 1) + (uz >> 1), qb)
        cx = div(uy, cw, qb - 1)  # uy / (2 cw): 2 cw would not fit Q2.30
        cy = -div(ux, cw, qb - 1)
        w, x, y, z = (
            _sat(mul(cw, w, qb) - mul(cx, x, qb) - mul(cy, y, qb)),
            _sat(mul(cw, x, qb) + mul(cx, w, qb) + mul(cy, z, qb)),
            _sat(mul(cw, y, qb) - mul(cx, z, qb) + mul(cy, w, qb)),
            _sat(mul(cw, z, qb) + mul(cx, y, qb) - mul(cy, x, qb)),
        )
        # normalise by one Newton step of 1/sqrt(n2) from 1: q *= (3 - n2) / 2 (n2 is 1 within 1e-6)
        n2 = mul(w, w, qb) + mul(x, x, qb) + mul(y, y, qb) + mul(z, z, qb)
        if one >> 1 < n2 < one + (one >> 1):
            k = (3 * one - n2) >> 1
        else:  # never in use (the steps keep |q| within 1e-6 of 1); a full normalisation if it ever is not
            k = div(one, sqrt(n2, qb), qb) if n2 > 0 else one
            w, x, y, z = (w, x, y, z) if n2 > 0 else (one, 0, 0, 0)
        self.qw, self.qx, self.qy, self.qz = mul(w, k, qb), mul(x, k, qb), mul(y, k, qb), mul(z, k, qb)

    def _start(self, gxq: int, gyq: int, gzq: int, axq: int, ayq: int, azq: int) -> None:
        F = self.f
        io, qb = F.io, F.quat
        n = sqrt(mul(axq, axq, io) + mul(ayq, ayq, io) + mul(azq, azq, io), io)
        if n < (1 << io) // 2:
            return
        one = 1 << qb
        ux, uy, uz = div(axq, n, qb), div(ayq, n, qb), div(azq, n, qb)
        if uz <= -one + 2:
            self.qw, self.qx, self.qy, self.qz = 0, one, 0, 0
        else:
            # (1 + uz, uy, -ux, 0) normalised: |.| = sqrt(2 (1 + uz)); cw = sqrt((1 + uz) / 2)
            cw = sqrt((one >> 1) + (uz >> 1), qb)
            self.qw, self.qx, self.qy, self.qz = cw, div(uy, cw, qb - 1), _sat(-div(ux, cw, qb - 1)), 0
        up = F.bias - io
        self.gl = [_sat(v << up) if up >= 0 else v >> -up for v in (gxq, gyq, gzq)]
        self.al = [axq, ayq, azq]
        self._started = True
