"""The report's first Kalman filter: the lab's "QR Controller Theory" filter [13], per axis.

Per sample, for roll (pitch the same with q and theta)::

    p = sp - b            # bias-corrected rate
    phi += p * P2PHI      # predict: integrate the gyro (P2PHI = dt, 0.0025 s at 400 Hz)
    e = phi - sphi        # innovation against the accelerometer angle
    phi -= e / C1         # correct the angle
    b += e / C2           # correct the gyro bias

Table 2: C1 = 10, C2 = 100, P2PHI = 0.0025. Checked: P2PHI is exactly dt at the 400 Hz RAW loop, so it is
taken as the sample's dt here (any rate works). At 400 Hz, 1/C1 per step is an accelerometer bandwidth of
400/10 = 40 rad/s (6.4 Hz), close to Table 3's measured 7.1-7.7 Hz cut-off; 1/C2 per step gives the bias loop
an integral gain of 4 s⁻²: bias converges in about 10 s. (Some versions of [13] write ``b += (e / P2PHI) / C2``;
with Table 2's C2 that would make the bias loop as fast as the angle loop, 1600 s⁻², and the bias would
swallow real rotation; the form above is the one that matches Table 3.) C1 and C2 are per-step constants, so
at another sample rate the bandwidths scale with the rate, as they would on the board. Yaw is the integrated
z rate. The first sample initialises the angles from the accelerometer.
"""

from __future__ import annotations

from . import fixed as fx
from .base import EulerFilterMixin, Q16AnglesMixin, accel_roll_pitch, wrap_pi

C1 = 10.0
C2 = 100.0


class KalmanFilter(EulerFilterMixin):
    """[13]'s filter in float."""

    def __init__(self, c1: float = C1, c2: float = C2) -> None:
        self.c1, self.c2 = c1, c2
        self.reset()

    def reset(self) -> None:
        self.roll = self.pitch = self.yaw = 0.0
        self.bias_x = self.bias_y = 0.0
        self._started = False

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        sphi, stheta = accel_roll_pitch(ax, ay, az)
        if not self._started:
            self.roll, self.pitch, self._started = sphi, stheta, True
            return
        c1, c2 = self.c1, self.c2
        phi = self.roll + (gx - self.bias_x) * dt
        e = wrap_pi(phi - sphi)  # wrapped: roll may pass ±180° (identical to [13] otherwise)
        self.roll = wrap_pi(phi - e / c1)
        self.bias_x += e / c2
        theta = self.pitch + (gy - self.bias_y) * dt
        e = theta - stheta
        self.pitch = theta - e / c1
        self.bias_y += e / c2
        self.yaw = wrap_pi(self.yaw + gz * dt)


class KalmanFilterQ16(Q16AnglesMixin):
    """[13]'s filter in Q16.16 (libfixmath semantics, saturating), with the corrected fixed-point atan2."""

    def __init__(self, c1: float = C1, c2: float = C2, *, correct_atan2: bool = True) -> None:
        self.c1, self.c2 = fx.from_float(c1), fx.from_float(c2)
        self.correct_atan2 = correct_atan2
        self.reset()

    def reset(self) -> None:
        self.r = self.p = self.y = 0
        self.bx = self.by = 0
        self._started = False

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        f = fx.from_float
        smul, sadd, ssub, sdiv = fx.smul, fx.sadd, fx.ssub, fx.sdiv
        sphi, stheta = fx.accel_roll_pitch(f(ax), f(ay), f(az), self.correct_atan2)
        if not self._started:
            self.r, self.p, self._started = sphi, stheta, True
            return
        fdt = f(dt)
        c1, c2 = self.c1, self.c2
        phi = sadd(self.r, smul(ssub(f(gx), self.bx), fdt))
        e = fx.wrap_pi(ssub(phi, sphi))
        self.r = fx.wrap_pi(ssub(phi, sdiv(e, c1)))
        self.bx = sadd(self.bx, sdiv(e, c2))
        theta = sadd(self.p, smul(ssub(f(gy), self.by), fdt))
        e = ssub(theta, stheta)
        self.p = ssub(theta, sdiv(e, c1))
        self.by = sadd(self.by, sdiv(e, c2))
        self.y = fx.wrap_pi(self.y + smul(f(gz), fdt))
