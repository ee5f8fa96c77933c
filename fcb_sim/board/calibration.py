"""CALIBRATION mode: the sums of the sensor samples taken at rest, and the means the flight core subtracts.

One implementation for the board (through its mode machine) and the headless scenarios:

- ``CalibrationSums``: the report's 64-bit sums and counters (Python ints cannot overflow at all), one sum and one
  count per named variable, because the sensors come at different rates (IMU 200/400 Hz, barometer 20 Hz); the
  means are rounded to the nearest integer, as the board's integer arithmetic would. DMP angles are summed as the
  lab template's int16 angles (``DMP_ANGLE_LSB`` per rad).
- ``Calibration``: the means as ``FlightCore.set_calibration`` applies them: gyro and accelerometer in raw chip
  words, the DMP's angles at rest in rad (FRD), the barometer's mean in Pa.

``CalibrationSums.result(pressure)`` turns the sums into a ``Calibration``; a variable without samples keeps its
neutral value (DMP angles 0 on the RAW path) and the pressure falls back to the reading passed in.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from fcb_sim.estimation import quaternion_to_euler
from fcb_sim.world import constants as P

CALIBRATED_VARS = ("gx", "gy", "gz", "ax", "ay", "az", "dmp_phi", "dmp_theta", "pressure")
DMP_ANGLE_LSB = P.ANGLE_LSB_PER_RAD  # DMP angles are summed as int16 angles of the lab's template


@dataclass(frozen=True)
class Calibration:
    """Means measured at rest in CALIBRATION mode. Gyro and accelerometer in raw chip words; ``dmp_phi`` and
    ``dmp_theta`` the DMP's angles at rest (rad, FRD); ``pressure`` the barometer's mean (Pa)."""

    gyro: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel: tuple[float, float, float] = (0.0, 0.0, P.ACC_LSB_PER_G)
    dmp_phi: float = 0.0
    dmp_theta: float = 0.0
    pressure: float = P.P0


class CalibrationSums:
    """Sums of sensor samples in unbounded integers, one sum and one count per named variable; the means are
    taken when CALIBRATION is left."""

    def __init__(self, names: Sequence[str] = CALIBRATED_VARS) -> None:
        self.names = tuple(names)
        self.sums: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self.reset()

    def reset(self) -> None:
        self.sums = {name: 0 for name in self.names}
        self.counts = {name: 0 for name in self.names}

    @property
    def count(self) -> int:
        """Samples of the first (primary, fastest) variable: what the minimum-sample rule looks at."""
        return self.counts[self.names[0]] if self.names else 0

    def add(self, values: Mapping[str, int]) -> None:
        for name, v in values.items():
            if name not in self.sums:
                raise KeyError(f"{name!r} is not calibrated (known: {', '.join(self.names)})")
            self.sums[name] += int(v)
            self.counts[name] += 1

    def add_imu(self, gx: int, gy: int, gz: int, ax: int, ay: int, az: int) -> None:
        """One IMU read, raw chip words."""
        self.add({"gx": gx, "gy": gy, "gz": gz, "ax": ax, "ay": ay, "az": az})

    def add_dmp(self, w: float, x: float, y: float, z: float) -> None:
        """One DMP quaternion (body-to-earth, z up): its roll and pitch in FRD, as int16 angles."""
        roll, pitch, _ = quaternion_to_euler(w, x, y, z)
        self.add({"dmp_phi": round(roll * DMP_ANGLE_LSB), "dmp_theta": round(-pitch * DMP_ANGLE_LSB)})

    def add_baro(self, pressure_pa: int) -> None:
        self.add({"pressure": pressure_pa})

    def means(self) -> dict[str, int]:
        """Rounded-to-nearest integer means: exact integer arithmetic, as the board's would be."""
        out = {}
        for name in self.names:
            n, s = self.counts[name], self.sums[name]
            out[name] = (2 * s + n) // (2 * n) if n else 0
        return out

    def result(self, pressure: float = P.P0) -> Calibration:
        """The means as the flight core applies them; ``pressure`` stands in when no barometer sample came.
        Raises ValueError when no IMU sample was collected."""
        if not self.counts.get("gx"):
            raise ValueError("no IMU samples collected")
        o, c = self.means(), self.counts
        return Calibration(
            gyro=(o["gx"], o["gy"], o["gz"]),
            accel=(o["ax"], o["ay"], o["az"]),
            dmp_phi=o["dmp_phi"] / DMP_ANGLE_LSB if c.get("dmp_phi") else 0.0,
            dmp_theta=o["dmp_theta"] / DMP_ANGLE_LSB if c.get("dmp_theta") else 0.0,
            pressure=float(o["pressure"]) if c.get("pressure") else float(pressure),
        )
