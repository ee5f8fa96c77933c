"""Physical constants of the simulated Quadrupel, each with its source.

Sources (cited below by their tag; full references in docs/board.md, "The model's constants"):

- [OS4]   S. Bouabdallah, R. Siegwart, "Full control of a quadrotor", IEEE/RSJ IROS 2007, Table I: the identified
          parameters of the OS4 quadrotor (mass, arm, inertia, thrust and drag factors).
- [MPU]   InvenSense MPU-6000/MPU-6050 Product Specification rev 3.4 and Register Map rev 4.2.
- [MS]    MEAS MS5611-01BA03 barometric pressure sensor datasheet.
- [LAB]   the lab report (seed/000_...txt): Table 1 gains, Table 2 filter constants, eq. 2-3, Figure 9, 100 Hz DMP,
          400 Hz RAW, 20 Hz barometer task (Figure 14).
- [TPL]   the lab's in4073 firmware template (mpu_wrapper.c): angles as int16 at 10430 LSB per rad, rates as the
          raw gyro words, the DMP FIFO at 100 Hz with the DLPF at 10 Hz.
- [LIPO]  typical 3S lithium-polymer figures (pack vendors' curves, about 20 mOhm per cell).
- [ISA]   ICAO standard atmosphere at sea level.
- [ASSUMED] values for which no published figure for this airframe exists; each says why it is plausible.

Scaling to the lab's board: the motor command ``ae`` (0..1000) sets the rotor speed in proportion, chosen so that
the OS4 airframe hovers at ae = 400 at the reference supply voltage V_REF, as the lab's quadcopter did.

The report's Table 1 gains are used as is, in the model's units: angles in 10430 LSB per rad, rates in raw gyro
words, lift and moments in ae² units (``Gains``). What they mean physically (loop bandwidths) and why the height
gains are what they are: docs/board.md, "The model's units and gains".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from term.core import protocol as _protocol

G = 9.80665  # m/s², standard gravity [ISA]

# --- airframe [OS4] --------------------------------------------------------------------------------------------
MASS = 0.65  # kg
ARM = 0.23  # m, rotor centre to centre of mass
IXX = 7.5e-3  # kg m²
IYY = 7.5e-3  # kg m²
IZZ = 1.3e-2  # kg m²
B_ROTOR = 3.13e-5  # N s², thrust = B_ROTOR * omega²
D_ROTOR = 7.5e-7  # N m s², rotor drag torque = D_ROTOR * omega²

# Linear drag: [ASSUMED] 0.25 N per m/s relative air speed, a terminal velocity of 25 m/s for 0.65 kg, in the range
# of published small-quadrotor fits (rotor-induced drag dominates at low speed).
DRAG_LINEAR = 0.25  # N s/m
# The drag's point of action: [ASSUMED] the rotor plane, 3 cm above the centre of mass, so a relative wind also
# tilts the quadrotor (a stand-in for rotor blade flapping, which does the same on real multirotors). With the
# P-only cascade this leaves a steady angle error in fast flight: 10 deg of roll (4.4 m/s sideways) holds at ~8.
DRAG_CP_HEIGHT = 0.03  # m
# Rotational drag: [ASSUMED] 5e-3 N m s (roll/pitch) and 3e-3 (yaw); the rotors' flapping and profile drag damp
# body rates with a time constant Ixx/k of about 1.5 s, much slower than the controllers.
DRAG_ROT_XY = 5e-3  # N m s/rad
DRAG_ROT_Z = 3e-3  # N m s/rad

# --- motors and ESC --------------------------------------------------------------------------------------------
AE_MAX = 1000
AE_HOVER_NOMINAL = 400  # the lab's board hovers at about 400 of 1000 (DESIGN.md)
OMEGA_HOVER = math.sqrt(MASS * G / 4.0 / B_ROTOR)  # rad/s, 225.7 rad/s = 2155 rpm
V_REF = 11.4  # V, loaded pack voltage at which ae = 400 hovers (3.8 V per cell under hover load) [LIPO]
OMEGA_PER_AE = OMEGA_HOVER / AE_HOVER_NOMINAL  # rad/s per ae unit at V_REF
# Motor speed time constant: [ASSUMED] 30 ms, typical of 8-10 inch propellers on small outrunners (identified
# values for such rotors lie between 20 and 60 ms).
MOTOR_TAU = 0.03  # s

# Firmware-unit mixing constants: thrust and yaw torque per ae² at V_REF.
B_FW = B_ROTOR * OMEGA_PER_AE**2  # N per ae², 9.96e-6
D_FW = D_ROTOR * OMEGA_PER_AE**2  # N m per ae², 2.39e-7

# Electrical power per rotor, P = POWER_COEF * omega³: [ASSUMED] from momentum theory for 0.2 m rotors
# (ideal induced power 7.3 W per rotor at hover), figure of merit 0.5 and motor+ESC efficiency 0.7: 20.7 W per
# rotor, 83 W (7.3 A at 11.4 V) to hover.
POWER_COEF = 20.7 / OMEGA_HOVER**3  # W s³
AVIONICS_CURRENT = 0.15  # A, board, receiver and ESC logic [ASSUMED]

# --- battery: 3S LiPo [LIPO] ------------------------------------------------------------------------------------
CELLS = 3
CAPACITY_AH = 2.2
R_INTERNAL = 0.07  # ohm, 3 x 20 mOhm cells plus leads and connector
# Resting (open-circuit) voltage per cell against state of charge, a typical vendor discharge curve.
OCV_SOC = (0.0, 0.05, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.00)
OCV_CELL = (3.27, 3.61, 3.69, 3.73, 3.77, 3.79, 3.82, 3.87, 3.92, 3.98, 4.06, 4.20)
BATTERY_SOC_START = 0.9
# Battery ADC: [ASSUMED] a 10-bit nRF51 ADC behind a divider, read as 10 mV units with about 2 counts of noise.
ADC_NOISE_10MV = 2.0

# --- MPU6050 [MPU] ---------------------------------------------------------------------------------------------
GYRO_LSB_PER_DPS = _protocol.GYRO_LSB_PER_DPS  # FS_SEL = 3, +-2000 deg/s (the words telemetry carries)
ACC_LSB_PER_G = float(_protocol.ACC_LSB_PER_G)  # AFS_SEL = 0, +-2 g
RATE_LSB_PER_RAD_S = GYRO_LSB_PER_DPS * 180.0 / math.pi  # 939.65
ACC_LSB_PER_MS2 = ACC_LSB_PER_G / G  # 1670.7
# Noise: gyro rate noise density 0.005 deg/s/rtHz (total 0.05 deg/s rms at DLPF 100 Hz); accelerometer 400 ug/rtHz.
# With the 42/44 Hz DLPF (DLPF_CFG = 3) the bandwidth is about 1.57 x 42 = 66 Hz.
GYRO_NOISE_DPS = 0.005 * math.sqrt(66.0)  # deg/s rms, 0.041
ACC_NOISE_G = 400e-6 * math.sqrt(66.0)  # g rms, 0.0032
# Initial offset: the datasheet allows +-20 deg/s (ZRO) and +-50/+-80 mg; real parts sit well inside.
# [ASSUMED] uniform within +-3 deg/s and +-40 mg, the bias then random-walks (temperature, ageing).
GYRO_BIAS_DPS = 3.0
ACC_BIAS_G = 0.04
GYRO_BIAS_WALK_DPS = 0.01  # deg/s per sqrt(s) [ASSUMED: 0.1 deg/s after 100 s]
ACC_BIAS_WALK_G = 2e-4  # g per sqrt(s) [ASSUMED]
# Motor vibration seen by the sensors: [ASSUMED] 0.15 g and 1.5 deg/s rms per axis at hover (after the DLPF),
# growing with the square of rotor speed (unbalance force ~ omega²); the report found accelerometer readings
# "high noise due to motor vibrations" [LAB].
VIB_ACC_G = 0.15
VIB_GYRO_DPS = 1.5
DLPF_DELAY = 0.0048  # s, DLPF_CFG = 3 group delay (4.8 ms gyro, 4.9 ms accel) [MPU register map]
# DMP: quaternion output at 100 Hz [LAB, TPL: dmp_set_fifo_rate(100)]. The template sets the DLPF to 10 Hz in DMP
# mode (mpu_set_lpf(10)), whose group delay is 13.4 ms (gyro) [MPU register map, DLPF_CFG = 5]; plus on average
# half a FIFO period (5 ms) before the sample is read: 18 ms. Orientation error of the fused output about
# 0.1 deg rms [ASSUMED], yaw drifts (no magnetometer).
DMP_RATE_HZ = 100.0
DMP_LATENCY = 0.018
DMP_NOISE_RAD = math.radians(0.1)
DMP_YAW_DRIFT_RAD_S = math.radians(0.02)

# --- MS5611 [MS] ------------------------------------------------------------------------------------------------
P0 = 101325.0  # Pa [ISA]
T0_K = 288.15  # K [ISA]
# The air of the lab the simulator flies in: a room at 20 °C (the "standard room temperature" the report's eq. 3
# assumes), so the barometric formula of the world and of the board's estimator agree; with ISA's 15 °C the
# board's heights came out 1.7 % too high (0.5 m at 30 m). The chip reads its own, warmer die (BARO_TEMP_C).
T_AIR_K = 293.15

# --- the simulator's bounds -------------------------------------------------------------------------------------
# The sky ends at CEILING_M above the floor: the world stops a climb there as the floor stops a descent, so every
# height the board can report fits its encoding (the Height packet's int16 cm: 327 m). At full lift the craft
# climbs at 42 m/s and would otherwise be 2 km up in a minute (a real flight meets the 120 m the law allows long
# before). An impact at either end faster than CRASH_SPEED_M_S, or touching down tilted more than CRASH_TILT_DEG
# (a rotor strikes), is a crash [ASSUMED]: the world records it and the board reports it.
CEILING_M = 300.0
CRASH_SPEED_M_S = 2.0
CRASH_TILT_DEG = 35.0
# A surface stops the craft within JOLT_S (legs, guards and the frame give a little): the accelerometer feels the
# speed into it over that time (1 m/s is 10 g, clipped at the chip's 2 g). Touches of one surface closer together
# than CONTACT_REPEAT_S are one contact (a craft pressed on the ceiling bounces off it and back at every step).
JOLT_S = 0.01
CONTACT_REPEAT_S = 0.5
M_AIR = 0.0289644  # kg/mol [ISA]
R_GAS = 8.31446  # J/(mol K)
# OSR 4096: RMS resolution 0.012 mbar = 1.2 Pa (the report's "0.012mbar (10cm)"); output in 0.01 mbar = 1 Pa.
BARO_NOISE_PA = 1.2
BARO_LSB_PA = 1.0
# Slow drift: [ASSUMED] random walk of 0.1 Pa per sqrt(s) (weather, self-heating; the report saw "considerable
# drift in pressure readings at constant altitude").
BARO_DRIFT_PA = 0.1
# Spikes (Figure 9 [LAB]: sudden excursions from air flow over the sensor): [ASSUMED] a Poisson process of
# 0.1 per s, each a jump of 4-15 Pa (0.3-1.3 m) of either sign, decaying over 0.1-0.5 s.
BARO_SPIKE_RATE = 0.1  # per s
BARO_SPIKE_PA = (4.0, 15.0)
BARO_SPIKE_TAU = (0.1, 0.5)  # s
BARO_TEMP_C = 25.0

# --- firmware units [TPL] --------------------------------------------------------------------------------------
ANGLE_LSB_PER_RAD = 10430.0


# The gains the pilot's keys step (the protocol's GAIN_OPS), by their parameter's name without its "ctrl." group:
# "ctrl.yaw_p" is Gains.yaw_p (a test checks the two name the same gains).
GAIN_PARAMS: dict[str, _protocol.Param] = {_protocol.PARAMS[p].name.removeprefix("ctrl."): p
                                           for p in _protocol.GAIN_OPS.values()}


def _gain_default(name: str) -> float:
    return float(_protocol.PARAMS[GAIN_PARAMS[name]].default)


@dataclass
class Gains:
    """Controller gains in the model's units (module docstring). Start values: the protocol's parameter table
    (term.core.protocol.PARAMS): the report's Table 1 as magnitudes (control.py explains the sign), plus our height
    PD."""

    yaw_p: float = _gain_default("yaw_p")
    p1: float = _gain_default("p1")
    p2: float = _gain_default("p2")
    height_p: float = _gain_default("height_p")
    height_d: float = _gain_default("height_d")


# Per-step changes for the pilot's gain keys (u/j, i/k, o/l, t/g, y/h): the table's steps.
GAIN_STEPS = {name: float(_protocol.PARAMS[p].step) for name, p in GAIN_PARAMS.items()}

# Motor limits used by the mixing.
AE_IDLE = 150  # minimum while armed: the rotors keep turning (thrust 14% of weight, stays on the floor)
PANIC_AE = 370  # descent level just under hover at V_REF (thrust 86% of weight: about -1.4 m/s²)


def ocv(soc: float) -> float:
    """Resting pack voltage (V) at state of charge 0..1 [LIPO]."""
    if soc <= 0.0:
        return OCV_CELL[0] * CELLS
    if soc >= 1.0:
        return OCV_CELL[-1] * CELLS
    for i in range(1, len(OCV_SOC)):
        if soc <= OCV_SOC[i]:
            s0, s1 = OCV_SOC[i - 1], OCV_SOC[i]
            v0, v1 = OCV_CELL[i - 1], OCV_CELL[i]
            return CELLS * (v0 + (v1 - v0) * (soc - s0) / (s1 - s0))
    return OCV_CELL[-1] * CELLS


def pressure_at(height_m: float) -> float:
    """Barometric formula (the report's eq. 2 with cT = R T / (M g)): pressure in Pa at a height above sea level,
    in the lab's air (T_AIR_K)."""
    return P0 * math.exp(-M_AIR * G * height_m / (R_GAS * T_AIR_K))
