"""What the board's telemetry task sends, built from the board's state (docs/board.md, "Tasks").

Over the UART: Attitude and Motion at every telemetry run (50 Hz by default, ``Param.TELEMETRY_HZ``), Height at
20 Hz, Status and Gains at 5 Hz, each field in the protocol's units (int16 fields clipped to their range, where
``term.core.protocol.saturated`` recognises them). Over BLE (the handover STARTED): the phone's Compact packet and, at a
lower rate, Compact2 (the rest of the flight screen: motors, height, vz, set point, flags, lift trim); the link
decides how many of each (fcb_sim/board/wireless.py). ``Telemetry.packets(parts, readings)`` gives the UART packets due
now; ``status``, ``compact`` and ``compact2`` build one packet each. Each takes the board's parts
(``fcb_sim.board.parts.BoardParts``) and what its tasks last measured and commanded (``Readings``), never the Board.
Sans-IO: the board's clock decides what is due.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from fcb_sim.board.parts import BoardParts
from term.core.protocol import (
    Attitude,
    Compact,
    Compact2,
    Flag,
    Gains,
    Height,
    Mode,
    Motion,
    Status,
    WirelessState,
    field_scale,
)

HEIGHT_PERIOD_US = 50_000  # Height at 20 Hz
_H = HEIGHT_UNIT_M = field_scale(Height, "height")  # m per unit on the wire and in the log (the packet table)
_VZ = field_scale(Height, "vz")
_AE2 = int(field_scale(Compact2, "ae1"))  # Compact2 carries a motor command in units of this many
STATUS_PERIOD_US = 200_000  # Status and Gains at 5 Hz


class Readings(NamedTuple):
    """What the board's tasks last measured and commanded."""

    ae: tuple[int, int, int, int]  # motor commands
    pressure: int  # Pa
    temperature: int  # 0.01 °C
    battery: int  # 10 mV
    path: str  # the sensor path running: "dmp" or "raw"


def log_row(b: BoardParts, r: Readings) -> tuple[int, ...]:
    """The flash log's record now (docs/flash_log.md): time, mode, attitude, rates, accelerations, motors, height,
    pressure, battery."""
    fc = b.core
    phi, theta, psi = fc.attitude_centideg()
    return (b.now, int(b.modes.mode), phi, theta, psi, round(fc.sp), round(fc.sq), round(fc.sr), round(fc.sax),
            round(fc.say), round(fc.saz), *r.ae, round(fc.height / HEIGHT_UNIT_M), r.pressure, r.battery)


def i16(v: float) -> int:
    """``v`` rounded and clipped to an int16 field's range."""
    v = int(round(v))
    return -32768 if v < -32768 else 32767 if v > 32767 else v


class Telemetry:
    """The telemetry task's schedule: the packets slower than the task itself go when they are due."""

    def __init__(self) -> None:
        self.runs = 0  # telemetry task runs
        self._due_at: dict[str, float] = {}

    def due(self, name: str, period_us: float, now: int) -> bool:
        """Whether a packet sent at its own rate (slower than the telemetry task) is due now."""
        due = self._due_at.get(name, 0.0)
        if now < due:
            return False
        self._due_at[name] = max(due + period_us, now - period_us / 2)
        return True

    def packets(self, b: BoardParts, r: Readings) -> list[Any]:
        """The UART telemetry due now, in the order it is sent."""
        fc = b.core
        now = b.now
        phi, theta, psi = fc.attitude_centideg()
        out: list[Any] = [Attitude(int(b.modes.mode), i16(phi), i16(theta), i16(psi), i16(fc.sp), i16(fc.sq),
                                   i16(fc.sr)),
                          Motion(i16(fc.sax), i16(fc.say), i16(fc.saz), *r.ae)]
        if self.due("height", HEIGHT_PERIOD_US, now):
            out.append(Height(r.pressure, i16(fc.height / _H), i16(fc.setpoint / _H), i16(fc.vz / _VZ),
                              r.battery, i16(r.temperature)))
        if self.due("status", STATUS_PERIOD_US, now):
            g = fc.gains
            out += [status(b, r), Gains(g.yaw_p, g.p1, g.p2, g.height_p, g.height_d)]
        return out


def compact(b: BoardParts, r: Readings) -> Compact:
    """The phone's telemetry: mode, handover state, attitude, battery."""
    phi, theta, psi = b.core.attitude_centideg()
    return Compact(int(b.modes.mode), int(b.wireless.state), phi, theta, psi, r.battery)


def compact2(b: BoardParts, r: Readings) -> Compact2:
    """The rest of the flight screen over BLE: motors (rounded to Compact2's unit), height, set point, vertical
    speed, the Status flags and the lift trim."""
    fc = b.core
    ae = (min(255, max(0, (int(a) + _AE2 // 2) // _AE2)) for a in r.ae)
    return Compact2(*ae, i16(fc.height / _H), i16(fc.setpoint / _H), i16(fc.vz / _VZ), flags(b, r),
                    b.modes.trims.lift)


def flags(b: BoardParts, r: Readings) -> int:
    """The status bits (``Flag``), as Status and Compact2 carry them."""
    m = b.modes
    bits = ((Flag.CALIBRATED, m.calibrated), (Flag.ARMED, m.motors_enabled),
            (Flag.LOGGING, b.log.recording), (Flag.BLE_CONNECTED, b.wireless.is_connected),
            (Flag.WIRELESS_ACTIVE, b.wireless.state is WirelessState.STARTED),
            (Flag.LOW_BATTERY, r.battery < m.config.low_battery or m.battery_low_latched),
            (Flag.LINK_TIMEOUT, m.link_timed_out), (Flag.RAW_SENSORS, r.path == "raw"),
            (Flag.FIXED_POINT, b.config.fixed_point), (Flag.PRIORITY_SCHEDULER, b.sched.priority),
            (Flag.HEIGHT_HOLD, m.mode == Mode.HEIGHT), (Flag.CRASHED, m.crashed),
            (Flag.MOTOR_TEST, m.motor_test.running),
            (Flag.HEIGHT_UNSURE, b.core.height_unsure))
    return sum(int(flag) for flag, on in bits if on)


def status(b: BoardParts, r: Readings) -> Status:
    """The Status packet: flags, trims, CPU load since the last Status, log fill, handover state."""
    t = b.modes.trims
    return Status(flags(b, r), t.roll, t.pitch, t.yaw, t.lift, b.prof.load(b.now), b.log.fill_pct,
                  int(b.wireless.state))
