"""Height estimation from barometer and accelerometer: the report's Figure 10 (section 3.8) as the documented
baseline, ``HeightEstimator``, and the robust estimator the board flies, ``HeightKalman``.

``make_height_estimator(name)`` builds either (``HEIGHT_ESTIMATORS``; ``HEIGHT_BEST`` is the board's default).
Both have the seam's interface: ``update_imu(ax, ay, az, qw, qx, qy, qz, dt)``, ``update_baro(pressure_pa, dt)``,
``reset(pressure_pa)``, attributes ``height`` (m, up, relative to the reset point) and ``vz`` (m/s, up), plus
``baro_rejected`` (readings the spike guard refused or took as a spike's onset, for telemetry).

HeightKalman: a Kalman filter on height, vertical speed, accelerometer bias and the barometer's spike, with a
robust barometer update, because the spikes (Figure 9: a sudden jump that decays; the simulator draws 0.3-1.3 m
decaying over 0.1-0.5 s, so several 20 Hz samples in a row) are what failed the HEIGHT hold with the
complementary filter (0.16 m rms; a median-of-3 cannot remove them, a fixed spike gate lets their tails in):

* prediction at every IMU sample (400 Hz): the earth-frame vertical acceleration (the rotation described below)
  minus the bias estimate is integrated into speed and height. The covariance is propagated once per baro
  sample over the elapsed time (exact for this linear model, F(T) = F(dt)^n), so the 400 Hz path costs what
  the complementary filter costs. Process noise: white acceleration (the motor vibration, default
  0.075 m/s²/√Hz = the simulator's 0.15 g rms at 400 Hz) and a random-walk bias (0.005 m/s²/√s);
* the barometer reads height + spike + noise (0.105 m: the MS5611's 1.2 Pa rms at OSR 4096 and its 1 Pa
  steps). The spike state decays (tau 0.3 s) with an uncertain rate (σ 5/s, the 2-10/s of the spikes), and
  while no spike runs its variance is (1 mm)², so the filter does not blame noise on it;
* each innovation (baro minus the accelerometer-predicted reading) is judged in units of its predicted
  standard deviation: beyond ``gate_sigma`` (3) it is the onset of a spike, of unknown size, so the spike's
  variance takes the whole innovation and the update gives it to the spike, not to the height. The tail that
  follows is then explained by the decaying spike instead of dragging the height, the speed and the bias
  along; between ``huber_sigma`` (2) and the gate its variance is scaled up (a Huber weight);
* never locked out: a real climb is seen by the accelerometer, so its innovations stay small (no reading of a
  hard 1 m climb in 0.6 s is taken for a spike). A lasting change the accelerometer did not see (weather, a
  door, a bias the filter got wrong) is first taken as a spike, but it does not decay: while the spike state
  shrinks the height's variance grows, and the filter moves the difference into the height (a 1 m baro step
  is on the new level within 2-5 s); if instead the onsets repeat with the same sign (``level_after`` in a
  row, each within ``rejump_window_s``) the difference is declared a level change and goes to the height.
* ``capture()`` remembers the height of an instant (HEIGHT's set point) as a clone state that keeps its
  covariance with the live states, so every later reading refines it (stochastic cloning: a fixed-lag
  smoother of that one instant). Its error is about half the live estimate's at the instant (tests), and the
  hold no longer keeps an unlucky instant's error for the rest of the flight (seeds 1-32: 0.078 -> 0.070 m rms
  mean, worst 0.124 -> 0.107 m).

Figures (HEIGHT hold, 30 s, P 400 / D 400 / I 100, seeds 1-12): 0.077 m rms mean, worst 0.107 m, against
0.167 / 0.38 m with the complementary filter (on its own gains, P 120 / D 320; on these it does worse, 0.25 m);
without spikes 0.068 / 0.096 m (the floor: the estimate's error at 20 Hz baro noise and 0.15 g vibration,
about 4 cm, and the baro's drift); with three times the spike rate 0.084 / 0.123 m (complementary
0.40 / 0.56 m).

HeightEstimator (the baseline): the report's Figure 10, after Klas Löfstedt's altitude estimator [9].

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


def reference(pressure_pa: float, temperature_k: float) -> tuple[float, float]:
    """A reset's reference pressure and the eq. 3 slope there (Pa per metre); ValueError for a bad pressure."""
    if not pressure_pa > 0.0:
        raise ValueError(f"reference pressure must be positive, got {pressure_pa!r}")
    return float(pressure_pa), pa_per_metre(pressure_pa, temperature_k)


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
        self.p_ref, self.k_pa_per_m = reference(pressure_pa, self.temperature_k)
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


# HeightKalman defaults (module docstring).
ACC_NOISE_DENSITY = 0.075  # m/s²/√Hz: 0.15 g rms of motor vibration, white at 400 Hz (params.VIB_ACC_G)
BIAS_WALK = 0.005  # m/s²/√s: the accelerometer's bias walk (2e-4 g/√s) with margin for attitude errors
BARO_SIGMA_M = 0.105  # m: 1.2 Pa rms noise and 1 Pa quantisation at 11.8 Pa/m
SPIKE_TAU_S = 0.3  # s: assumed decay of a spike (Figure 9; the simulator draws 0.1-0.5 s)
SPIKE_RATE_SIGMA = 5.0  # 1/s: uncertainty of the decay rate 1/tau (1/0.5 to 1/0.1 s is 2 to 10 per s)
INITIAL_SIGMA = (0.03, 0.05, 0.1)  # m, m/s, m/s²: at reset (on the floor after calibration)
_SS_FLOOR = 1e-6  # m²: spike variance when no spike is running (keeps the filter from trusting s = 0 blindly)


class HeightKalman:
    """Height (m, up, relative to the reset point), vertical speed (m/s, up), accelerometer bias (m/s²) and the
    barometer's spike (m) by a Kalman filter with a spike-robust barometer update (module docstring)."""

    def __init__(
        self,
        *,
        acc_noise_density: float = ACC_NOISE_DENSITY,
        bias_walk: float = BIAS_WALK,
        baro_sigma_m: float = BARO_SIGMA_M,
        spike_tau_s: float = SPIKE_TAU_S,
        spike_rate_sigma: float = SPIKE_RATE_SIGMA,
        gate_sigma: float = 3.0,
        huber_sigma: float = 2.0,
        level_after: int = 3,
        rejump_window_s: float = 1.0,
        temperature_k: float = T_ROOM,
    ) -> None:
        self.q_acc = acc_noise_density * acc_noise_density  # PSD, m²/s³
        self.q_bias = bias_walk * bias_walk  # PSD, m²/s⁵
        self.r = baro_sigma_m * baro_sigma_m
        self.spike_tau_s = spike_tau_s
        self.spike_rate_sigma = spike_rate_sigma
        self.gate_sigma = gate_sigma
        self.huber_sigma = huber_sigma
        self.level_after = level_after
        self.rejump_window_s = rejump_window_s
        self.temperature_k = temperature_k
        self.reset(SEA_LEVEL_PA)

    def reset(self, pressure_pa: float) -> None:
        """Start again at height 0, at rest, with this pressure as the reference."""
        self.p_ref, self.k_pa_per_m = reference(pressure_pa, self.temperature_k)
        self.height = 0.0
        self.vz = 0.0
        self.bias = 0.0  # m/s², earth-up accelerometer bias estimate
        self.spike = 0.0  # m, the barometer's spike offset estimate (its reading is height + spike + noise)
        self.az_earth = 0.0  # bias-corrected vertical acceleration, m/s² (telemetry)
        self.baro_raw = 0.0  # eq. 3 height of the last pressure sample
        self.innovation = 0.0  # baro minus prediction at the last sample, m
        sh, sv, sb = INITIAL_SIGMA
        # covariance, symmetric, order h v b s: hh hv hb hs vv vb vs bb bs ss
        self.p = [sh * sh, 0.0, 0.0, 0.0, sv * sv, 0.0, 0.0, sb * sb, 0.0, _SS_FLOOR]
        self._t_pred = 0.0  # s of IMU prediction since the covariance was last propagated
        self._jump_sign = 0  # sign of the last spike onset
        self._rejumps = 0  # onsets in a row with the same sign, each within rejump_window_s of the last
        self._t_jump = math.inf  # s since the last spike onset
        self.baro_rejected = 0  # readings taken as the onset of a spike (telemetry)
        self.level_changes = 0  # lasting baro changes taken as real (telemetry)
        # the height at the last capture(), a clone state refined by every later reading (stochastic cloning)
        self.captured_height = 0.0
        self._c = [0.0, 0.0, 0.0, 0.0]  # its covariance with h, v, b, s
        self._c00 = 0.0

    def capture(self) -> float:
        """Remember the height of this instant (HEIGHT's set point) and return it. Unlike a copy of ``height``,
        ``captured_height`` keeps improving as later readings arrive (its covariance with the live states is
        carried along), so a set point taken at a noisy instant settles on where the quadcopter really was
        (the fixed-lag smoother's estimate) within a second or two."""
        if self._t_pred > 0.0:
            self._propagate(self._t_pred)
            self._t_pred = 0.0
        p = self.p
        self.captured_height = self.height
        self._c = [p[0], p[1], p[2], p[3]]
        self._c00 = p[0]
        return self.height

    def baro_to_height(self, pressure_pa: float) -> float:
        """Eq. 3 with the units made right: metres above the reset point (pressure in Pa)."""
        return (pressure_pa - self.p_ref) / -self.k_pa_per_m

    def update_imu(
        self, ax: float, ay: float, az: float, qw: float, qx: float, qy: float, qz: float, dt: float
    ) -> None:
        """A new IMU sample: chip-frame specific force (m/s², z up), attitude quaternion body-to-earth."""
        if dt <= 0.0:
            return
        # Earth-up component of the specific force (third row of R(q)), minus gravity and the bias estimate.
        a = (
            2.0 * (qx * qz - qw * qy) * ax
            + 2.0 * (qy * qz + qw * qx) * ay
            + (qw * qw - qx * qx - qy * qy + qz * qz) * az
            - G
            - self.bias
        )
        self.az_earth = a
        v = self.vz
        self.height += (v + 0.5 * a * dt) * dt
        self.vz = v + a * dt
        self._t_pred += dt

    def _propagate(self, t: float) -> None:
        """State spike and covariance over ``t`` s: P = F P F' + Q with
        F = [[1, t, -t²/2, 0], [0, 1, -t, 0], [0, 0, 1, 0], [0, 0, 0, phi]], phi = exp(-t / spike_tau_s)."""
        hh, hv, hb, hs, vv, vb, vs, bb, bs, ss = self.p
        phi = math.exp(-t / self.spike_tau_s)
        c = 0.5 * t * t
        # row h of F P (columns h v b s), row v (v b s)
        ah = hh + t * hv - c * hb
        av = hv + t * vv - c * vb
        ab = hb + t * vb - c * bb
        as_ = hs + t * vs - c * bs
        bv = vv - t * vb
        bb_ = vb - t * bb
        bs_ = vs - t * bs
        qa, qb = self.q_acc, self.q_bias
        t3 = t * t * t
        ch, cv, cb, cs = self._c
        self._c = [ch + t * cv - c * cb, cv - t * cb, cb, phi * cs]
        s = self.spike * phi
        self.spike = s
        # the decay rate is uncertain: d(s)/d(rate) = -t s
        ds = t * s * self.spike_rate_sigma
        self.p = [
            ah + t * av - c * ab + qa * t3 / 3.0 + qb * t3 * t * t / 20.0,
            av - t * ab + qa * t * t / 2.0 + qb * t3 * t / 8.0,
            ab - qb * t3 / 6.0,
            phi * as_,
            bv - t * bb_ + qa * t + qb * t3 / 3.0,
            bb_ - qb * t * t / 2.0,
            phi * bs_,
            bb + qb * t,
            phi * bs,
            phi * phi * ss + ds * ds + _SS_FLOOR * (1.0 - phi * phi),
        ]

    def update_baro(self, pressure_pa: float, dt: float) -> None:
        """A new pressure sample (Pa); dt is the time since the previous pressure sample (s)."""
        z = self.baro_to_height(pressure_pa)
        self.baro_raw = z
        # the IMU's clock decides how far the state was predicted; dt only if no IMU sample came in between
        t = self._t_pred if self._t_pred > 0.0 else max(0.0, dt)
        self._t_pred = 0.0
        if t > 0.0:
            self._propagate(t)
        self._t_jump += t
        p = self.p
        nu = z - self.height - self.spike
        self.innovation = nu
        r = self.r
        s = p[0] + 2.0 * p[3] + p[9] + r
        r_sigma = abs(nu) / math.sqrt(s)
        if r_sigma > self.gate_sigma:
            # Far outside what the accelerometer predicts: the onset of a spike. Its size is unknown, so the
            # spike's variance takes the whole innovation and the update below gives it to the spike, not to
            # the height. A spike decays; onsets of the same sign again and again mean it does not: a real
            # change of the barometer's level, which then goes to the height.
            self.baro_rejected += 1
            sign = 1 if nu > 0.0 else -1
            same = sign == self._jump_sign and self._t_jump < self.rejump_window_s
            self._rejumps = self._rejumps + 1 if same else 0
            self._jump_sign = sign
            self._t_jump = 0.0
            if self._rejumps >= self.level_after:
                self._rejumps = 0
                self.level_changes += 1
                hh, hv, hb, hs, vv, vb, vs, bb, bs, ss = p
                # fold the spike into the height (h' = h + s), then own the new level's uncertainty
                self.height += self.spike
                self.spike = 0.0
                c_ = self._c
                self._c = [c_[0] + c_[3], c_[1], c_[2], 0.0]
                nu = z - self.height
                p = [hh + 2.0 * hs + ss + nu * nu, hv + vs, hb + bs, 0.0, vv, vb, 0.0, bb, 0.0, _SS_FLOOR]
            else:
                p[9] += nu * nu
        elif r_sigma > self.huber_sigma:
            # a moderate outlier counts less (Huber weight)
            r *= r_sigma / self.huber_sigma
        hh, hv, hb, hs, vv, vb, vs, bb, bs, ss = p
        gh, gv, gb, gs = hh + hs, hv + vs, hb + bs, hs + ss  # P H', H = [1, 0, 0, 1]
        s = gh + gs + r
        kh, kv, kb, ks = gh / s, gv / s, gb / s, gs / s
        self.height += kh * nu
        self.vz += kv * nu
        self.bias += kb * nu
        self.spike += ks * nu
        ch, cv, cb, cs = self._c
        g0 = ch + cs
        k0 = g0 / s
        self.captured_height += k0 * nu
        self._c = [ch - k0 * gh, cv - k0 * gv, cb - k0 * gb, cs - k0 * gs]
        self._c00 -= k0 * g0
        self.p = [
            hh - kh * gh, hv - kh * gv, hb - kh * gb, hs - kh * gs,
            vv - kv * gv, vb - kv * gb, vs - kv * gs,
            bb - kb * gb, bs - kb * gs,
            ss - ks * gs,
        ]


HEIGHT_ESTIMATORS: tuple[str, ...] = ("complementary", "kalman")
HEIGHT_BEST = "kalman"


def make_height_estimator(name: str = HEIGHT_BEST, **kw: float | bool) -> HeightEstimator | HeightKalman:
    """``"kalman"``: the robust HeightKalman (the board's default); ``"complementary"``: the report's Figure 10
    as HEIGHT flies it (without the baro high-pass, see fcb_sim/flight.py). Keyword arguments go to the class."""
    if name == "kalman":
        return HeightKalman(**kw)
    if name == "complementary":
        kw.setdefault("baro_highpass_hz", 0.0)
        return HeightEstimator(**kw)
    raise ValueError(f"unknown height estimator {name!r}; choose from {', '.join(HEIGHT_ESTIMATORS)}")
