"""The default RAW-path attitude filter ("ikf"): gravity tracked by a small Kalman filter in an almost-inertial
frame, with sensor-latency prediction. Derivation, figures and the fixed-point twin: docs/attitude.md.

Own design and code. Ideas learned from VQF (D. Laidig and T. Seel, "VQF: Highly accurate IMU orientation
estimation with bias estimation and magnetic disturbance rejection", Information Fusion 91, 2023; the C++ of
github.com/dlaidig/vqf): integrate the gyro alone into a frame that is almost inertial, low-pass the
accelerometer *in that frame* (linear accelerations average out there, gravity does not), and estimate the gyro
bias from rest phases. VQF's low-pass is a fixed 2nd-order Butterworth; here the same response is the steady
state of a Kalman filter, which lets its bandwidth follow the motion.

Per sample (chip z-up frame; gyro rad/s, specific force m/s²; docs/attitude.md, "The algorithm"): 1. rest
detection, and at rest the bias pulled towards the low-passed gyro; 2. strapdown by the exact rotation of the
bias-corrected rate; 3. a Kalman filter per horizontal axis on V (velocity), G_h (horizontal gravity not yet
removed) and D (its drift per radian turned), fed the earth-frame horizontal specific force, with the pseudo
measurement V = 0; 4. rebase: q rotated by the swing that makes the estimated gravity vertical, G_h restarts from
zero; 5. output: q carried ``latency`` seconds ahead along the current rate. Yaw is the integrated, bias-corrected
heading (no magnetometer).

Parameters: tau, k_rot and latency chosen on the 17 BROAD trials and scored leave-one-trial-out by bench.filters
(0.52° mean, VQF offline 0.53°); the rest thresholds and times are VQF's defaults. Cost per sample on the board:
docs/board.md, "The RAW filter's price"; the fixed-point twin is :mod:`.ikf_fixed`. Non-finite samples, dt <= 0
and samples no sensor gives (RATE_MAX, ACC_MAX, DT_MAX) are skipped; an all-zero accelerometer carries no
gravity and leaves the estimate coasting on the gyro. The simulator runs its C translation, firmware/board/ikf_f.c
(fcb_sim.estimation.native: the same doubles).
"""

from __future__ import annotations

import math

from fcb_sim.estimation.base import QuaternionAnglesMixin, quat_step

G0 = 9.81
# Samples no sensor gives are skipped like non-finite ones: finite but huge, they made sin() raise, a division by
# zero, or a NaN state (found by tests/estimation/test_ikf_native.py's property). The MPU6050 reads 35 rad/s and 157
# m/s² at most.
RATE_MAX = 1e4  # |gx| + |gy| + |gz|, rad/s
ACC_MAX = 1e5  # |ax| + |ay| + |az|, m/s²
DT_MAX = 60.0  # s
P_GG0 = 0.1  # initial gravity variance, (m/s²)², about its steady state: no extra trust in the first samples
P_VV_MAX = 1e6  # covariance clamp against a runaway (it never gets near this in use)


class InertialKalmanFilter(QuaternionAnglesMixin):
    """Gravity in an almost-inertial frame by a 3-state Kalman filter, rebased every sample (module docstring)."""

    def __init__(
        self,
        *,
        tau: float = 4.5,
        k_rot: float = 0.5,
        drift_init: float = 1e-3,
        drift_noise: float = 1e-6,
        latency: float = 0.0025,
        rest_r: float = 0.01,
        rest_gyro: float = math.radians(2.0),
        rest_acc: float = 0.5,
        rest_time: float = 1.5,
        rest_tau: float = 0.5,
        rest_bias_tau: float = 2.0,
        bias_max: float = math.radians(5.0),
        decimation: int = 1,
    ) -> None:
        if not (isinstance(decimation, int) and 1 <= decimation <= 64):
            raise ValueError("decimation must be an int in 1..64")
        if not (tau > 0.0 and k_rot >= 0.0 and drift_init >= 0.0 and drift_noise >= 0.0 and latency >= 0.0):
            raise ValueError("tau must be > 0; k_rot, drift_init, drift_noise and latency >= 0")
        self.tau = tau
        self.k_rot = k_rot
        self.drift_init = drift_init
        self.drift_noise = drift_noise
        self.latency = latency
        self.rest_r = rest_r
        self.rest_gyro = rest_gyro
        self.rest_acc = rest_acc
        self.rest_time = rest_time
        self.rest_tau = rest_tau
        self.rest_bias_tau = rest_bias_tau
        self.bias_max = bias_max
        self.decimation = decimation  # the gravity part runs every decimation-th sample (docs/attitude.md)
        self.q_g0 = (math.sqrt(2.0) / tau) ** 4  # gravity random-walk intensity per unit velocity-noise intensity
        self.reset()

    def reset(self) -> None:
        self.w, self.x, self.y, self.z = 1.0, 0.0, 0.0, 0.0
        self.vx = self.vy = 0.0
        self.dx = self.dy = 0.0
        # covariance of (V, G_h, D), the same for both horizontal axes
        self.pvv = self.pvg = self.pvd = 0.0
        self.pgg = P_GG0
        self.pgd = 0.0
        self.pdd = self.drift_init
        self.bx = self.by = self.bz = 0.0
        self.rx = self.ry = self.rz = 0.0  # last bias-corrected rate, for the output prediction
        self._gl = [0.0, 0.0, 0.0]
        self._al = [0.0, 0.0, G0]
        self._rest_t = 0.0
        self.at_rest = False
        self._started = False
        self._phase = 0

    # --- outputs ---
    def quaternion(self) -> tuple[float, float, float, float]:
        """The attitude predicted ``latency`` seconds ahead along the current rate (body to earth, z up)."""
        rx, ry, rz = self.rx, self.ry, self.rz
        rate = math.sqrt(rx * rx + ry * ry + rz * rz)
        return quat_step(self.w, self.x, self.y, self.z, rx, ry, rz, rate, self.latency)

    @property
    def bias(self) -> tuple[float, float, float]:
        return self.bx, self.by, self.bz

    # --- the filter ---
    def _start(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float) -> None:
        n = math.sqrt(ax * ax + ay * ay + az * az)
        if n < 0.5:
            return  # no gravity in this sample (free fall, a dead sensor): wait for one that has it
        # the swing that takes the measured up (a / |a|) to earth z: quaternion (1 + uz, uy, -ux, 0)
        ux, uy, uz = ax / n, ay / n, az / n
        if uz < -0.999999:
            self.w, self.x, self.y, self.z = 0.0, 1.0, 0.0, 0.0  # upside down: any half turn about a level axis
        else:
            k = 1.0 / math.sqrt((1.0 + uz) * (1.0 + uz) + uy * uy + ux * ux)
            self.w, self.x, self.y, self.z = (1.0 + uz) * k, uy * k, -ux * k, 0.0
        self._gl = [gx, gy, gz]
        self._al = [ax, ay, az]
        self._started = True

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        if not (0.0 < dt < DT_MAX and abs(gx) + abs(gy) + abs(gz) < RATE_MAX
                and abs(ax) + abs(ay) + abs(az) < ACC_MAX):  # also NaN: every comparison with it is false
            return
        if not self._started:
            self._start(gx, gy, gz, ax, ay, az)
            return
        n = self.decimation
        last = self._phase + 1 >= n  # this sample runs the gravity part (every n-th; every one for n = 1)
        if last:
            self._rest(gx, gy, gz, ax, ay, az, n * dt)  # 1.
        # 2. strapdown with the bias-corrected rate (exact axis-angle step), every sample
        wx, wy, wz = gx - self.bx, gy - self.by, gz - self.bz
        self.rx, self.ry, self.rz = wx, wy, wz
        rate = math.sqrt(wx * wx + wy * wy + wz * wz)
        w, x, y, z = quat_step(self.w, self.x, self.y, self.z, wx, wy, wz, rate, dt)
        if not last:  # between gravity steps q is the strapdown alone
            self._phase += 1
            self.w, self.x, self.y, self.z = w, x, y, z
            return
        self._phase = 0
        # 3. horizontal specific force in the earth frame (this sample's: a mean of the n samples in the body frame
        # was worse, 0.71° against 0.51° at n = 4, since the body turns under it), and the Kalman filter
        fx = (1.0 - 2.0 * (y * y + z * z)) * ax + 2.0 * (x * y - w * z) * ay + 2.0 * (x * z + w * y) * az
        fy = 2.0 * (x * y + w * z) * ax + (1.0 - 2.0 * (x * x + z * z)) * ay + 2.0 * (y * z - w * x) * az
        gxh, gyh = self._gravity(fx, fy, rate, n * dt)
        self._rebase(w, x, y, z, gxh, gyh)  # 4.
        # the bias is clamped last: a stuck-high rate must not become a stuck-high bias
        m = self.bias_max
        self.bx = m if self.bx > m else -m if self.bx < -m else self.bx
        self.by = m if self.by > m else -m if self.by < -m else self.by
        self.bz = m if self.bz > m else -m if self.bz < -m else self.bz

    def _rest(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        """Step 1: rest detection (gyro and accelerometer near their low-pass for ``rest_time``), and at rest the
        bias pulled towards the low-passed gyro."""
        gl, al = self._gl, self._al
        kr = dt / (self.rest_tau + dt)
        gl[0] += kr * (gx - gl[0])
        gl[1] += kr * (gy - gl[1])
        gl[2] += kr * (gz - gl[2])
        al[0] += kr * (ax - al[0])
        al[1] += kr * (ay - al[1])
        al[2] += kr * (az - al[2])
        m = self.bias_max
        # products, not ** 2 (pow): the C of firmware/board/ikf_f.c computes the same bits
        dgx, dgy, dgz, dax, day, daz = gx - gl[0], gy - gl[1], gz - gl[2], ax - al[0], ay - al[1], az - al[2]
        still = (
            dgx * dgx + dgy * dgy + dgz * dgz < self.rest_gyro * self.rest_gyro
            and dax * dax + day * day + daz * daz < self.rest_acc * self.rest_acc
            and abs(gl[0]) < m and abs(gl[1]) < m and abs(gl[2]) < m
        )
        self._rest_t = self._rest_t + dt if still else 0.0
        self.at_rest = self._rest_t >= self.rest_time
        if self.at_rest:
            kb = dt / (self.rest_bias_tau + dt)
            self.bx += kb * (gl[0] - self.bx)
            self.by += kb * (gl[1] - self.by)
            self.bz += kb * (gl[2] - self.bz)

    def _gravity(self, fx: float, fy: float, rate: float, dt: float) -> tuple[float, float]:
        """Step 3: the Kalman filter on (V, G_h, D) per horizontal axis, fed the earth-frame horizontal specific
        force (fx, fy); returns the horizontal gravity G_h not yet removed (it restarts from 0 at each rebase)."""
        e = rate * dt  # radians turned in this step
        vx = self.vx + fx * dt
        vy = self.vy + fy * dt
        gxh = self.dx * e  # G_h restarts from 0 after each rebase; the drift moves it
        gyh = self.dy * e
        pvv, pvg, pvd, pgg, pgd, pdd = self.pvv, self.pvg, self.pvd, self.pgg, self.pgd, self.pdd
        # predict: x' = F x, F = [[1, -dt, 0], [0, 1, e], [0, 0, 1]], plus process noise on G and D
        a_vv = pvv - 2.0 * dt * pvg + dt * dt * pgg
        a_vg = pvg + e * pvd - dt * pgg - dt * e * pgd
        a_vd = pvd - dt * pgd
        a_gg = pgg + 2.0 * e * pgd + e * e * pdd + self.q_g0 * (1.0 + self.k_rot * rate) * dt
        a_gd = pgd + e * pdd
        a_dd = pdd + self.drift_noise * e
        # update with the pseudo measurement V = 0, noise 1/dt (unit intensity; at rest the velocity is known to
        # be zero, so the measurement is rest_r times as noisy: the filter settles faster on a still sensor)
        inv_s = 1.0 / (a_vv + (self.rest_r if self.at_rest else 1.0) / dt)
        kv, kg, kd = a_vv * inv_s, a_vg * inv_s, a_vd * inv_s
        gxh -= kg * vx
        gyh -= kg * vy
        self.dx -= kd * vx
        self.dy -= kd * vy
        self.vx = vx - kv * vx
        self.vy = vy - kv * vy
        self.pvv = min(a_vv - kv * a_vv, P_VV_MAX)
        self.pvg = a_vg - kv * a_vg
        self.pvd = a_vd - kv * a_vd
        self.pgg = a_gg - kg * a_vg
        self.pgd = a_gd - kg * a_vd
        self.pdd = a_dd - kd * a_vd
        return gxh, gyh

    def _rebase(self, w: float, x: float, y: float, z: float, gxh: float, gyh: float) -> None:
        """Step 4: q (strapped down) rotated in the earth frame so that the estimated gravity (gxh, gyh, g) is
        vertical, normalised, kept."""
        h2 = gxh * gxh + gyh * gyh
        gz_ = math.sqrt(G0 * G0 - h2) if h2 < 0.81 * G0 * G0 else 0.4359 * G0  # at most a 64° step
        cw, cx, cy = G0 + gz_, gyh, -gxh
        k = 1.0 / math.sqrt(cw * cw + cx * cx + cy * cy)
        cw, cx, cy = cw * k, cx * k, cy * k
        w, x, y, z = (
            cw * w - cx * x - cy * y,
            cw * x + cx * w + cy * z,
            cw * y - cx * z + cy * w,
            cw * z + cx * y - cy * x,
        )
        n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        self.w, self.x, self.y, self.z = w * n, x * n, y * n, z * n
