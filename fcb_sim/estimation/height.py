"""Height estimator of the report's Figure 10 (section 3.8): barometer and accelerometer, two complementary
filters, after Klas Löfstedt's altitude estimator [9].

Pipeline, one step per sample:

* Barometer (``update_baro``): pressure -> height by the linearised barometric formula (eq. 3) relative to
  the pressure at ``reset``. Beyond the report, two optional spike guards (Figure 9), both off by default:
  ``median3`` (median of the last three samples: removes single-sample spikes, costs a sample of delay; our
  simulated spikes last 0.1-0.5 s, so it only adds delay there) and ``spike_gate_m`` (skip readings farther
  than this from the estimate, for at most ``spike_hold_s``, then re-lock; with 0.3 m the simulator's
  HEIGHT hold improved on three seeds of four (0.11 -> 0.06-0.09 m rms) and got worse on one (0.20 -> 0.39 m:
  a slowly decaying spike is let in half-way), so it stays off by default. Then two paths, as the report's
  text describes them:
  - velocity path: 0.1 Hz high-pass (removes slow drift: temperature, supply, weather) -> low-pass (the
    report's "low pass filtered barometer readings", about 0.3 s) -> difference quotient = ``baro_vz``;
  - position path: the *absolute* reading ("combined with the absolute barometer reading to obtain the
    current position") -> the same low-pass = ``baro_height``.
  A high-pass on the position path too (``position_highpass_hz``, default off) would make every lasting
  height change decay with tau = 1.6 s: a HEIGHT hold around a captured set point then climbs or sinks
  without end (tried in the simulator: +2 m in 15 s), so the default follows the report's text.
* Accelerometer (``update_imu``): chip-frame specific force rotated into the earth frame with the attitude
  quaternion, gravity removed -> 0.1 Hz high-pass (absorbs a calibration offset or a tilted calibration).
* Velocity complementary filter: ``vz = a_v (vz + a dt) + (1 - a_v) baro_vz``, α_velocity = 0.995.
* Position complementary filter: ``height = a_p (height + vz dt) + (1 - a_p) baro_height``, α_position = 0.98.

The report's α values are per step at its 400 Hz loop. Here they are turned into time constants
(tau = dt_ref α / (1 - α): 0.50 s for velocity, 0.12 s for position) so the filter behaves the same at any
sample rate; at 400 Hz the per-step factor is exactly the report's.

Units of eq. 3. Eq. 2 is P1 = P2 exp(-ΔH / (cT)) with c = R / (M g) = 29.27 m/K; at room temperature
(T = 293.15 K) the scale height cT is 8.58 km. Linearising, P1 ≈ P2 (1 - ΔH / (cT)), so
ΔH = (P1 - P2) / (-P2 / (cT)). Near sea level P2 / (cT) = 101325 Pa / 8581 m = 11.8 Pa/m = 0.118 mbar/m. So
the report's "ΔH = (P1 - P2) / -0.12" is right with pressures in **mbar (hPa)** and ΔH in metres (its own
figures agree: 0.012 mbar ≈ 10 cm, 1.5 mbar ≈ 12.5 m). With pressures in Pa, as our barometer and the
protocol report them, the divisor is -11.8 (Pa per metre); using -0.12 with Pa would overstate heights by
a factor of 100. We compute the divisor from the pressure at reset (P g M / (R T)), which is 11.8 Pa/m at
sea level and smaller at altitude. Over the ±4 m of the lab the linearisation error is about 0.02 %.

Why not eq. 4 literally. Eq. 4, ``sa_zI = sa_zB - (a² - b² - c² + d²) S``, subtracts gravity's projection on
the body z axis from the body-z accelerometer reading: the result is the linear acceleration along body z,
not along earth z (they differ by the factor cos(tilt) and by the leakage of the body x/y accelerations).
The proper rotation takes the third row of the body-to-earth rotation matrix,
``a_up = R20 fx + R21 fy + R22 fz - g`` with ``R22 = w² - x² - y² + z²`` (eq. 4's factor) and
``R20 = 2(xz - wy)``, ``R21 = 2(yz + wx)``. At hover both agree; in a banked turn eq. 4 is wrong by
(1 - cos φ) times the thrust acceleration (0.15 m/s² at 10°), which integrates into metres.
"""

from __future__ import annotations

import math

G = 9.80665  # m/s², standard gravity
R_GAS = 8.314462618  # J/(mol K)
M_AIR = 0.0289644  # kg/mol, molar mass of dry air
T_ROOM = 293.15  # K, the "standard room temperature" of eq. 3
SEA_LEVEL_PA = 101325.0

ALPHA_VELOCITY = 0.995  # report, Figure 11
ALPHA_POSITION = 0.98  # report, Figure 11
ALPHA_RATE_HZ = 400.0  # the loop rate the α values were tuned at (RAW mode)
HIGHPASS_HZ = 0.1  # report: "a very low cut-off frequency (about 0.1 Hz)"
BARO_LOWPASS_S = 0.3  # time constant of the baro low-pass (report: ~0.5 s of added delay)


def pa_per_metre(pressure_pa: float, temperature_k: float = T_ROOM) -> float:
    """dP/dh (positive number, Pa per metre up) of the linearised eq. 2 at this pressure: P g M / (R T)."""
    return pressure_pa * G * M_AIR / (R_GAS * temperature_k)


def _alpha_to_tau(alpha: float, rate_hz: float) -> float:
    dt = 1.0 / rate_hz
    return dt * alpha / (1.0 - alpha)


class HeightEstimator:
    """Height (m, up, relative to the reset point) and vertical speed (m/s, up) from baro and IMU."""

    def __init__(
        self,
        *,
        alpha_velocity: float = ALPHA_VELOCITY,
        alpha_position: float = ALPHA_POSITION,
        alpha_rate_hz: float = ALPHA_RATE_HZ,
        acc_highpass_hz: float = HIGHPASS_HZ,
        baro_highpass_hz: float = HIGHPASS_HZ,
        position_highpass_hz: float = 0.0,
        baro_lowpass_s: float = BARO_LOWPASS_S,
        median3: bool = False,
        spike_gate_m: float = 0.0,
        spike_hold_s: float = 1.0,
        temperature_k: float = T_ROOM,
    ) -> None:
        self.tau_v = _alpha_to_tau(alpha_velocity, alpha_rate_hz)
        self.tau_p = _alpha_to_tau(alpha_position, alpha_rate_hz)
        # First-order high-pass time constants; 0 Hz disables a high-pass.
        self.tau_hp_acc = 1.0 / (2.0 * math.pi * acc_highpass_hz) if acc_highpass_hz > 0.0 else math.inf
        self.tau_hp_baro = 1.0 / (2.0 * math.pi * baro_highpass_hz) if baro_highpass_hz > 0.0 else math.inf
        self.tau_hp_pos = 1.0 / (2.0 * math.pi * position_highpass_hz) if position_highpass_hz > 0.0 else math.inf
        self.baro_lowpass_s = baro_lowpass_s
        self.median3 = median3
        self.spike_gate_m = spike_gate_m
        self.spike_hold_s = spike_hold_s
        self.temperature_k = temperature_k
        self.reset(SEA_LEVEL_PA)

    def reset(self, pressure_pa: float) -> None:
        """Start again at height 0, at rest, with this pressure as the reference."""
        if not pressure_pa > 0.0:
            raise ValueError(f"reference pressure must be positive, got {pressure_pa!r}")
        self.p_ref = float(pressure_pa)
        self.k_pa_per_m = pa_per_metre(self.p_ref, self.temperature_k)
        self.height = 0.0
        self.vz = 0.0
        self.az_earth = 0.0  # linear vertical acceleration after the high-pass, m/s² (for telemetry)
        self.baro_raw = 0.0  # eq. 3 height of the last pressure sample
        self.baro_height = 0.0  # position path: after median and low-pass
        self.baro_vz = 0.0  # velocity path: after median, high-pass, low-pass and difference quotient
        self._hist = [0.0, 0.0, 0.0]
        self._gated_s = 0.0
        self._relock = False
        self.baro_rejected = 0  # samples dropped by the spike gate (telemetry)
        self._hp_b_in = 0.0
        self._hp_b_out = 0.0
        self._lp_v = 0.0
        self._hp_p_out = 0.0
        self._hp_a_in = 0.0
        self._hp_a_out = 0.0
        self._a_primed = False

    def baro_to_height(self, pressure_pa: float) -> float:
        """Eq. 3 with the units made right: metres above the reset point (pressure in Pa)."""
        return (pressure_pa - self.p_ref) / -self.k_pa_per_m

    def update_baro(self, pressure_pa: float, dt: float) -> None:
        """A new pressure sample (Pa); dt is the time since the previous pressure sample (s)."""
        if dt <= 0.0:
            return
        h = self.baro_to_height(pressure_pa)
        self.baro_raw = h
        if self.median3:
            hist = self._hist
            hist[0], hist[1], hist[2] = hist[1], hist[2], h
            a, b, c = hist
            h = max(min(a, b), min(max(a, b), c))
        if self.spike_gate_m > 0.0:
            # Innovation gate: a reading far from the estimate is a spike (Figure 9) and is skipped, for at
            # most spike_hold_s; a difference lasting longer is real (or drift): then every reading is taken
            # until the estimate is back within the gate.
            if abs(h - self.height) > self.spike_gate_m:
                if not self._relock:
                    self._gated_s += dt
                    if self._gated_s <= self.spike_hold_s:
                        self.baro_rejected += 1
                        return
                    self._relock = True
            else:
                self._gated_s = 0.0
                self._relock = False
        lp = dt / (self.baro_lowpass_s + dt) if self.baro_lowpass_s > 0.0 else 1.0
        # Velocity path. High-pass: y = k (y + x - x_prev), k = tau / (tau + dt); then low-pass; then d/dt.
        k = self.tau_hp_baro / (self.tau_hp_baro + dt) if self.tau_hp_baro != math.inf else 1.0
        self._hp_b_out = k * (self._hp_b_out + h - self._hp_b_in)
        prev = self._lp_v
        self._lp_v = prev + lp * (self._hp_b_out - prev)
        self.baro_vz = (self._lp_v - prev) / dt
        # Position path: the absolute reading (optionally high-passed too), low-passed.
        if self.tau_hp_pos != math.inf:
            k = self.tau_hp_pos / (self.tau_hp_pos + dt)
            self._hp_p_out = k * (self._hp_p_out + h - self._hp_b_in)
            x = self._hp_p_out
        else:
            x = h
        self._hp_b_in = h
        self.baro_height += lp * (x - self.baro_height)

    def update_imu(
        self, ax: float, ay: float, az: float, qw: float, qx: float, qy: float, qz: float, dt: float
    ) -> None:
        """A new IMU sample: chip-frame specific force (m/s², z up), attitude quaternion body-to-earth."""
        if dt <= 0.0:
            return
        # Earth-up component of the specific force (third row of R(q)), minus gravity.
        a_up = (
            2.0 * (qx * qz - qw * qy) * ax
            + 2.0 * (qy * qz + qw * qx) * ay
            + (qw * qw - qx * qx - qy * qy + qz * qz) * az
            - G
        )
        if not self._a_primed:
            # Start the high-pass at its input so a constant offset does not kick the velocity.
            self._hp_a_in = a_up
            self._a_primed = True
        k = self.tau_hp_acc / (self.tau_hp_acc + dt) if self.tau_hp_acc != math.inf else 1.0
        self._hp_a_out = k * (self._hp_a_out + a_up - self._hp_a_in)
        self._hp_a_in = a_up
        a = self._hp_a_out
        self.az_earth = a
        av = self.tau_v / (self.tau_v + dt)
        self.vz = av * (self.vz + a * dt) + (1.0 - av) * self.baro_vz
        ap = self.tau_p / (self.tau_p + dt)
        self.height = ap * (self.height + self.vz * dt) + (1.0 - ap) * self.baro_height
