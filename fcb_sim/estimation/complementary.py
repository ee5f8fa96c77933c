"""The report's complementary filter (eq. 1), per axis, in floating point and in Q16.16.

``phi = K_gyro (phi + p dt) + (1 - K_gyro) phi_acc``, the same for theta with q. Table 2 lists K_gyro = 0.9 (the
bench-tuned value); the board flew with 0.999 (section 3.7.2) after 0.9 made it twitch. At 400 Hz these are
accelerometer time constants of 22.5 ms (a 7.1 Hz cut-off, Table 3's 7.2 Hz) and 2.5 s.

Like the firmware, the gyro's body rates drive the angles directly (the small-angle form of the Euler
kinematics) and yaw is the integrated z rate. Fine for a quad in flight; wrong for large rotations
(the benchmark on hand-held real data shows it). Beyond the report, the first sample initialises roll and pitch
from the accelerometer instead of from zero (with K_gyro = 0.999 a start from zero takes 10 s to settle).
"""

from __future__ import annotations

import math

from . import fixed as fx
from .base import EulerFilterMixin, Q16AnglesMixin, wrap_pi

K_GYRO_FLOWN = 0.999
K_GYRO_TABLE2 = 0.9


class ComplementaryFilter(EulerFilterMixin):
    """Per-axis complementary filter in float."""

    def __init__(self, k_gyro: float = K_GYRO_FLOWN) -> None:
        self.k_gyro = k_gyro
        self.reset()

    def reset(self) -> None:
        self.roll = self.pitch = self.yaw = 0.0
        self._started = False

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        roll_acc = math.atan2(ay, az)
        pitch_acc = math.atan2(-ax, math.sqrt(ay * ay + az * az))
        if not self._started:
            self.roll, self.pitch, self._started = roll_acc, pitch_acc, True
            return
        ka = 1.0 - self.k_gyro
        # eq. 1 as "prediction + K_acce (measurement - prediction)", with the difference wrapped so a roll
        # through ±180° does not average +179° and -179° into 0 (identical to eq. 1 otherwise).
        roll = self.roll + gx * dt
        self.roll = wrap_pi(roll + ka * wrap_pi(roll_acc - roll))
        pitch = self.pitch + gy * dt
        self.pitch = pitch + ka * (pitch_acc - pitch)
        self.yaw = wrap_pi(self.yaw + gz * dt)


class ComplementaryFilterQ16(Q16AnglesMixin):
    """The same filter in Q16.16 (libfixmath semantics, saturating), with the corrected fixed-point atan2.

    With K_gyro = 0.999, K_acce is 66 LSB (0.001007), and the rounded product K_acce * (acc - angle) is 0
    for |acc - angle| < 0.5 / 0.001007 LSB = 0.0076 rad: a dead band of ±0.43° in which the accelerometer
    stops correcting (eq. 1 written literally, K (phi + p dt) + K_acce acc, has the same dead band). The board
    flew with it; the tests pin it.

    Inputs are converted to fix16 at the door (as the firmware would scale its integer samples); the state
    stays in fix16; ``roll``/``pitch``/``yaw`` are read back as floats.
    """

    def __init__(self, k_gyro: float = K_GYRO_FLOWN, *, correct_atan2: bool = True) -> None:
        self.k_acc = fx.ONE - fx.from_float(k_gyro)
        self.correct_atan2 = correct_atan2
        self.reset()

    def reset(self) -> None:
        self.r = self.p = self.y = 0
        self._started = False

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        f = fx.from_float
        smul, sadd, ssub = fx.smul, fx.sadd, fx.ssub
        roll_acc, pitch_acc = fx.accel_roll_pitch(f(ax), f(ay), f(az), self.correct_atan2)
        if not self._started:
            self.r, self.p, self._started = roll_acc, pitch_acc, True
            return
        fdt = f(dt)
        ka = self.k_acc
        r = sadd(self.r, smul(f(gx), fdt))
        self.r = fx.wrap_pi(sadd(r, smul(ka, fx.wrap_pi(ssub(roll_acc, r)))))
        p = sadd(self.p, smul(f(gy), fdt))
        self.p = sadd(p, smul(ka, ssub(pitch_acc, p)))
        self.y = fx.wrap_pi(self.y + smul(f(gz), fdt))


