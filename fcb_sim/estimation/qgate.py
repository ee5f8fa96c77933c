"""Beyond the report: a quaternion attitude filter that holds up on real data ("qgate"), the default before ikf.

Own design, using ideas from VQF (D. Laidig and T. Seel, "VQF: Highly accurate IMU orientation estimation
with bias estimation and magnetic disturbance rejection", Information Fusion 91, 2023): correct the
inclination with the accelerometer low-pass filtered in an (almost) inertial frame, and estimate the gyro
bias both at rest and during motion. No code of theirs is used.

Per sample (docs/attitude.md, "How qgate works", says why each step is as it is):

1. Strapdown: integrate the bias-corrected gyro exactly (axis-angle increment) into q (body-to-earth).
2. Rotate the specific force into the earth frame with q and low-pass it there (first order, ``tau_acc``),
   a sample whose |a| is more than ``gate`` (10 m/s²) from g entering with weight (gate / deviation)².
3. Correct: rotate q about the horizontal earth axis that brings the filtered vector to vertical, by the
   fraction ``dt / tau_corr`` of the angle; rotate the filtered vector with it so the loop stays consistent.
4. Bias: during motion the correction's body-frame component feeds an integral (``tau_bias``); at rest (gyro and
   accelerometer steady for ``rest_time``) the bias is pulled towards the low-passed gyro. Clamped to
   ``bias_max``.

Yaw is not observable without a magnetometer; it is the integrated, bias-corrected heading. On the 17 BROAD trials
it scores 1.35° mean, 5.5° worst (bench.filters). Float only: on the board's Q16.16 the per-step corrections (a
fraction dt / tau of a small angle) are below the resolution.
"""

from __future__ import annotations

import math

from fcb_sim.estimation.base import QuaternionAnglesMixin, quat_step

G = 9.81


class QGateFilter(QuaternionAnglesMixin):
    """Quaternion filter with earth-frame accelerometer low-pass, gating and gyro-bias estimation."""

    def __init__(
        self,
        *,
        tau_acc: float = 3.0,
        tau_corr: float = 2.0,
        tau_bias: float = 60.0,
        gate: float = 10.0,
        rest_gyro: float = math.radians(2.0),
        rest_acc: float = 0.5,
        rest_time: float = 1.5,
        tau_rest_bias: float = 2.0,
        bias_max: float = math.radians(3.0),
    ) -> None:
        self.tau_acc = tau_acc
        self.tau_corr = tau_corr
        self.tau_bias = tau_bias
        self.gate = gate
        self.rest_gyro = rest_gyro
        self.rest_acc = rest_acc
        self.rest_time = rest_time
        self.tau_rest_bias = tau_rest_bias
        self.bias_max = bias_max
        self.reset()

    def reset(self) -> None:
        self.w, self.x, self.y, self.z = 1.0, 0.0, 0.0, 0.0
        self.bx = self.by = self.bz = 0.0
        self.fx = self.fy = 0.0
        self.fz = G
        self._started = False
        self._rest_t = 0.0
        self._gl = [0.0, 0.0, 0.0]  # low-passed gyro for rest detection / rest bias
        self._al = [0.0, 0.0, G]  # low-passed body accelerometer for rest detection
        self.at_rest = False

    # --- outputs ---
    def quaternion(self) -> tuple[float, float, float, float]:
        return self.w, self.x, self.y, self.z

    # --- the filter ---
    def _init_from_acc(self, ax: float, ay: float, az: float) -> None:
        n = math.sqrt(ax * ax + ay * ay + az * az)
        if n < 1e-6:
            return
        roll = math.atan2(ay, az)
        pitch = math.atan2(-ax, math.sqrt(ay * ay + az * az))
        cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
        cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
        self.w, self.x, self.y, self.z = cr * cp, sr * cp, cr * sp, -sr * sp
        self.fx, self.fy, self.fz = 0.0, 0.0, n
        self._al = [ax, ay, az]
        self._started = True

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        if not self._started:
            self._init_from_acc(ax, ay, az)
            return
        if dt <= 0.0:
            return
        # 1. strapdown with the bias-corrected rate
        wx, wy, wz = gx - self.bx, gy - self.by, gz - self.bz
        rate = math.sqrt(wx * wx + wy * wy + wz * wz)
        w, x, y, z = quat_step(self.w, self.x, self.y, self.z, wx, wy, wz, rate, dt)
        self._lowpass(w, x, y, z, ax, ay, az, dt)  # 2.
        w, x, y, z = self._correct(w, x, y, z, dt)  # 3. and 4a.
        n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        self.w, self.x, self.y, self.z = w * n, x * n, y * n, z * n
        self._rest(gx, gy, gz, ax, ay, az, dt)  # 4b.
        m = self.bias_max
        self.bx = m if self.bx > m else -m if self.bx < -m else self.bx
        self.by = m if self.by > m else -m if self.by < -m else self.by
        self.bz = m if self.bz > m else -m if self.bz < -m else self.bz

    def _lowpass(self, w: float, x: float, y: float, z: float, ax: float, ay: float, az: float, dt: float) -> None:
        """Step 2: the specific force in the earth frame (attitude w, x, y, z), low-passed there, with the
        magnitude gate."""
        an = math.sqrt(ax * ax + ay * ay + az * az)
        dev = abs(an - G)
        # Soft gate: full weight within `gate` of g, then falling as (gate / dev)^2, so a tap or an
        # impact barely moves the filtered vector while a long centripetal load still gets averaged in.
        wgt = 1.0 if dev <= self.gate else (self.gate / dev) ** 2
        if wgt > 1e-3:
            ex = (1.0 - 2.0 * (y * y + z * z)) * ax + 2.0 * (x * y - w * z) * ay + 2.0 * (x * z + w * y) * az
            ey = 2.0 * (x * y + w * z) * ax + (1.0 - 2.0 * (x * x + z * z)) * ay + 2.0 * (y * z - w * x) * az
            ez = 2.0 * (x * z - w * y) * ax + 2.0 * (y * z + w * x) * ay + (1.0 - 2.0 * (x * x + y * y)) * az
            k = wgt * dt / (self.tau_acc + dt)
            self.fx += k * (ex - self.fx)
            self.fy += k * (ey - self.fy)
            self.fz += k * (ez - self.fz)

    def _correct(self, w: float, x: float, y: float, z: float, dt: float) -> tuple[float, float, float, float]:
        """Steps 3 and 4a: the attitude rotated about the horizontal axis f x z by a fraction of the angle that
        makes the filtered vector f vertical (f turned with it), and the bias fed the correction in body
        coordinates; returns the corrected attitude (not normalised)."""
        fx_, fy_, fz_ = self.fx, self.fy, self.fz
        fn = math.sqrt(fx_ * fx_ + fy_ * fy_ + fz_ * fz_)
        # axis (unnormalised) = f_hat x e_z = (fy, -fx, 0)/|f|; angle = atan2(horizontal, vertical)
        hn = math.sqrt(fx_ * fx_ + fy_ * fy_)
        if not (fn > 1e-6 and hn > 1e-12):
            return w, x, y, z
        angle = math.atan2(hn, fz_) * dt / (self.tau_corr + dt)
        s = math.sin(0.5 * angle) / hn
        c = math.cos(0.5 * angle)
        cx, cy = fy_ * s, -fx_ * s  # earth-frame correction quaternion (c, cx, cy, 0)
        # q <- dq (earth) * q (the earth-frame correction multiplies from the left; until this was
        # fixed it multiplied from the right, a body-frame rotation, which is only right near level)
        w, x, y, z = (
            c * w - cx * x - cy * y,
            c * x + cx * w + cy * z,
            c * y - cx * z + cy * w,
            c * z + cx * y - cy * x,
        )
        # rotate the filtered vector with the correction (small angle: f += theta x f)
        tx, ty = fy_ / hn * angle, -fx_ / hn * angle
        self.fx = fx_ + ty * fz_
        self.fy = fy_ - tx * fz_
        self.fz = fz_ + tx * fy_ - ty * fx_
        # 4a. bias during motion: the correction in body coordinates (R^T t), integrated
        if self.tau_bias > 0.0:
            bx = (1.0 - 2.0 * (y * y + z * z)) * tx + 2.0 * (x * y + w * z) * ty
            by = 2.0 * (x * y - w * z) * tx + (1.0 - 2.0 * (x * x + z * z)) * ty
            bz = 2.0 * (x * z + w * y) * tx + 2.0 * (y * z - w * x) * ty
            kb = 1.0 / self.tau_bias
            self.bx -= kb * bx
            self.by -= kb * by
            self.bz -= kb * bz
        return w, x, y, z

    def _rest(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        """Step 4b: rest detection (gyro and accelerometer steady for ``rest_time``) and the bias at rest."""
        gl, al = self._gl, self._al
        kr = dt / (0.5 + dt)
        gl[0] += kr * (gx - gl[0])
        gl[1] += kr * (gy - gl[1])
        gl[2] += kr * (gz - gl[2])
        al[0] += kr * (ax - al[0])
        al[1] += kr * (ay - al[1])
        al[2] += kr * (az - al[2])
        gd = (gx - gl[0]) ** 2 + (gy - gl[1]) ** 2 + (gz - gl[2]) ** 2
        ad = (ax - al[0]) ** 2 + (ay - al[1]) ** 2 + (az - al[2]) ** 2
        if gd < self.rest_gyro**2 and ad < self.rest_acc**2 and (
            gl[0] ** 2 + gl[1] ** 2 + gl[2] ** 2 < (2.0 * self.bias_max) ** 2
        ):
            self._rest_t += dt
        else:
            self._rest_t = 0.0
        self.at_rest = self._rest_t >= self.rest_time
        if self.at_rest:
            kb = dt / (self.tau_rest_bias + dt)
            self.bx += kb * (gl[0] - self.bx)
            self.by += kb * (gl[1] - self.by)
            self.bz += kb * (gl[2] - self.bz)
