"""The board's controllers and motor mixing, in the firmware's units (constants.py explains them).

- Yaw rate: ``N = yaw_p * (r_sp - r)``.
- Roll and pitch, cascaded: P1 turns the angle error into a rate set point, P2 the rate error into a moment:
  ``L = P2 * (P1 * (phi_sp - phi) - p)`` and ``M = P2 * (P1 * (theta_sp - theta) - q)``.
- Height: PD around the set point, ``Z = Z_base - height_p * (h_sp - h) + height_d * vz`` (Z is negative lift),
  plus an integral ``- I`` with ``I += height_i * (h_sp - h) dt`` clamped to ``HEIGHT_I_LIMIT`` (``height_integral``):
  the battery sags during a flight, so the hover thrust of the Z_base captured at entry slowly falls and a PD
  alone sinks below the set point (in the simulator, flying on the true height over 120 s: P 400 / D 400 alone
  4.4 cm rms, with the integral 0.3 cm).
- Mixing: the plus-frame equations of DESIGN.md with b = d = 1 (Z/L/M/N in ae² units) inverted for ae_i², then
  the integer square root of the report's appendix, clamped to 0..1000, with a minimum idle while armed.

Units: angles in 10430 LSB per rad (the lab template's int16 angles), rates in raw gyro LSB (16.4 per deg/s),
moments and lift in ae². Table 1's numbers are used as they are: P1 0.4, P2 111, yaw P 800 (magnitudes).

The sign of the cascade (the report: "We are not sure why the P2 values have opposite signs ... We think this
unstable behavior may be related to the inverted sign in the cascaded P controller"). The lab's template
computes ``theta = -asin(...) * 10430``: pitch positive nose UP. It fills ``sq`` with the chip's raw gyro y word,
and the MPU6050's y axis points LEFT (the chip is x forward, y left, z up), so a nose-up rotation gives a
NEGATIVE ``sq``. In the pitch cascade ``M = P2 (P1 (theta_sp - theta) - sq)`` the angle term and the rate term
therefore have opposite conventions: with either sign of P2, one of the two pushes the wrong way (P2 > 0: the
rate term un-damps; P2 < 0: the angle term drives the pitch away from the set point, a slow divergence the pilot
fights, the "twitching"). Roll has no such mismatch (chip x = body x and phi = atan2(...) keeps its sign), so
the table's roll and pitch P2 had to differ in sign, and the yaw P is negative because ``sr`` is the chip's z
word (z up: a nose-right turn reads negative). The fix is to map the chip's axes to the body's ONCE, where the
samples enter (flight.py): ``p = gx, q = -gy, r = -gz``, and the z-up estimators' angles as ``phi = roll,
theta = -pitch, psi = -yaw`` (docs/architecture.md). Then every loop has the same form and every gain is
positive: a positive angle error asks for a positive rate, a positive rate error for a positive moment, and
positive L/M/N spin the quadrotor positively about x/y/z (tests/board/test_control.py checks the motor differentials).
"""

from __future__ import annotations

from fcb_sim.world import constants as P
from term.core.protocol import STICK_MAX

ANGLE_LSB_PER_RAD = P.ANGLE_LSB_PER_RAD
RATE_LSB_PER_RAD_S = P.RATE_LSB_PER_RAD_S
AE_MAX = P.AE_MAX

# Stick scaling (sticks are int16, lift 0..32767): full roll/pitch stick asks for 32767 >> 3 = 4096 angle LSB
# (22.5 deg), full yaw twist for 32767 >> 4 = 2048 rate LSB (125 deg/s), full lift for ae 800 on every motor.
STICK_ANGLE_SHIFT = 3
STICK_YAW_SHIFT = 4
LIFT_AE_MAX = 800
# MANUAL: sticks straight to moments (ae² per stick unit): full roll is +-65534 ae² (ae 439/357 about hover).
MANUAL_LM_GAIN = 2
MANUAL_N_GAIN = 4


def isqrt_appendix(square: int) -> int:
    """The report's appendix C verbatim: clz-based first guess, two Newton-Raphson iterations.

    ``xn = 1 << ((32 - clz(square)) >> 1)``; ``32 - clz(x)`` is ``x.bit_length()`` for a uint32. Contrary to
    the report's "maximum error of 1 for inputs between 1E6 and 0", it is off by 2 for 4181 of those inputs
    (first at 506925: 713 instead of 711); ``isqrt_nr`` adds the missing correction.
    """
    if square <= 0:
        return 0
    xn = 1 << (square.bit_length() >> 1)
    xn = (xn + square // xn) >> 1
    xn = (xn + square // xn) >> 1
    return xn


def isqrt_nr(square: int) -> int:
    """Integer square root for the mixing: the appendix's two iterations plus one correction step.

    After the first iteration Newton-Raphson approaches from above, so the only error left is an overshoot;
    one compare-and-decrement (a multiply on the M0) brings the error over 0..1e6 to at most 1.
    """
    if square <= 0:
        return 0
    xn = 1 << (square.bit_length() >> 1)
    xn = (xn + square // xn) >> 1
    xn = (xn + square // xn) >> 1
    if xn * xn > square:
        xn -= 1
    return xn


def mix(z: float, l: float, m: float, n: float, *, armed: bool = True,
        idle: int = P.AE_IDLE) -> tuple[int, int, int, int]:
    """Motor commands from lift Z (negative up) and moments L, M, N (ae² units).

    Inverting ``Z = -(a1+a2+a3+a4)``, ``L = a4 - a2``, ``M = a1 - a3``, ``N = -a1 + a2 - a3 + a4`` (a_i = ae_i²):
    ``a1 = (S - N + 2M)/4``, ``a2 = (S + N - 2L)/4``, ``a3 = (S - N - 2M)/4``, ``a4 = (S + N + 2L)/4``, S = -Z.
    Negative squares become 0; results are clamped to 0..1000 and, while armed, to at least ``idle``.
    """
    s = -int(z)
    li = 2 * int(l)
    mi = 2 * int(m)
    ni = int(n)
    lo = idle if armed else 0
    out = [(s - ni + mi) >> 2, (s + ni - li) >> 2, (s - ni - mi) >> 2, (s + ni + li) >> 2]
    for j in range(4):
        a = out[j]
        if a > 0:
            # isqrt_nr inlined (this runs 400 times per simulated second)
            v = 1 << (a.bit_length() >> 1)
            v = (v + a // v) >> 1
            v = (v + a // v) >> 1
            if v * v > a:
                v -= 1
        else:
            v = 0
        out[j] = lo if v < lo else AE_MAX if v > AE_MAX else v
    return out[0], out[1], out[2], out[3]


def lift_to_z(lift: int) -> int:
    """Lift stick (0..STICK_MAX) to Z (ae² units, negative up): every motor at ``lift * LIFT_AE_MAX / STICK_MAX``."""
    if lift <= 0:
        return 0
    ae = lift * LIFT_AE_MAX // STICK_MAX
    return -4 * ae * ae


def z_to_lift(z: float) -> int:
    """Inverse of ``lift_to_z`` (for pilots and tests): the stick that gives this Z."""
    if z >= 0:
        return 0
    ae = isqrt_nr(int(-z) // 4)
    return min(STICK_MAX, -(-ae * STICK_MAX // LIFT_AE_MAX))


def yaw_rate(r_sp: float, r: float, yaw_p: float) -> float:
    """Yaw moment N (ae²) from the yaw-rate error (rate LSB)."""
    return yaw_p * (r_sp - r)


def cascade(angle_sp: float, angle: float, rate: float, p1: float, p2: float) -> float:
    """Roll or pitch moment (ae²): P1 on the angle error (angle LSB) gives a rate set point (rate LSB), P2 on
    the rate error gives the moment. Same signs on both axes (see the module docstring)."""
    return p2 * (p1 * (angle_sp - angle) - rate)


def height_pd(z_base: float, h_sp_mm: float, h_mm: float, vz_mm_s: float, kp: float, kd: float) -> float:
    """Height-hold Z (ae², negative up) around ``z_base``: below the set point or sinking asks for more lift."""
    return z_base - kp * (h_sp_mm - h_mm) + kd * vz_mm_s


# Anti-windup bound of the height integral: 100000 ae² of Z is 1.0 N, 15 % of the weight (a sag of the 3S pack
# from full to storage voltage costs about 10 % of the thrust at a fixed command).
HEIGHT_I_LIMIT = 100000.0


def height_integral(i_prev: float, h_sp_mm: float, h_mm: float, ki: float, dt: float,
                    limit: float = HEIGHT_I_LIMIT, saturated: bool = False) -> float:
    """The height integral (ae², positive asks for more lift; subtract it from Z) after one step of ``dt`` s.

    Anti-windup twice over: the integral is clamped to ``±limit``, and while the output is ``saturated`` (the
    lift command was clipped) it only integrates in the direction that leaves the saturation."""
    step = ki * (h_sp_mm - h_mm) * dt
    if saturated and step * i_prev > 0.0:
        return i_prev
    i = i_prev + step
    return limit if i > limit else -limit if i < -limit else i
