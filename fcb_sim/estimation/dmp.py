"""DMP path: the MPU6050's quaternion to Euler angles, as the report's firmware did it (appendix C, eq. 5).

The firmware replaced ``asin`` (slow in software floating point on the Cortex-M0) by the identity
``asin(x) = atan(x / sqrt(1 - x²))``, computed as ``atan2(x, sqrt(1 - x²))``, and fell back to ``asin``
near the singularity at |x| = 1. Here x = 2(wy - xz) = sin(pitch), so |x| -> 1 means pitch -> ±90°
(the report says "≥ 45 degrees"; that is a slip: sin(45°) is 0.707, not 1). A quad in regular flight never
gets there, but the fallback keeps the function total: the input is clamped so a slightly non-unit
quaternion (|x| a hair above 1) still gives ±90°, never a math domain error.
"""

from __future__ import annotations

import math

#: Above this |sin(pitch)| (pitch ≈ 81.9°) the identity loses precision (sqrt of a tiny difference), so
#: use asin, as the firmware did.
ASIN_FALLBACK = 0.99


def asin_via_atan2(x: float) -> float:
    """asin(x) by eq. 5, with the asin fallback near |x| = 1 and clamping beyond it."""
    if -ASIN_FALLBACK < x < ASIN_FALLBACK:
        return math.atan2(x, math.sqrt(1.0 - x * x))
    return math.asin(1.0 if x > 1.0 else -1.0 if x < -1.0 else x)


def quaternion_to_euler(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """Body-to-earth quaternion (earth z up) to ZYX Euler angles (roll, pitch, yaw) in rad.

    Roll and yaw in (-π, π], pitch in [-π/2, π/2]. The quaternion need not be exactly unit (the DMP's is
    quantised to Q30); it is normalised first.
    """
    n2 = w * w + x * x + y * y + z * z
    if n2 <= 0.0:
        raise ValueError("zero quaternion")
    if abs(n2 - 1.0) > 1e-9:
        s = 1.0 / math.sqrt(n2)
        w, x, y, z = w * s, x * s, y * s, z * s
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = asin_via_atan2(2.0 * (w * y - x * z))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw
