"""Height estimation from barometer and accelerometer: the report's Figure 10 (section 3.8) as the documented
baseline, ``HeightEstimator``, and the robust estimator the board flies, ``HeightKalman``. The derivations, the
figures and why eq. 4 is not used literally: docs/height.md.

``make_height_estimator(name)`` builds either (``HEIGHT_ESTIMATORS``; ``HEIGHT_BEST`` is the board's default).
Both have the seam's interface: ``update_imu(ax, ay, az, qw, qx, qy, qz, dt)`` (chip-frame specific force in
m/s², attitude quaternion), ``update_baro(pressure_pa, dt)``, ``reset(pressure_pa)``, the thrust hint
``motors_off`` (the flight core sets it at every control step), attributes ``height`` (m, up, relative to the
reset point) and ``vz`` (m/s, up), plus ``baro_rejected`` (readings the spike guard refused, for telemetry).
Pressure becomes height by eq. 2 exactly (``baro_height``: cT ln(p_ref / p), at the report's room temperature).

``HeightKalman``: a Kalman filter on height, vertical speed, accelerometer bias and the barometer's spike, with
a spike-robust barometer update (an innovation beyond 3 sigma is the onset of a spike, given to the spike state;
onsets that repeat with one sign are a real level change), and ``capture()`` for HEIGHT's set point (a clone
state every later reading refines). On the ground (no thrust and the accelerometer at rest for
``GROUND_REST_S``) it stops integrating: the speed is zero, the accelerometer's reading is its bias, and the
height is re-anchored to the barometer (a trimmed mean over ``ANCHOR_S``) and then held, so neither a bad
landing nor the barometer's drift moves it (``on_ground``, ``anchored``); on the floor it was calibrated on the
height is 0 at once and the barometer's offset there goes into the reference. A hard stop (a jolt against the
motion, over within 30 ms: the ceiling, a landing) zeroes the speed and makes the height ``unsure`` until the
barometer has pulled it in (``stops``, ``stop_kind``, ``stop_speed``; docs/height.md "Contact"). The thrust model
(``thrust_model``, ``THRUST_MODEL``; on, on both boards) integrates the motors' thrust (the flight core's
``thrust_hint``, the sum of ae² times ``supply_sq``, the pack's (V / V_REF)²) times a gain (the nominal hover's,
then learnt from the accelerometer), less the airframe's drag, instead of the accelerometer's vibration; with the
motors running on the pad the craft is ``on_legs`` (the height held, the speed zero) until that thrust passes the
weight, and the climb is integrated from the floor at once (docs/height.md "The thrust model").

``HeightEstimator``: the report's Figure 10, after Klas Löfstedt's altitude estimator: a velocity and a position
complementary filter between the high-passed earth-frame acceleration and the low-passed barometer, with the
report's alpha values turned into time constants.
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


def baro_height(pressure_pa: float, p_ref: float, k_pa_per_m: float) -> float:
    """Height above the reference (m) by eq. 2, ``cT ln(p_ref / p)`` with ``cT = p_ref / k``; eq. 3 (linear) for
    a pressure that is not positive (nothing a barometer reads)."""
    if pressure_pa > 0.0:
        return p_ref / k_pa_per_m * math.log(p_ref / pressure_pa)
    return (pressure_pa - p_ref) / -k_pa_per_m


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
        self.motors_off = False  # the seam's thrust hint (the Kalman filter uses it; the report's filter does not)
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
        """Metres above the reset point (pressure in Pa): eq. 2 exactly, cT ln(p_ref / p) (eq. 3's linear form is
        5 cm short at 30 m)."""
        return baro_height(pressure_pa, self.p_ref, self.k_pa_per_m)

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


# On the ground (HeightKalman, docs/board.md "Height on the ground"): no thrust and the accelerometer at rest this
# long means the craft stands on something; the barometer over ANCHOR_S then gives the height, which is held.
GROUND_REST_S = 0.5
REST_ACC = 0.5  # m/s²: |specific force| within this of g is at rest (no thrust, no vibration, no fall, no carry)
ANCHOR_S = 1.0  # s of barometer readings (a trimmed mean: spikes and noise out) to re-anchor the height
REST_TAU_S = 0.05  # s: |specific force| - g is low-passed this long before the rest test (idle motors vibrate)
# The floor the craft was calibrated on is height 0: a touch-down this close to it is on that floor, so the height
# is 0 at once and the barometer's reading there is its offset (the reference follows it); farther (a table, a
# step) the barometer's trimmed mean gives the height, as before.
GROUND_SNAP_M = 0.5
# A hard stop (docs/height.md "Contact"): a surface stops the craft in about 10 ms, a jolt the accelerometer feels
# (clipped at 2 g) against the estimated motion. A run of STOP_SAMPLES to STOP_MAX_SAMPLES samples beyond STOP_ACC
# against a speed of at least STOP_VZ is a stop, when it ends: the speed is zero, the jolt's tail is not integrated
# for STOP_HOLD_S, and the height is unsure by STOP_H_SIGMA (where the surface is only the barometer says) until
# the barometer has pulled it in.
# STOP_ACC is 1 g: a surface stopping 0.15 m/s in 10 ms is 1.5 g; the motors' braking with their vibration (up to
# 0.5 g and 0.3 g rms at full thrust) crossed 0.7 g in runs short enough to be taken for a stop (the descent from
# 30 m of tests/estimation/test_height_profile.py).
STOP_ACC = 6.9  # m/s²
STOP_VZ = 0.15  # m/s
# A stop going down is a landing only near the floor the board knows (the calibration's): the motors braking a
# descent, their vibration on top, crossed STOP_ACC in runs short enough to look like one, 5 m up (the descent from
# 30 m of tests/estimation/test_height_profile.py). Elsewhere a landing is found by the rest test, as before.
STOP_FLOOR_M = 1.0
STOP_SAMPLES = 2
STOP_MAX_SAMPLES = 12  # 30 ms: a longer run is braking by the motors (their 30 ms lag), not a surface
STOP_HOLD_S = 0.01
STOP_H_SIGMA = 0.3  # m
UNSURE_SIGMA = 0.15  # m: a height less certain than this is flagged unsure (telemetry, the screen)
STOP_UP, STOP_DOWN = 2, 1  # the kinds of a hard stop: the ceiling (going up), the ground (a landing)
# While the craft stands anchored, the barometer's slow drift (weather, self-heating: minutes on the pad at term
# --sim) is followed by a mean of this time constant, each reading's pull clipped (a spike moves it little); at
# lift-off the reference pressure takes that drift out, so the climb starts from the held height (issue 22).
STAND_TAU_S = 2.0
STAND_CLIP_M = 0.1
GROUND_BIAS_TAU_S = 2.0  # s: on the ground the accelerometer's earth-up reading is its bias

# HeightKalman defaults (module docstring).
ACC_NOISE_DENSITY = 0.075  # m/s²/√Hz: 0.15 g rms of motor vibration, white at 400 Hz (params.VIB_ACC_G)
BIAS_WALK = 0.005  # m/s²/√s: the accelerometer's bias walk (2e-4 g/√s) with margin for attitude errors
BARO_SIGMA_M = 0.105  # m: 1.2 Pa rms noise and 1 Pa quantisation at 11.8 Pa/m
SPIKE_TAU_S = 0.3  # s: assumed decay of a spike (Figure 9; the simulator draws 0.1-0.5 s)
SPIKE_RATE_SIGMA = 5.0  # 1/s: uncertainty of the decay rate 1/tau (1/0.5 to 1/0.1 s is 2 to 10 per s)
INITIAL_SIGMA = (0.03, 0.05, 0.1)  # m, m/s, m/s²: at reset (on the floor after calibration)
_SS_FLOOR = 1e-6  # m²: spike variance when no spike is running (keeps the filter from trusting s = 0 blindly)
TREND_GAIN = 0.2  # per baro reading (20 Hz): the innovations' running mean over about a quarter second
TREND_SIGMA = 1.5  # a running mean of this many sigmas of one sign is a wrong speed, not noise
TREND_VZ_VAR = 0.25  # (m/s)² added to the speed's variance at such a reading
# The thrust model (docs/height.md "The thrust model"): the motors' commands, told by the flight core as
# ``thrust_hint`` (the sum of ae² over the four motors times the pack's (V / V_REF)²), predict the specific force
# along the body's z axis as c * u, u the hint lagged by the motors' MOTOR_LAG_S; c (m/s² per ae²) starts at the
# nominal hover's and is learnt from the accelerometer over THRUST_TAU_S. The filter integrates c u (less the
# airframe's drag) instead of the accelerometer's vibration (0.15 g rms at hover): what the model misses (a gust,
# c's error) reaches the height through the bias state and the barometer. A contact (the ceiling, a hand: a force
# the model knows nothing of) shows as the accelerometer's 0.2 s mean (without the drag) leaving the model's by
# THRUST_GATE: that sample integrates the accelerometer and c learns nothing from it. Below THRUST_MIN (the motors
# off or near it) the accelerometer is integrated, as before.
MOTOR_LAG_S = 0.03  # s: the rotors' time constant (fcb_sim/world/constants.py MOTOR_TAU)
THRUST_TAU_S = 10.0  # s
THRUST_FAST_S = 0.2  # s: the accelerometer's mean the gate compares
THRUST_GATE = 0.6  # m/s²
THRUST_MIN = 10000.0  # ae²: four motors at 50
THRUST_ABOVE_M = 0.15  # m: nearer the floor than this the legs may carry it (a force the model does not know)
MODEL_NOISE_DENSITY = 0.04  # m/s²/√Hz: the process noise with the thrust model (what c u misses)
MODEL_BIAS_WALK = 0.02  # m/s²/√s: the bias walk with the thrust model (c's slow error goes to the bias state)
# The thrust model is on on both boards (issue 35; firmware/board/qb_height.c twins it): a keyboard pilot who reads
# the screen holds 1 m with it (docs/height.md "The thrust model"). ``HeightKalman(thrust_model=False)`` turns it
# off, or this switch for every HeightKalman built after it is set (bench.height and bench.keyboard --thrust-model).
THRUST_MODEL = True
# The model's gain before the accelerometer has taught it one: the board's nominal hover (four motors at
# AE_HOVER at a loaded pack of V_REF carry the craft's weight; fcb_sim/world/constants.py AE_HOVER_NOMINAL, V_REF).
# The hint is scaled by (supply / V_REF)² (the ESCs' speed follows the pack's loaded voltage, the thrust its
# square), so the gain is the same on a full pack and a tired one. A flight refines it (THRUST_TAU_S).
AE_HOVER = 400.0
V_REF = 11.4  # V
THRUST_C0 = G / (4.0 * AE_HOVER * AE_HOVER)  # m/s² per ae²
# On the legs (docs/height.md "The thrust model"): motors running on the floor the craft stood on, their modelled
# thrust below the weight: the floor carries it, the height is held and the speed is zero until the model's thrust
# passes the weight (the lift-off: the model's acceleration is integrated from the floor at once, no lag); the
# accelerometer's 0.2 s mean beyond g by THRUST_GATE ends it too (a climb the model's gain missed: a heavier craft).
# The airframe's vertical drag per unit mass (1/s): the specific force the accelerometer feels in a climb or a
# descent besides the thrust (fcb_sim/world/constants.py DRAG_LINEAR / MASS: 0.25 N s/m on 0.65 kg; 0.2 m/s² at
# 0.5 m/s, a quarter of g's 2 %): the model's acceleration and its gain's lesson take it out.
DRAG_PER_S = 0.385


class HeightKalman:
    """Height (m, up, relative to the reset point), vertical speed (m/s, up), accelerometer bias (m/s²) and the
    barometer's spike (m) by a Kalman filter with a spike-robust barometer update (module docstring)."""

    def __init__(
        self,
        *,
        acc_noise_density: float = ACC_NOISE_DENSITY,
        model_noise_density: float = MODEL_NOISE_DENSITY,
        thrust_tau_s: float = THRUST_TAU_S,
        thrust_model: bool | None = None,
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
        self.q_model = model_noise_density * model_noise_density  # PSD with the thrust model, m²/s³
        self.q_model_bias = MODEL_BIAS_WALK * MODEL_BIAS_WALK
        self.thrust_tau_s = thrust_tau_s
        self.thrust_model = THRUST_MODEL if thrust_model is None else thrust_model
        self.q_bias = bias_walk * bias_walk  # PSD, m²/s⁵
        self.r = baro_sigma_m * baro_sigma_m
        self.spike_tau_s = spike_tau_s
        self.spike_rate_sigma = spike_rate_sigma
        self.gate_sigma = gate_sigma
        self.huber_sigma = huber_sigma
        self.level_after = level_after
        self.rejump_window_s = rejump_window_s
        self.temperature_k = temperature_k
        self.motors_off = False  # told by the flight core at every control step: no thrust that could lift it
        self.thrust_hint = 0.0  # told by the flight core at every control step: the sum of ae², times supply_sq
        self.supply_sq = 1.0  # (the pack's loaded voltage / V_REF)², told by the flight core at every battery reading
        # the thrust model's state, kept by a reset (the craft's gain does not change with a calibration)
        self._u = 0.0  # the thrust hint lagged as the rotors follow it (ae²)
        self.thrust_c = THRUST_C0  # m/s² per ae²: the model's gain (the nominal hover's until learnt)
        self._az_fast = G  # the accelerometer's body-z reading over THRUST_FAST_S (m/s²)
        self._u_fast = 0.0  # the lagged thrust hint over THRUST_FAST_S (ae²), to compare with _az_fast
        self.model_on = False  # the last sample integrated the thrust model (telemetry, tests)
        self.on_legs = False  # motors running on the floor, their thrust below the weight (update_imu)
        self._lifting = False  # from the legs until THRUST_ABOVE_M: the model integrated, not re-learnt
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
        self._trend = 0.0  # running mean of the signed, normalised innovations
        self.trend_resets = 0  # times the speed was made unsure by a lasting trend (telemetry)
        self.on_ground = False  # no thrust and at rest for GROUND_REST_S (set by update_imu)
        self.anchored = False  # on the ground, the height re-anchored to the barometer (then held)
        self._stand_baro = 0.0  # while anchored: the barometer's height, slowly followed (its drift)
        self._rest_s = 0.0
        self._ground_baro: list[float] = []
        self._ground_baro_s = 0.0
        self._acc_lp = 0.0  # |specific force| - g, low-passed over REST_TAU_S (m/s²)
        self.ground_ref = 0.0  # m: the floor's height (the reset point is on it)
        self._snapped = False  # on the ground, on that floor: the height is ground_ref
        self._stop_n = 0  # samples in a row of a jolt against the motion
        self._stop_v = 0.0  # the speed when that run began (m/s)
        self._stop_hold = 0.0  # s left of a stop's jolt, not integrated
        self.stops = 0  # hard stops seen (telemetry: the board sends each as an event)
        self.stop_kind = 0  # STOP_UP or STOP_DOWN, of the last
        self.stop_speed = 0.0  # m/s, the estimated speed it stopped
        # the height at the last capture(), a clone state refined by every later reading (stochastic cloning)
        self.captured_height = 0.0
        self._c = [0.0, 0.0, 0.0, 0.0]  # its covariance with h, v, b, s
        self._c00 = 0.0

    def carry_thrust_model(self, other: HeightKalman) -> None:
        """Take over ``other``'s thrust model (its gain, the lagged hint and the means, the pack's voltage, the flags):
        what a reset keeps, for an estimator built anew in its place (the est.height parameter)."""
        for name in ("thrust_hint", "supply_sq", "_u", "thrust_c", "_az_fast", "_u_fast", "model_on", "on_legs",
                     "_lifting", "motors_off"):
            setattr(self, name, getattr(other, name))

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
        """Metres above the reset point (pressure in Pa): eq. 2 exactly, cT ln(p_ref / p) (eq. 3's linear form is
        5 cm short at 30 m)."""
        return baro_height(pressure_pa, self.p_ref, self.k_pa_per_m)

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
        self._acc_lp += (math.sqrt(ax * ax + ay * ay + az * az) - G - self._acc_lp) * min(1.0, dt / REST_TAU_S)
        rest = self.motors_off and abs(self._acc_lp) < REST_ACC
        self._rest_s = self._rest_s + dt if rest else 0.0
        if self.on_ground != (self._rest_s >= GROUND_REST_S):
            self._set_ground(not self.on_ground)
        self._u += (self.thrust_hint - self._u) * (dt / (MOTOR_LAG_S + dt))
        kf = dt / (THRUST_FAST_S + dt)
        self._az_fast += (az - self._az_fast) * kf
        self._u_fast += (self._u - self._u_fast) * kf  # the model over the same mean as the accelerometer
        if self.on_ground:
            # Standing still: no speed, the height held; what the accelerometer reads is its bias.
            self.bias += a * min(1.0, dt / GROUND_BIAS_TAU_S)
            self.vz = 0.0
            self.az_earth = 0.0
            return
        r33 = qw * qw - qx * qx - qy * qy + qz * qz
        if self.on_legs:
            if self.thrust_c * self._u * r33 <= G and self._az_fast <= G + THRUST_GATE:
                self.vz = 0.0  # the floor carries what the thrust does not
                self.az_earth = 0.0
                return
            self.on_legs = False  # the thrust passes the weight: it lifts, from the floor, now
            self._lifting = True
        self.az_earth = a
        a_in = self._thrust_accel(az, r33, a, dt)
        v = self.vz
        if self._stop_hold > 0.0:  # the jolt of a stop: the craft stands at the surface
            self._stop_hold -= dt
            self.vz = 0.0
            self._t_pred += dt
            return
        n = self._stop_n
        if (a > STOP_ACC or a < -STOP_ACC) and a * (self._stop_v if n else v) < 0.0 and (n or abs(v) >= STOP_VZ):
            if n == 0:
                self._stop_v = v
            self._stop_n = n + 1 if n < 255 else n
        elif n:
            self._stop_n = 0
            near = self._stop_v > 0.0 or abs(self.height - self.ground_ref) < STOP_FLOOR_M  # (a landing: the floor)
            if STOP_SAMPLES <= n <= STOP_MAX_SAMPLES and near:  # a jolt, over as fast as a surface stops the craft
                self._hard_stop()
                self._t_pred += dt
                return
        self.height += (v + 0.5 * a_in * dt) * dt
        self.vz = v + a_in * dt
        self._t_pred += dt
        if self._lifting and self.height < self.ground_ref:
            self.height = self.ground_ref  # just off the floor (the barometer's pull too): not below it
            if self.vz < 0.0:
                self.vz = 0.0

    def _thrust_accel(self, az: float, r33: float, a: float, dt: float) -> float:
        """The earth-up acceleration to integrate (m/s²): the thrust model's, c u r33 - g - bias, or the
        accelerometer's ``a`` when the motors are (nearly) off or the model is disabled (module constants)."""
        u = self._u
        c = self.thrust_c
        drag = DRAG_PER_S * self.vz  # (along the body's z: the same at the small tilts of a hover or a climb)
        strong = u >= THRUST_MIN
        near = self.height - self.ground_ref < THRUST_ABOVE_M
        if self._lifting:
            if strong and near:
                self.model_on = True  # off the legs: the model's thrust, the floor's readings not learnt from
                return c * u * r33 - drag - G - self.bias
            self._lifting = False
        if not self.thrust_model or not strong or near:
            self.model_on = False
            return a
        thrust_fast = self._az_fast + drag  # the accelerometer's mean without the drag: the thrust's
        if abs(thrust_fast - c * self._u_fast) > THRUST_GATE:
            # a force the model does not know (a contact, a hand): the accelerometer's, and nothing learnt from it
            self.model_on = False
            return a
        c += ((az + drag) / u - c) * (dt * (1.0 / self.thrust_tau_s))  # a running mean over THRUST_TAU_S
        self.thrust_c = c
        self.model_on = True
        return c * u * r33 - drag - G - self.bias

    @property
    def unsure(self) -> bool:
        """The height is not known to UNSURE_SIGMA: after a hard stop until the barometer has pulled it in, on a
        floor not yet anchored, after a lift-off from one (the screen marks the figure)."""
        if self.on_ground:
            return not (self._snapped or self.anchored)
        p0 = self.p[0]
        if self._t_pred > 0.0:
            t = self._t_pred
            p0 += t * (2.0 * self.p[1] + t * self.p[4])  # the height's variance grown since the last reading
        return p0 > UNSURE_SIGMA * UNSURE_SIGMA

    def _hard_stop(self) -> None:
        """A surface stopped the craft (the jolt against the motion): the speed is zero, the height unsure."""
        v = self._stop_v
        self.stops += 1
        self.stop_kind = STOP_UP if v > 0.0 else STOP_DOWN
        self.stop_speed = abs(v)
        self.vz = 0.0
        self._stop_n = 0
        self._stop_hold = STOP_HOLD_S
        if self._t_pred > 0.0:
            self._propagate(self._t_pred)
            self._t_pred = 0.0
        hh, _hv, hb, hs, _vv, _vb, _vs, bb, bs, ss = self.p
        sv = INITIAL_SIGMA[1]
        self.p = [max(hh, STOP_H_SIGMA * STOP_H_SIGMA), 0.0, hb, hs, sv * sv, 0.0, 0.0, bb, bs, ss]
        self._trend = 0.0

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
        qa, qb = (self.q_model, self.q_model_bias) if self.model_on else (self.q_acc, self.q_bias)
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

    def _set_ground(self, on: bool) -> None:
        """Touch-down (at rest, no thrust) or lift-off (thrust, or moved): the state the filter carries on from."""
        # the motors turn (idle's vibration or more thrust ended the rest) on the floor it knows: on the legs until
        # their thrust passes the weight
        self.on_legs = not on and self.thrust_model and self.thrust_hint > 0.0 and (self.anchored or self._snapped)
        self._lifting = False
        if not on:
            # lift-off: the covariance of a filter at rest, no spike running; a height not yet anchored is unsure
            sh, sv, _sb = INITIAL_SIGMA
            var_h = sh * sh if (self.anchored or self._snapped) else max(self.p[0], 1.0)
            if self.anchored:  # the barometer drifted while the craft stood: its reference takes the drift out
                self.p_ref *= math.exp(-(self._stand_baro - self.height) * self.k_pa_per_m / self.p_ref)
            self.p = [var_h, 0.0, 0.0, 0.0, sv * sv, 0.0, 0.0, self.p[7], 0.0, _SS_FLOOR]
            self.spike = 0.0
        # on the floor it was calibrated on (close to it): the height is the floor's at once
        self._snapped = on and abs(self.height - self.ground_ref) < GROUND_SNAP_M
        if self._snapped:
            self.height = self.ground_ref
        self._stop_hold = 0.0
        self._stop_n = 0
        self.on_ground = on
        self.anchored = False
        self._ground_baro = []
        self._ground_baro_s = 0.0
        self.vz = 0.0
        self._t_pred = 0.0

    def _ground_baro_update(self, z: float, dt: float) -> None:
        """On the ground: the first ANCHOR_S of readings give the height (a trimmed mean, so neither the noise nor
        a spike moves it); after that the height is held, whatever the barometer drifts (the craft stands)."""
        if self.anchored:
            pull = max(-STAND_CLIP_M, min(STAND_CLIP_M, z - self._stand_baro))
            self._stand_baro += pull * min(1.0, max(0.0, dt) / STAND_TAU_S)
            return
        buf = self._ground_baro
        buf.append(z)
        self._ground_baro_s += max(0.0, dt)
        if self._ground_baro_s < ANCHOR_S:
            return
        ordered = sorted(buf)
        cut = len(ordered) // 4
        middle = ordered[cut : len(ordered) - cut]
        mean = sum(middle) / len(middle)
        # the floor is ground_ref, if the barometer agrees within GROUND_SNAP_M: what it reads there is its offset;
        # else (a table the estimate did not follow) the barometer's height stands, as before
        self._snapped = self._snapped and abs(mean - self.ground_ref) < GROUND_SNAP_M
        if self._snapped:
            self.p_ref *= math.exp(-(mean - self.ground_ref) * self.k_pa_per_m / self.p_ref)
            mean = self.ground_ref
        self.height = mean
        self._stand_baro = self.height
        self.anchored = True
        self.spike = 0.0

    def update_baro(self, pressure_pa: float, dt: float) -> None:
        """A new pressure sample (Pa); dt is the time since the previous pressure sample (s)."""
        z = self.baro_to_height(pressure_pa)
        self.baro_raw = z
        if self.on_ground:
            self._t_pred = 0.0
            self._ground_baro_update(z, dt)
            return
        if self.on_legs:  # the height held: the barometer not needed (its noise would move it)
            self._t_pred = 0.0
            return
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
        # A speed the accelerometer got wrong (a touch-down its 2 g range clipped, a knock) shows as innovations
        # that keep one sign: when their running mean passes TREND_SIGMA, the speed is made unsure, so the
        # barometer corrects it within a few readings instead of the height running away (issue 10.3).
        self._trend += TREND_GAIN * (math.copysign(r_sigma, nu) - self._trend)
        if abs(self._trend) > TREND_SIGMA:
            p[4] += TREND_VZ_VAR
            self.trend_resets += 1
        if r_sigma > self.gate_sigma:
            p, nu = self._spike_onset(p, nu, z)
        elif r_sigma > self.huber_sigma:
            # a moderate outlier counts less (Huber weight)
            r *= r_sigma / self.huber_sigma
        self._baro_correct(p, nu, r)

    def _spike_onset(self, p: list[float], nu: float, z: float) -> tuple[list[float], float]:
        """A reading far outside what the accelerometer predicts: the onset of a spike. Its size is unknown, so
        the spike's variance takes the whole innovation and the update gives it to the spike, not to the height.
        A spike decays; onsets of the same sign again and again mean it does not: a real change of the
        barometer's level, which then goes to the height. Returns the covariance and innovation to update with."""
        self.baro_rejected += 1
        sign = 1 if nu > 0.0 else -1
        same = sign == self._jump_sign and self._t_jump < self.rejump_window_s
        self._rejumps = self._rejumps + 1 if same else 0
        self._jump_sign = sign
        self._t_jump = 0.0
        if self._rejumps < self.level_after:
            p[9] += nu * nu
            return p, nu
        self._rejumps = 0
        self.level_changes += 1
        hh, hv, hb, hs, vv, vb, vs, bb, bs, ss = p
        # fold the spike into the height (h' = h + s), then own the new level's uncertainty
        self.height += self.spike
        self.spike = 0.0
        c_ = self._c
        self._c = [c_[0] + c_[3], c_[1], c_[2], 0.0]
        nu = z - self.height
        return [hh + 2.0 * hs + ss + nu * nu, hv + vs, hb + bs, 0.0, vv, vb, 0.0, bb, 0.0, _SS_FLOOR], nu

    def _baro_correct(self, p: list[float], nu: float, r: float) -> None:
        """The Kalman update with innovation ``nu`` (m) of noise variance ``r`` (m²): the barometer reads height
        plus spike, H = [1, 0, 0, 1]; the captured height (the clone state) is refined too."""
        hh, hv, hb, hs, vv, vb, vs, bb, bs, ss = p
        gh, gv, gb, gs = hh + hs, hv + vs, hb + bs, hs + ss  # P H'
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
    as HEIGHT flies it (without the baro high-pass, see fcb_sim/board/flight.py). Keyword arguments go to the class."""
    if name == "kalman":
        return HeightKalman(**kw)
    if name == "complementary":
        kw.setdefault("baro_highpass_hz", 0.0)
        return HeightEstimator(**kw)
    raise ValueError(f"unknown height estimator {name!r}; choose from {', '.join(HEIGHT_ESTIMATORS)}")
