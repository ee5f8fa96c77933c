"""What every attitude filter shares: the protocol, Euler/quaternion conversion, accelerometer angles.

Conventions (docs/architecture.md): the chip's z-up frame, gyro in rad/s, specific force in m/s² (+9.81 on z
when level), ZYX Euler angles (roll about x, pitch about y, yaw about z), quaternion body-to-earth (w, x, y, z)
with earth z up. Everything here is plain scalar ``math``: filters run 400 times per simulated second.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable


@runtime_checkable
class AttitudeFilter(Protocol):
    """An attitude estimator fed one IMU sample at a time."""

    roll: float
    pitch: float
    yaw: float

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        """Advance by one sample: gyro rad/s, specific force m/s² (chip frame, z up), dt seconds."""

    def quaternion(self) -> tuple[float, float, float, float]:
        """Attitude as a unit quaternion (w, x, y, z), body-to-earth, earth z up."""

    def reset(self) -> None:
        """Forget all state; the next sample starts the filter again."""


def euler_to_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """ZYX Euler angles (rad) to the body-to-earth unit quaternion (w, x, y, z)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def accel_roll_pitch(ax: float, ay: float, az: float) -> tuple[float, float]:
    """Roll and pitch (rad) from specific force alone, valid when the body is not accelerating.

    Level reads (0, 0, +g). Rolling right side down (positive roll about x) gives +ay, pitching nose down
    (positive pitch about y, which points left) gives -ax.
    """
    return math.atan2(ay, az), math.atan2(-ax, math.sqrt(ay * ay + az * az))


def quat_step(w: float, x: float, y: float, z: float, wx: float, wy: float, wz: float, rate: float,
              t: float) -> tuple[float, float, float, float]:
    """q (x) (cos h, sin h * omega / |omega|), h = |omega| t / 2: the attitude carried ``t`` seconds along the body
    rate omega = (wx, wy, wz) (rad/s) by the exact axis-angle step, ``rate`` being |omega| (the caller has it).
    Unchanged below a half step of 1e-12 rad. The strapdown step of ikf and qgate and ikf's latency prediction
    (one step, issue 20); firmware/board/ikf_f.c repeats its operations."""
    half = 0.5 * rate * t
    if half <= 1e-12:
        return w, x, y, z
    s = math.sin(half) / rate
    c = math.cos(half)
    dx, dy, dz = wx * s, wy * s, wz * s
    return (
        w * c - x * dx - y * dy - z * dz,
        w * dx + x * c + y * dz - z * dy,
        w * dy - x * dz + y * c + z * dx,
        w * dz + x * dy - y * dx + z * c,
    )


def wrap_pi(a: float) -> float:
    """Wrap an angle (rad) into (-π, π]."""
    if a > math.pi:
        return a - 2.0 * math.pi
    if a <= -math.pi:
        return a + 2.0 * math.pi
    return a


class EulerFilterMixin:
    """Quaternion output for the per-axis filters, which keep roll, pitch and yaw as their state."""

    roll: float
    pitch: float
    yaw: float

    def quaternion(self) -> tuple[float, float, float, float]:
        return euler_to_quaternion(self.roll, self.pitch, self.yaw)


class QuaternionAnglesMixin:
    """ZYX Euler angles for the filters whose state is a quaternion (qgate, ikf and its fixed-point twin)."""

    def quaternion(self) -> tuple[float, float, float, float]:
        raise NotImplementedError

    @property
    def roll(self) -> float:
        w, x, y, z = self.quaternion()
        return math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))

    @property
    def pitch(self) -> float:
        w, x, y, z = self.quaternion()
        s = 2.0 * (w * y - x * z)
        return math.asin(1.0 if s > 1.0 else -1.0 if s < -1.0 else s)

    @property
    def yaw(self) -> float:
        w, x, y, z = self.quaternion()
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class Q16AnglesMixin(EulerFilterMixin):
    """The float view of a Q16.16 filter whose state is the angles ``r``, ``p``, ``y`` in fix16 radians."""

    r: int
    p: int
    y: int

    @property
    def roll(self) -> float:  # type: ignore[override]
        return self.r / 65536.0

    @property
    def pitch(self) -> float:  # type: ignore[override]
        return self.p / 65536.0

    @property
    def yaw(self) -> float:  # type: ignore[override]
        return self.y / 65536.0
