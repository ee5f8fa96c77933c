"""Sensor models of the Quadrupel board: MPU6050 (raw and DMP), MS5611 barometer, battery ADC.

Each model turns the true state (passed in as plain floats by ``physics.World``) into what the firmware reads:

- ``Mpu6050.read``: raw int16 words in the chip frame (x forward, y left, z up; docs/architecture.md), 16.4 LSB
  per deg/s and 16384 LSB per g, with white noise, a per-part offset that random-walks, motor vibration that grows
  with rotor speed squared, the DLPF's lag, quantisation and saturation at the int16 limits.
- ``Dmp``: the DMP's fused quaternion (body-to-earth, earth z up) at 100 Hz, delivered with its latency, a little
  noise and a slow yaw drift.
- ``Ms5611``: compensated pressure in Pa (1 Pa = 0.01 mbar steps) and temperature in 0.01 degC, with 1.2 Pa rms
  noise, slow drift and the sudden spikes of the report's Figure 9.
- ``BatteryAdc``: pack voltage in 10 mV units.

All randomness comes from the one ``random.Random`` of the World, directly or through ``NoiseTable`` (a table of
standard normals drawn from that generator once; reading it is ~20x cheaper than ``random.gauss``), so a seed
fixes every sample. Constants and their sources: constants.py.
"""

from __future__ import annotations

import math
import random
import threading
from collections import deque

from fcb_sim.world import constants as P

_TABLE_BITS = 15
# The tables drawn so far, by the generator's state before the draw: (table, state after). Most worlds of a process
# start from the same few seeds, and drawing 32k normals costs ~20 ms a world (15 s of CPU across the test suite).
_DRAWN: dict[tuple[int, object], tuple[tuple[float, ...], object]] = {}
_DRAWN_MAX = 8  # tables kept (about 1 MB each)
_DRAWN_LOCK = threading.Lock()  # worlds are made on several threads (term --sim's board, a test's)


class NoiseTable:
    """Standard normal samples drawn once from the World's generator, read in sequence; on wrap-around the read
    position jumps to a random place so sequences do not repeat in lock-step. A table drawn before from the same
    generator state is taken again (with the generator left where that draw left it: the same samples after)."""

    __slots__ = ("rng", "tab", "i", "limit")

    def __init__(self, rng: random.Random, bits: int = _TABLE_BITS) -> None:
        self.rng = rng
        n = 1 << bits
        key = (bits, rng.getstate())
        with _DRAWN_LOCK:
            drawn = _DRAWN.get(key)
        if drawn is None:
            gauss = rng.gauss
            drawn = (tuple([gauss(0.0, 1.0) for _ in range(n)]), rng.getstate())
            with _DRAWN_LOCK:
                if len(_DRAWN) >= _DRAWN_MAX:
                    del _DRAWN[next(iter(_DRAWN))]
                _DRAWN[key] = drawn
        else:
            rng.setstate(drawn[1])
        self.tab = drawn[0]
        self.i = 0
        self.limit = n - 16

    def take(self, count: int) -> int:
        """Reserve ``count`` (<= 16) consecutive samples; returns the index of the first."""
        i = self.i
        if i > self.limit:
            i = self.rng.randrange(self.limit)
        self.i = i + count
        return i


class Mpu6050:
    """MPU6050 raw gyro and accelerometer (chip frame FLU, int16 words)."""

    def __init__(self, rng: random.Random, noise: NoiseTable, *, vibration: float = 1.0) -> None:
        self.noise = noise
        self.rng = rng
        u = rng.uniform
        g = P.GYRO_BIAS_DPS * P.GYRO_LSB_PER_DPS
        a = P.ACC_BIAS_G * P.ACC_LSB_PER_G
        # per-part offsets in LSB (chip frame)
        self.gyro_bias = [u(-g, g), u(-g, g), u(-g, g)]
        self.acc_bias = [u(-a, a), u(-a, a), u(-a, a)]
        self.gyro_var = (P.GYRO_NOISE_DPS * P.GYRO_LSB_PER_DPS) ** 2
        self.acc_var = (P.ACC_NOISE_G * P.ACC_LSB_PER_G) ** 2
        self.vib_gyro = P.VIB_GYRO_DPS * P.GYRO_LSB_PER_DPS * vibration
        self.vib_acc = P.VIB_ACC_G * P.ACC_LSB_PER_G * vibration
        self._walk_t = 0.0
        self._last_t: float | None = None
        # DLPF state (true values in LSB, chip frame)
        self._f = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

    def reset_filter(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float) -> None:
        """Start the DLPF at these true chip-frame values (LSB)."""
        self._f = [gx, gy, gz, ax, ay, az]

    def read(self, t: float, p: float, q: float, r: float, fx: float, fy: float, fz: float,
             rotor_sq: float) -> tuple[int, int, int, int, int, int]:
        """One sample at time ``t`` from body (FRD) rates in rad/s, body specific force in m/s² and the mean
        squared rotor speed relative to hover (vibration)."""
        last = self._last_t
        self._last_t = t
        f = self._f
        k = P.RATE_LSB_PER_RAD_S
        s = P.ACC_LSB_PER_MS2
        if last is None:
            # chip frame: x forward, y left, z up
            f[:] = [p * k, -q * k, -r * k, fx * s, -fy * s, -fz * s]
            dt = 0.0
        else:
            dt = t - last
            # first-order stand-in for the DLPF (4.8 ms group delay)
            a = dt / (P.DLPF_DELAY + dt) if dt > 0.0 else 0.0
            ka, sa_ = k * a, s * a
            b = 1.0 - a
            f[0] = f[0] * b + p * ka
            f[1] = f[1] * b - q * ka
            f[2] = f[2] * b - r * ka
            f[3] = f[3] * b + fx * sa_
            f[4] = f[4] * b - fy * sa_
            f[5] = f[5] * b - fz * sa_
        self._walk_t += dt
        if self._walk_t >= 0.1:
            self._walk(self._walk_t)
            self._walk_t = 0.0
        vg = self.vib_gyro * rotor_sq
        va = self.vib_acc * rotor_sq
        sg = math.sqrt(self.gyro_var + vg * vg)
        sa = math.sqrt(self.acc_var + va * va)
        nt = self.noise
        i = nt.i
        if i > nt.limit:
            i = nt.rng.randrange(nt.limit)
        nt.i = i + 6
        tab = nt.tab
        gb = self.gyro_bias
        ab = self.acc_bias
        v0 = round(f[0] + gb[0] + sg * tab[i])
        v1 = round(f[1] + gb[1] + sg * tab[i + 1])
        v2 = round(f[2] + gb[2] + sg * tab[i + 2])
        v3 = round(f[3] + ab[0] + sa * tab[i + 3])
        v4 = round(f[4] + ab[1] + sa * tab[i + 4])
        v5 = round(f[5] + ab[2] + sa * tab[i + 5])
        # saturation at the int16 limits (+-2000 deg/s, +-2 g)
        return (
            -32768 if v0 < -32768 else 32767 if v0 > 32767 else v0,
            -32768 if v1 < -32768 else 32767 if v1 > 32767 else v1,
            -32768 if v2 < -32768 else 32767 if v2 > 32767 else v2,
            -32768 if v3 < -32768 else 32767 if v3 > 32767 else v3,
            -32768 if v4 < -32768 else 32767 if v4 > 32767 else v4,
            -32768 if v5 < -32768 else 32767 if v5 > 32767 else v5,
        )

    def _walk(self, dt: float) -> None:
        nt = self.noise
        i = nt.take(6)
        tab = nt.tab
        sg = P.GYRO_BIAS_WALK_DPS * P.GYRO_LSB_PER_DPS * math.sqrt(dt)
        sa = P.ACC_BIAS_WALK_G * P.ACC_LSB_PER_G * math.sqrt(dt)
        for j in range(3):
            self.gyro_bias[j] += sg * tab[i + j]
            self.acc_bias[j] += sa * tab[i + 3 + j]


class Dmp:
    """The DMP's quaternion output: sampled by the World at DMP_RATE_HZ, ready DMP_LATENCY later."""

    def __init__(self, rng: random.Random, noise: NoiseTable, *, latency: float = P.DMP_LATENCY) -> None:
        self.noise = noise
        self.latency = latency
        self.period = 1.0 / P.DMP_RATE_HZ
        self.yaw_drift = rng.choice((-1.0, 1.0)) * P.DMP_YAW_DRIFT_RAD_S
        self.pending: deque[tuple[float, tuple[float, float, float, float]]] = deque()
        self.latest: tuple[float, float, float, float] | None = None

    def sample(self, t: float, w: float, x: float, y: float, z: float) -> None:
        """Record the fused quaternion for true attitude (FRD body to NED earth) at sample time ``t``."""
        nt = self.noise
        i = nt.take(3)
        tab = nt.tab
        s = 0.5 * P.DMP_NOISE_RAD
        ex, ey = s * tab[i], s * tab[i + 1]
        ez = s * tab[i + 2] + 0.5 * self.yaw_drift * t
        # chip convention: body FLU to earth z up = conjugation of the FRD->NED quaternion by a 180 deg turn about x
        qw, qx, qy, qz = w, x, -y, -z
        # small error rotation in the earth frame: e (x) q
        ow = qw - ex * qx - ey * qy - ez * qz
        ox = qx + ex * qw + ey * qz - ez * qy
        oy = qy - ex * qz + ey * qw + ez * qx
        oz = qz + ex * qy - ey * qx + ez * qw
        n = 1.0 / math.sqrt(ow * ow + ox * ox + oy * oy + oz * oz)
        if ow < 0.0:
            n = -n
        self.pending.append((t + self.latency, (ow * n, ox * n, oy * n, oz * n)))

    def read(self, now: float) -> tuple[float, float, float, float] | None:
        """The newest quaternion that became ready since the last read, or None."""
        pend = self.pending
        out = None
        while pend and pend[0][0] <= now:
            out = pend.popleft()[1]
        if out is not None:
            self.latest = out
        return out


class Ms5611:
    """MS5611 compensated pressure (Pa) and temperature (0.01 degC)."""

    def __init__(self, rng: random.Random, noise: NoiseTable, *, spikes: bool = True, altitude: float = 0.0,
                 spike_rate: float = P.BARO_SPIKE_RATE) -> None:
        self.rng = rng
        self.noise = noise
        self.spikes_enabled = spikes
        self.spike_rate = spike_rate
        self.altitude = altitude
        self.drift = 0.0
        self.spikes: list[tuple[float, float, float]] = []  # (start time, amplitude Pa, decay s)
        self.spike_count = 0
        self._last_t: float | None = None

    def read(self, t: float, height: float) -> tuple[int, int]:
        last = self._last_t
        self._last_t = t
        dt = 0.0 if last is None else max(0.0, t - last)
        rng = self.rng
        nt = self.noise
        i = nt.take(2)
        tab = nt.tab
        self.drift += P.BARO_DRIFT_PA * math.sqrt(dt) * tab[i]
        if self.spikes_enabled and dt > 0.0 and rng.random() < self.spike_rate * dt:
            lo, hi = P.BARO_SPIKE_PA
            amp = rng.uniform(lo, hi) * rng.choice((-1.0, 1.0))
            tau = rng.uniform(*P.BARO_SPIKE_TAU)
            self.spikes.append((t, amp, tau))
            self.spike_count += 1
        spike = 0.0
        if self.spikes:
            keep = []
            for t0, amp, tau in self.spikes:
                age = t - t0
                if age < 6.0 * tau:
                    spike += amp * math.exp(-age / tau)
                    keep.append((t0, amp, tau))
            self.spikes = keep
        pa = P.pressure_at(self.altitude + height) + self.drift + spike + P.BARO_NOISE_PA * tab[i + 1]
        return round(pa / P.BARO_LSB_PA) * int(P.BARO_LSB_PA), round(P.BARO_TEMP_C * 100.0)


class BatteryAdc:
    """Pack voltage as the board's ADC reports it, in 10 mV units."""

    def __init__(self, noise: NoiseTable) -> None:
        self.noise = noise

    def read(self, volts: float) -> int:
        i = self.noise.take(1)
        return max(0, round(volts * 100.0 + P.ADC_NOISE_10MV * self.noise.tab[i]))
