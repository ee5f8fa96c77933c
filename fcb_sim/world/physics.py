"""The world the simulated board flies in: a 6-DOF quadrotor, its motors, battery, sensors and disturbances.

Frames and signs follow docs/architecture.md: earth NED, body FRD, plus frame (ae1 front, ae2 right, ae3 back,
ae4 left; motors 1 and 3 turn clockwise seen from above). Constants and their sources: constants.py.

Model, integrated at a fixed step (default 1 kHz, ``physics_hz`` may be raised):

- motors: first-order speed response (time constant MOTOR_TAU, discretised exactly so any step is stable) towards
  ``ae * OMEGA_PER_AE * V_loaded / V_REF``; thrust ``B_ROTOR w²`` along -z, yaw torque ``D_ROTOR w²``, so that
  Z, L, M, N are the mixing of DESIGN.md with b = B_ROTOR (and l = ARM), d = D_ROTOR;
- rigid body: Newton in NED and Euler's equations in FRD (gyroscopic term w x Iw included), linear drag against
  the wind acting at the rotor plane (gusts tilt it), rotational drag; semi-implicit Euler, the quaternion
  renormalised every 10 ms; stable at 1 kHz (the fastest mode, the 30 ms motor lag, is integrated exactly);
- ground contact at h = 0: the quadrotor rests level on its feet until the thrust lifts it, lands inelastically
  (vertical and horizontal speed to zero, levelled on its legs), and never goes below the floor; the sky ends at
  ``P.CEILING_M`` (a climb stops there); in a ``room`` (term --sim: the lab of ROOM_HALF_M and ROOM_CEILING_M in
  term.core.protocol) walls that far from the pad and a lower ceiling stop it the same way (the speed into them
  zeroed, the craft sliding along them); an impact faster than ``P.CRASH_SPEED_M_S``, or a touch-down tilted past
  ``P.CRASH_TILT_DEG``, is recorded in ``crashes`` (time, speed, tilt);
- contact is felt: the stop at a surface is a jolt of ``P.JOLT_S`` (the speed into it over that time: the
  accelerometer clips it at its 2 g), and while the craft is pressed against the ceiling or a wall that surface
  carries the push (the accelerometer reads no acceleration into it, as on the floor). Every touch starts a
  ``Contact`` in ``contacts`` (time, where, speed into the surface); ``contact`` names what it touches now
  ("ground", "ceiling", "wall" or "") for the room view;
- 3S LiPo: resting voltage against state of charge, internal resistance (the voltage sags with the motors'
  current, which slows the motors for the same command), charge drawn by the motors' electrical power;
- disturbances: wind (mean plus Ornstein-Uhlenbeck gusts), pushes (a force and torque for a while), a motor stuck
  low (its command capped).

API (the seam of docs/architecture.md): ``advance_to(t)``, ``set_motors(ae1, ae2, ae3, ae4)``, ``imu()``,
``dmp()``, ``baro()``, ``battery()``, ``truth``. All noise comes from ``World.rng``, one ``random.Random(seed)``.
"""

from __future__ import annotations

import math
import random
from typing import NamedTuple

from fcb_sim.world import constants as P
from fcb_sim.world.sensors import BatteryAdc, Dmp, Mpu6050, Ms5611, NoiseTable

SLOW_EVERY = 10  # physics steps between updates of the slow parts (battery, wind, pushes)


class Crash(NamedTuple):
    """An impact the craft does not walk away from: when (s), how fast (m/s, the whole speed), how tilted (deg),
    and where ("ground", "ceiling" or "wall")."""

    t: float
    speed: float
    tilt_deg: float
    where: str


class Contact(NamedTuple):
    """The craft touched something: when (s), where ("ground", "ceiling" or "wall") and its speed into it (m/s).
    A touch within ``P.CONTACT_REPEAT_S`` of the same surface's last is the same contact (no new event)."""

    t: float
    where: str
    speed: float


class Truth(NamedTuple):
    """The true state at ``t`` (s). Position NED (m) with ``h = -d`` up; velocity NED (m/s); attitude ZYX Euler
    angles (rad, FRD signs) and the body-to-NED quaternion; body rates (rad/s); rotor speeds (rad/s)."""

    t: float
    n: float
    e: float
    h: float
    vn: float
    ve: float
    vd: float
    phi: float
    theta: float
    psi: float
    p: float
    q: float
    r: float
    qw: float
    qx: float
    qy: float
    qz: float
    omega: tuple[float, float, float, float]
    volts: float
    current: float
    soc: float
    on_ground: bool


def quat_to_euler(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """ZYX Euler angles (phi, theta, psi) of a body-to-earth quaternion."""
    phi = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - z * x)
    theta = math.asin(-1.0 if s < -1.0 else 1.0 if s > 1.0 else s)
    psi = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return phi, theta, psi


def euler_to_quat(phi: float, theta: float, psi: float) -> tuple[float, float, float, float]:
    """Body-to-earth quaternion of ZYX Euler angles."""
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


class World:
    """The quadrotor, its sensors and its surroundings, advanced in fixed steps to the board's clock."""

    def __init__(self, seed: int = 1, *, physics_hz: float = 1000.0, height: float = 0.0, airborne: bool = False,
                 phi: float = 0.0, theta: float = 0.0, psi: float = 0.0, soc: float = P.BATTERY_SOC_START,
                 drag: bool = True, ground: bool = True, baro_spikes: bool = True, vibration: float = 1.0,
                 dmp_latency: float = P.DMP_LATENCY, room: tuple[float, float] | None = None) -> None:
        if physics_hz < 1000.0:
            raise ValueError("physics_hz must be at least 1000")
        self.rng = random.Random(seed)
        self.dt = 1.0 / physics_hz
        self.k = 0  # physics steps taken; time = k * dt
        self.t = 0.0
        self.ground_enabled = ground
        self.room = room  # (walls' distance from the pad, ceiling) in m; None: the open sky up to P.CEILING_M
        self.drag_lin = P.DRAG_LINEAR if drag else 0.0
        self.drag_xy = P.DRAG_ROT_XY if drag else 0.0
        self.drag_z = P.DRAG_ROT_Z if drag else 0.0
        self._init_body(height, airborne, phi, theta, psi)
        self._init_power(soc, airborne)
        self._init_disturbances()
        # sensors, all drawing from self.rng (in this order: a seed gives the same noise)
        self.noise = NoiseTable(self.rng)
        self.mpu = Mpu6050(self.rng, self.noise, vibration=vibration)
        self.dmp_model = Dmp(self.rng, self.noise, latency=dmp_latency)
        self.baro_model = Ms5611(self.rng, self.noise, spikes=baro_spikes)
        self.adc = BatteryAdc(self.noise)
        self._dmp_every = max(1, round(physics_hz / P.DMP_RATE_HZ))
        self._schedule(0)
        self._init_integrator()
        self.dmp_model.sample(0.0, self.qw, self.qx, self.qy, self.qz)

    def _init_body(self, height: float, airborne: bool, phi: float, theta: float, psi: float) -> None:
        """Position, speed, attitude and rates: at rest on the floor, or in the air at ``height``."""
        self.n = self.e = 0.0
        self.d = -height
        self.vn = self.ve = self.vd = 0.0
        self.qw, self.qx, self.qy, self.qz = euler_to_quat(phi, theta, psi)
        self.p = self.q = self.r = 0.0
        self.acc_n = self.acc_e = self.acc_d = 0.0  # acceleration NED of the last step (m/s²)
        self.on_ground = self.ground_enabled and height <= 0.0 and not airborne
        if self.on_ground:
            self.d = 0.0
            self.qw, self.qx, self.qy, self.qz = euler_to_quat(0.0, 0.0, psi)
        self.landings: list[tuple[float, float]] = []  # (time, vertical impact speed m/s)
        self.crashes: list[Crash] = []  # impacts too fast or too tilted (params: CRASH_SPEED_M_S, CRASH_TILT_DEG)
        self.contacts: list[Contact] = []  # every touch of the floor, the ceiling or a wall (module docstring)
        self._touch_t = {"ground": -math.inf, "ceiling": -math.inf, "wall": -math.inf}  # last step touching it
        self._jolt = (0.0, 0.0, 0.0)  # m/s² NED: a surface stopping the craft, felt until _jolt_until
        self._jolt_until = -math.inf
        self.ceiling_d = -P.CEILING_M if self.room is None else -min(P.CEILING_M, self.room[1])  # NED down
        self.wall = math.inf if self.room is None else self.room[0]

    def _init_power(self, soc: float, airborne: bool) -> None:
        """Battery and motors: idle, or (``airborne``) rotors at hover speed with the battery at that load."""
        self.soc = soc
        self.current = P.AVIONICS_CURRENT
        self.volts = P.ocv(soc) - self.current * P.R_INTERNAL
        self.cmd = [0, 0, 0, 0]  # motor commands in effect (after a stuck motor's cap)
        self.stuck: list[int | None] = [None, None, None, None]
        self._any_stuck = False
        w0 = 0.0
        if airborne:
            w0 = P.OMEGA_HOVER
            self.current = 4.0 * P.POWER_COEF * w0**3 / self.volts + P.AVIONICS_CURRENT
            self.volts = P.ocv(soc) - self.current * P.R_INTERNAL
            self.cmd = [round(w0 / (P.OMEGA_PER_AE * self.volts / P.V_REF))] * 4
        self.w1 = self.w2 = self.w3 = self.w4 = w0
        self.requested = tuple(self.cmd)  # as the firmware last wrote them

    def _init_disturbances(self) -> None:
        self.wind_mean = (0.0, 0.0, 0.0)
        self.gust_std = 0.0
        self.gust_tau = 1.0
        self.gust = [0.0, 0.0, 0.0]
        self.pushes: list[tuple[float, float, tuple[float, ...]]] = []
        self.ext = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # force NED (N), torque body (N m) now acting

    def _init_integrator(self) -> None:
        """The integrator's constants: Euler's equations pre-divided by the inertia and multiplied by dt."""
        dt = self.dt
        self._alpha = 1.0 - math.exp(-dt / P.MOTOR_TAU)
        self._consts = (
            self._alpha,
            P.B_ROTOR / P.MASS,  # thrust acceleration per rotor speed squared
            self.drag_lin / P.MASS,
            P.B_ROTOR * P.ARM / P.IXX * dt,
            P.B_ROTOR * P.ARM / P.IYY * dt,
            P.D_ROTOR / P.IZZ * dt,
            self.drag_xy / P.IXX * dt, self.drag_xy / P.IYY * dt, self.drag_z / P.IZZ * dt,
            (P.IZZ - P.IYY) / P.IXX * dt, (P.IXX - P.IZZ) / P.IYY * dt, (P.IYY - P.IXX) / P.IZZ * dt,
            0.5 * dt,
        )
        self._update_forcing()
        self._inv_4wh2 = 0.25 / (P.OMEGA_HOVER * P.OMEGA_HOVER)
        self._targets = [0.0, 0.0, 0.0, 0.0]
        self._update_targets()

    # ---- commands and disturbances ---------------------------------------------------------------------------
    def set_motors(self, ae1: int, ae2: int, ae3: int, ae4: int) -> None:
        """Motor commands 0..1000 (clamped), as the firmware writes them."""
        self.requested = (ae1, ae2, ae3, ae4)
        hi = P.AE_MAX
        c = [0 if v < 0 else hi if v > hi else v for v in self.requested]
        if self._any_stuck:
            for i, s in enumerate(self.stuck):
                if s is not None and c[i] > s:
                    c[i] = s
        self.cmd = c
        k = self._omega_per_ae
        self._targets = [c[0] * k, c[1] * k, c[2] * k, c[3] * k]

    def stick_motor(self, index: int, level: int | None) -> None:
        """Motor ``index`` (1..4) can no longer exceed ``level`` (a failing ESC or motor); None frees it."""
        self.stuck[index - 1] = level
        self._any_stuck = any(s is not None for s in self.stuck)
        self.set_motors(*self.requested)

    def set_wind(self, n: float = 0.0, e: float = 0.0, d: float = 0.0, *, gust_std: float = 0.0,
                 gust_tau: float = 1.0) -> None:
        """Mean wind (NED, m/s) plus gusts: each axis an Ornstein-Uhlenbeck process of std ``gust_std`` m/s
        and correlation time ``gust_tau`` s."""
        self.wind_mean = (n, e, d)
        self.gust_std = gust_std
        self.gust_tau = gust_tau
        self._update_forcing()

    def push(self, fn: float = 0.0, fe: float = 0.0, fd: float = 0.0, duration: float = 0.1, *,
             tx: float = 0.0, ty: float = 0.0, tz: float = 0.0, start: float | None = None) -> None:
        """Apply a force (NED, N) and a torque (body, N m) from ``start`` (default now) for ``duration`` s."""
        t0 = self.t if start is None else start
        self.pushes.append((t0, t0 + duration, (fn, fe, fd, tx, ty, tz)))

    # ---- sensors ---------------------------------------------------------------------------------------------
    def imu(self) -> tuple[int, int, int, int, int, int]:
        """MPU6050 raw words (gx, gy, gz, ax, ay, az), chip frame, at the current time."""
        # body specific force f = R^T (a - g), inlined (this runs 400 times per simulated second)
        w, x, y, z = self.qw, self.qx, self.qy, self.qz
        an, ae, ad = self.acc_n, self.acc_e, self.acc_d - P.G
        if self.t < self._jolt_until:  # a surface stopping the craft
            jn, je, jd = self._jolt
            an, ae, ad = an + jn, ae + je, ad + jd
        fx = (1 - 2 * (y * y + z * z)) * an + 2 * (x * y + w * z) * ae + 2 * (x * z - w * y) * ad
        fy = 2 * (x * y - w * z) * an + (1 - 2 * (x * x + z * z)) * ae + 2 * (y * z + w * x) * ad
        fz = 2 * (x * z + w * y) * an + 2 * (y * z - w * x) * ae + (1 - 2 * (x * x + y * y)) * ad
        w1, w2, w3, w4 = self.w1, self.w2, self.w3, self.w4
        rs = (w1 * w1 + w2 * w2 + w3 * w3 + w4 * w4) * self._inv_4wh2
        return self.mpu.read(self.t, self.p, self.q, self.r, fx, fy, fz, rs)

    def dmp(self) -> tuple[float, float, float, float] | None:
        """The DMP's newest quaternion (w, x, y, z), body-to-earth with earth z up, or None if none is new."""
        return self.dmp_model.read(self.t)

    def baro(self) -> tuple[int, int]:
        """MS5611: (pressure Pa, temperature 0.01 degC)."""
        return self.baro_model.read(self.t, -self.d)

    def battery(self) -> int:
        """Pack voltage in 10 mV units."""
        return self.adc.read(self.volts)

    @property
    def truth(self) -> Truth:
        phi, theta, psi = quat_to_euler(self.qw, self.qx, self.qy, self.qz)
        return Truth(self.t, self.n, self.e, -self.d, self.vn, self.ve, self.vd, phi, theta, psi,
                     self.p, self.q, self.r, self.qw, self.qx, self.qy, self.qz,
                     (self.w1, self.w2, self.w3, self.w4), self.volts, self.current, self.soc, self.on_ground)

    def energy(self) -> float:
        """Kinetic plus potential energy (J), for checks of the integrator."""
        v2 = self.vn * self.vn + self.ve * self.ve + self.vd * self.vd
        rot = P.IXX * self.p * self.p + P.IYY * self.q * self.q + P.IZZ * self.r * self.r
        return 0.5 * P.MASS * v2 + 0.5 * rot + P.MASS * P.G * (-self.d)

    # ---- integration -----------------------------------------------------------------------------------------
    def _update_targets(self) -> None:
        k = self._omega_per_ae = P.OMEGA_PER_AE * self.volts / P.V_REF  # the ESC's speed scales with the supply
        c = self.cmd
        self._targets = [c[0] * k, c[1] * k, c[2] * k, c[3] * k]

    def _update_forcing(self) -> None:
        """Air velocity (NED), the external force and torque, and the drag's moment, scaled as the integrator
        uses them. Refreshed every SLOW_EVERY steps: the wind and the speed change slowly."""
        dt = self.dt
        mn, me, md = self.wind_mean
        g = self.gust
        x = self.ext
        m = P.MASS
        wn, we, wd = mn + g[0], me + g[1], md + g[2]
        tx, ty = x[3], x[4]
        if self.drag_lin > 0.0:
            # the drag acts at the rotor plane, DRAG_CP_HEIGHT above the centre of mass: moment r x F in the body
            # frame with r = (0, 0, -h), F = R^T (-k (v - wind)); a gust tilts the quadrotor (rotor flapping)
            k = self.drag_lin
            fn, fe, fd = -k * (self.vn - wn), -k * (self.ve - we), -k * (self.vd - wd)
            qw, qx, qy, qz = self.qw, self.qx, self.qy, self.qz
            fbx = (1 - 2 * (qy * qy + qz * qz)) * fn + 2 * (qx * qy + qw * qz) * fe + 2 * (qx * qz - qw * qy) * fd
            fby = 2 * (qx * qy - qw * qz) * fn + (1 - 2 * (qx * qx + qz * qz)) * fe + 2 * (qy * qz + qw * qx) * fd
            h = P.DRAG_CP_HEIGHT
            tx += h * fby
            ty -= h * fbx
        self._forcing = (wn, we, wd, x[0] / m, x[1] / m, x[2] / m + P.G,
                         tx / P.IXX * dt, ty / P.IYY * dt, x[5] / P.IZZ * dt)

    def _slow(self, dt: float) -> None:
        """Battery, wind and pushes, every SLOW_EVERY steps."""
        w1, w2, w3, w4 = self.w1, self.w2, self.w3, self.w4
        power = P.POWER_COEF * (w1 * w1 * w1 + w2 * w2 * w2 + w3 * w3 * w3 + w4 * w4 * w4)
        self.current = power / max(self.volts, 1.0) + P.AVIONICS_CURRENT
        self.soc = max(0.0, self.soc - self.current * dt / (3600.0 * P.CAPACITY_AH))
        self.volts = max(0.0, P.ocv(self.soc) - self.current * P.R_INTERNAL)
        self._update_targets()
        if self.gust_std > 0.0:
            nt = self.noise
            i = nt.take(3)
            a = dt / self.gust_tau
            s = self.gust_std * math.sqrt(2.0 * a)
            g = self.gust
            for j in range(3):
                g[j] += -g[j] * a + s * nt.tab[i + j]
        if self.pushes:
            t = self.t
            tot = [0.0] * 6
            keep = []
            for t0, t1, f in self.pushes:
                if t < t1:
                    keep.append((t0, t1, f))
                    if t >= t0:
                        for j in range(6):
                            tot[j] += f[j]
            self.pushes = keep
            self.ext = tuple(tot)
        elif self.ext != (0.0, 0.0, 0.0, 0.0, 0.0, 0.0):
            self.ext = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._update_forcing()

    def _impact(self, t: float, vn: float, ve: float, vd: float, qx: float, qy: float, where: str) -> None:
        """A hit on the floor, the ceiling or a wall: a crash if too fast or (on the floor) too tilted."""
        speed = math.sqrt(vn * vn + ve * ve + vd * vd)
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (qx * qx + qy * qy)))))
        if speed > P.CRASH_SPEED_M_S or (where == "ground" and tilt > P.CRASH_TILT_DEG):
            self.crashes.append(Crash(t, speed, tilt, where))

    @property
    def contact(self) -> str:
        """What the craft touches now: "ground", "ceiling", "wall" or "" (within the last physics step or two)."""
        if self.on_ground:
            return "ground"
        for where in ("ceiling", "wall"):
            if self.t - self._touch_t[where] <= 2.5 * self.dt:
                return where
        return ""

    def _contact(self, t: float, where: str, vn: float, ve: float, vd: float) -> None:
        """A step that ended at a surface with this speed into it (NED, m/s): the jolt the accelerometer feels, and
        a new ``Contact`` unless the craft touched the same surface within CONTACT_REPEAT_S."""
        speed = math.sqrt(vn * vn + ve * ve + vd * vd)
        if t - self._touch_t[where] > 1.5 * self.dt:  # a new touch (pressed on it, each step touches again)
            k = -1.0 / P.JOLT_S
            self._jolt = (vn * k, ve * k, vd * k)
            self._jolt_until = t + P.JOLT_S
        if t - self._touch_t[where] > P.CONTACT_REPEAT_S:
            self.contacts.append(Contact(t, where, speed))
        self._touch_t[where] = t

    def advance_to(self, t: float) -> None:
        """Integrate in fixed steps up to time ``t`` (s); a time in the past does nothing. The steps run in
        stretches up to the next periodic event (``_event``), inlined on locals (CPython is much faster with them
        than with attribute access in the hot loop)."""
        dt = self.dt
        k_end = int(t / dt + 1e-9)
        while self.k < k_end:
            k_stop = self._next_evt if self._next_evt < k_end else k_end
            n, e, d, vn, ve, vd = self.n, self.e, self.d, self.vn, self.ve, self.vd
            qw, qx, qy, qz, p, q, r = self.qw, self.qx, self.qy, self.qz, self.p, self.q, self.r
            w1, w2, w3, w4 = self.w1, self.w2, self.w3, self.w4
            on_ground, ground, ceiling_d, wall = self.on_ground, self.ground_enabled, self.ceiling_d, self.wall
            c1, c2, c3, c4 = self._targets
            alpha, kbm, klm, kl, km, kn, dpx, dpy, dpz, gx_, gy_, gz_, hdt = self._consts
            wn, we, wd, fxn, fxe, fxdg, txb, tyb, tzb = self._forcing
            for k in range(self.k + 1, k_stop + 1):  # (at least one step: an, ae, ad are always set)
                # motors: exact first-order response
                w1 += (c1 - w1) * alpha
                w2 += (c2 - w2) * alpha
                w3 += (c3 - w3) * alpha
                w4 += (c4 - w4) * alpha
                s1 = w1 * w1
                s2 = w2 * w2
                s3 = w3 * w3
                s4 = w4 * w4
                ta = kbm * (s1 + s2 + s3 + s4)
                t2 = ta + ta
                # translational: thrust along body -z (third column of R), drag against the air, in NED
                an = fxn - t2 * (qx * qz + qw * qy) - klm * (vn - wn)
                ae = fxe - t2 * (qy * qz - qw * qx) - klm * (ve - we)
                ad = fxdg - ta + t2 * (qx * qx + qy * qy) - klm * (vd - wd)
                if on_ground and ad >= 0.0:
                    an = ae = ad = 0.0  # resting on the feet: the floor carries what the rotors do not
                    continue
                on_ground = False  # (take-off when the thrust beats the weight)
                vn, ve, vd = vn + an * dt, ve + ae * dt, vd + ad * dt
                n, e, d = n + vn * dt, e + ve * dt, d + vd * dt
                # rotational: Euler's equations in the body frame (explicit, pre-scaled)
                p, q, r = (p + kl * (s4 - s2) - dpx * p + txb - gx_ * q * r,
                           q + km * (s1 - s3) - dpy * q + tyb - gy_ * r * p,
                           r + kn * (s2 + s4 - s1 - s3) - dpz * r + tzb - gz_ * p * q)
                hp, hq, hr = p * hdt, q * hdt, r * hdt
                qw, qx, qy, qz = (qw - qx * hp - qy * hq - qz * hr, qx + qw * hp + qy * hr - qz * hq,
                                  qy + qw * hq + qz * hp - qx * hr, qz + qw * hr + qx * hq - qy * hp)
                if d < ceiling_d:  # the ceiling stops the climb and carries the push (the accelerometer feels it)
                    self._impact(k * dt, vn, ve, vd, qx, qy, "ceiling")
                    self._contact(k * dt, "ceiling", 0.0, 0.0, vd)
                    d, vd = ceiling_d, 0.0
                    ad = ad if ad > 0.0 else 0.0
                if n > wall or n < -wall:  # a wall: the speed into it stops, the craft slides along it
                    self._impact(k * dt, vn, 0.0, 0.0, qx, qy, "wall")
                    self._contact(k * dt, "wall", vn, 0.0, 0.0)
                    n, vn = (wall if n > 0.0 else -wall), 0.0
                    an = 0.0 if an * n > 0.0 else an
                if e > wall or e < -wall:
                    self._impact(k * dt, 0.0, ve, 0.0, qx, qy, "wall")
                    self._contact(k * dt, "wall", 0.0, ve, 0.0)
                    e, ve = (wall if e > 0.0 else -wall), 0.0
                    ae = 0.0 if ae * e > 0.0 else ae
                if ground and d > 0.0:  # touch-down: inelastic
                    qw, qx, qy, qz = self._touch_down(k * dt, vn, ve, vd, qw, qx, qy, qz)
                    d = vn = ve = vd = an = ae = ad = p = q = r = 0.0
                    on_ground = True
            self.n, self.e, self.d, self.vn, self.ve, self.vd = n, e, d, vn, ve, vd
            self.qw, self.qx, self.qy, self.qz, self.p, self.q, self.r = qw, qx, qy, qz, p, q, r
            self.w1, self.w2, self.w3, self.w4 = w1, w2, w3, w4
            self.acc_n, self.acc_e, self.acc_d, self.on_ground = an, ae, ad, on_ground
            self.k, self.t = k_stop, k_stop * dt
            if k_stop == self._next_evt:
                self._event(k_stop)

    def _event(self, k: int) -> None:
        """The periodic event at step ``k`` (every DMP sample and every SLOW_EVERY steps): the attitude
        renormalised by one Newton step for 1/sqrt(n2) (n2 stays within 1e-5 of 1 in between), then the DMP model
        samples it and the slow parts are updated."""
        qw, qx, qy, qz = self.qw, self.qx, self.qy, self.qz
        f = 1.5 - 0.5 * (qw * qw + qx * qx + qy * qy + qz * qz)
        self.qw, self.qx, self.qy, self.qz = qw * f, qx * f, qy * f, qz * f
        if k % self._dmp_every == 0:
            self.dmp_model.sample(k * self.dt, self.qw, self.qx, self.qy, self.qz)
        if k % SLOW_EVERY == 0:
            self._slow(SLOW_EVERY * self.dt)
        self._schedule(k)

    def _schedule(self, k: int) -> None:
        """The step of the next periodic event after step ``k``."""
        next_dmp = (k // self._dmp_every + 1) * self._dmp_every
        next_slow = (k // SLOW_EVERY + 1) * SLOW_EVERY
        self._next_evt = next_dmp if next_dmp < next_slow else next_slow

    def _touch_down(self, t: float, vn: float, ve: float, vd: float,
                    qw: float, qx: float, qy: float, qz: float) -> tuple[float, float, float, float]:
        """Record a landing (and a crash if it was one); the attitude levelled on the legs, yaw kept."""
        self.landings.append((t, vd))
        self._impact(t, vn, ve, vd, qx, qy, "ground")
        self._contact(t, "ground", vn, ve, vd)
        psi = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        return math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)
