"""The report's second Kalman filter, "with noise covariance": the TKJ Electronics formulation [4], per axis.

State (angle, gyro bias), covariance P (2x2), per sample::

    rate = new_rate - bias;  angle += dt * rate
    P00 += dt * (dt*P11 - P01 - P10 + Q_angle);  P01 -= dt * P11;  P10 -= dt * P11;  P11 += Q_bias * dt
    S = P00 + R_measure;  K0 = P00 / S;  K1 = P10 / S
    y = new_angle - angle;  angle += K0 * y;  bias += K1 * y
    P00 -= K0 * P00;  P01 -= K0 * P01;  P10 -= K1 * P00;  P11 -= K1 * P01   (with the old P00, P01)

Table 2's Kalman (2) constants map onto it as C1 = Q_angle = 0.01, C2 = Q_bias = 0.001, R = R_measure = 1,
P2PHI = dt = 0.0025 (400 Hz). With these the steady-state angle gain is about 0.005 per step (an
accelerometer bandwidth near 0.3 Hz), not Table 3's measured 7.3 Hz: the report does not say how its units
were scaled, so treat the table's constants as relative. TKJ's own defaults are Q_angle 0.001, Q_bias 0.003,
R 0.03.

In Q16.16 the products Q_angle dt = 2.5e-5 (1.6 LSB) and Q_bias dt = 2.5e-6 (0.16 LSB) are at or below the
resolution 2^-16 = 1.5e-5: Q_bias dt rounds to 0, so the fixed-point bias covariance never grows and the
fixed-point filter does not learn the bias. That is what libfixmath on the board would have done; the tests
state the float/fixed agreement bound that results.
"""

from __future__ import annotations

from . import fixed as fx
from .base import EulerFilterMixin, accel_roll_pitch, wrap_pi

Q_ANGLE = 0.01
Q_BIAS = 0.001
R_MEASURE = 1.0


class _Axis:
    __slots__ = ("angle", "bias", "p00", "p01", "p10", "p11")

    def __init__(self, angle: float) -> None:
        self.angle = angle
        self.bias = 0.0
        self.p00 = self.p01 = self.p10 = self.p11 = 0.0


class KalmanCovFilter(EulerFilterMixin):
    """TKJ's two-state Kalman filter per axis, in float."""

    def __init__(self, q_angle: float = Q_ANGLE, q_bias: float = Q_BIAS, r_measure: float = R_MEASURE) -> None:
        self.q_angle, self.q_bias, self.r_measure = q_angle, q_bias, r_measure
        self.reset()

    def reset(self) -> None:
        self.yaw = 0.0
        self._x: _Axis | None = None
        self._y: _Axis | None = None

    @property
    def roll(self) -> float:
        return self._x.angle if self._x is not None else 0.0

    @property
    def pitch(self) -> float:
        return self._y.angle if self._y is not None else 0.0

    def _step(self, s: _Axis, new_angle: float, new_rate: float, dt: float) -> None:
        s.angle += dt * (new_rate - s.bias)
        p00, p01, p10, p11 = s.p00, s.p01, s.p10, s.p11
        p00 += dt * (dt * p11 - p01 - p10 + self.q_angle)
        p01 -= dt * p11
        p10 -= dt * p11
        p11 += self.q_bias * dt
        inv_s = 1.0 / (p00 + self.r_measure)
        k0, k1 = p00 * inv_s, p10 * inv_s
        y = wrap_pi(new_angle - s.angle)  # wrapped: roll may pass ±180°
        s.angle = wrap_pi(s.angle + k0 * y)
        s.bias += k1 * y
        s.p00 = p00 - k0 * p00
        s.p01 = p01 - k0 * p01
        s.p10 = p10 - k1 * p00
        s.p11 = p11 - k1 * p01

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        sphi, stheta = accel_roll_pitch(ax, ay, az)
        if self._x is None or self._y is None:
            self._x, self._y = _Axis(sphi), _Axis(stheta)
            return
        self._step(self._x, sphi, gx, dt)
        self._step(self._y, stheta, gy, dt)
        self.yaw = wrap_pi(self.yaw + gz * dt)


class _AxisQ16:
    __slots__ = ("angle", "bias", "p00", "p01", "p10", "p11")

    def __init__(self, angle: int) -> None:
        self.angle = angle
        self.bias = 0
        self.p00 = self.p01 = self.p10 = self.p11 = 0


class KalmanCovFilterQ16(EulerFilterMixin):
    """TKJ's filter in Q16.16 (libfixmath semantics, saturating), with the corrected fixed-point atan2."""

    def __init__(
        self,
        q_angle: float = Q_ANGLE,
        q_bias: float = Q_BIAS,
        r_measure: float = R_MEASURE,
        *,
        correct_atan2: bool = True,
    ) -> None:
        f = fx.from_float
        self.q_angle, self.q_bias, self.r_measure = f(q_angle), f(q_bias), f(r_measure)
        self.correct_atan2 = correct_atan2
        self.reset()

    def reset(self) -> None:
        self.y = 0
        self._x: _AxisQ16 | None = None
        self._y: _AxisQ16 | None = None

    @property
    def roll(self) -> float:
        return self._x.angle / 65536.0 if self._x is not None else 0.0

    @property
    def pitch(self) -> float:
        return self._y.angle / 65536.0 if self._y is not None else 0.0

    @property
    def yaw(self) -> float:
        return self.y / 65536.0

    def _step(self, s: _AxisQ16, new_angle: int, new_rate: int, dt: int) -> None:
        smul, sadd, ssub, sdiv = fx.smul, fx.sadd, fx.ssub, fx.sdiv
        s.angle = sadd(s.angle, smul(dt, ssub(new_rate, s.bias)))
        p00, p01, p10, p11 = s.p00, s.p01, s.p10, s.p11
        p00 = sadd(p00, smul(dt, sadd(ssub(ssub(smul(dt, p11), p01), p10), self.q_angle)))
        dp11 = smul(dt, p11)
        p01 = ssub(p01, dp11)
        p10 = ssub(p10, dp11)
        p11 = sadd(p11, smul(self.q_bias, dt))
        sden = sadd(p00, self.r_measure)
        k0, k1 = sdiv(p00, sden), sdiv(p10, sden)
        y = fx.wrap_pi(ssub(new_angle, s.angle))
        s.angle = fx.wrap_pi(sadd(s.angle, smul(k0, y)))
        s.bias = sadd(s.bias, smul(k1, y))
        s.p00 = ssub(p00, smul(k0, p00))
        s.p01 = ssub(p01, smul(k0, p01))
        s.p10 = ssub(p10, smul(k1, p00))
        s.p11 = ssub(p11, smul(k1, p01))

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        f = fx.from_float
        sphi, stheta = fx.accel_roll_pitch(f(ax), f(ay), f(az), self.correct_atan2)
        if self._x is None or self._y is None:
            self._x, self._y = _AxisQ16(sphi), _AxisQ16(stheta)
            return
        fdt = f(dt)
        self._step(self._x, sphi, f(gx), fdt)
        self._step(self._y, stheta, f(gy), fdt)
        self.y = fx.wrap_pi(self.y + fx.smul(f(gz), fdt))
