"""The flight in MAVLink's words: the board's packets and term's figures as MAVLink messages, and back (the mapping
table is docs/mavlink.md). Pure: no socket, no thread, no clock; pymavlink's ``common`` dialect (the ``mavlink``
extra) builds the messages. Used by the live endpoint (term/data/mavlink.py) and the telemetry-log writer
(term/data/tlog.py), so a live ground station and a .tlog see the same messages.

- ``codec()``: pymavlink's MAVLink 2 codec, or ``MavlinkMissing`` (one line naming the extra).
- ``Telemetry``: fed board packets (``packet``), link statistics (``stats``) and the time; gives the messages each
  one makes (ATTITUDE from Attitude and Compact; ALTITUDE, VFR_HUD, SCALED_PRESSURE from Height; SERVO_OUTPUT_RAW
  from Motion; STATUSTEXT from Event) and, once a second, HEARTBEAT, SYS_STATUS and BATTERY_STATUS (``periodic``).
  Rates are capped per message (``RATE_HZ``): what QGroundControl and MAVProxy draw from, not every packet.
- Parameters: ``PARAM_NAMES`` gives each row of the protocol's parameter table (``PARAMS``) a MAVLink name of at
  most 16 characters (``ctrl.yaw_p`` is ``CTRL_YAW_P``; long words shortened by ``_ABBREV``), ``PARAM_BY_MAV``
  the way back. Every value travels as MAV_PARAM_TYPE_REAL32 (bytewise and cast readings agree): numbers in
  their unit, an enum as its raw number (its choice's index plus the table's base), a bool as 0 or 1.
  ``param_raw(spec, value)`` is a float from the ground station to the wire's raw value (to the table's step:
  a float32 cannot carry 0.999 exactly), or the one-line reason it is refused (outside the table's range).
- Modes: the HEARTBEAT's custom mode is the board's ``Mode`` number; MAV_MODE_FLAG_SAFETY_ARMED is set out of
  SAFE (in a flight mode and in PANIC: the motors may turn).
"""

from __future__ import annotations

import math
from typing import Any

from term.core.protocol import (
    BATTERY_FULL,
    BATTERY_LOW,
    EVENT_ARG_SCALE,
    FLIGHT_MODES,
    GYRO_LSB_PER_DPS,
    PARAMS,
    Attitude,
    Compact,
    Compact2,
    Event,
    EventCode,
    Flag,
    Height,
    Mode,
    Motion,
    ParamSpec,
    Status,
    field_scale,
)
from term.session.texts import event_text

INSTALL_HINT = "MAVLink needs pymavlink: pip install 'quadrupel[mavlink]' (or: pip install pymavlink)"
SYSTEM_ID = 1  # the vehicle's MAVLink system id (a ground station is 255)
COMPONENT_ID = 1  # MAV_COMP_ID_AUTOPILOT1
PARAM_NAME_MAX = 16  # MAVLink's param_id: 16 characters, no terminator when full
STATUSTEXT_MAX = 50  # one STATUSTEXT's text; longer ones go in chunks sharing an id (MAVLink 2)
# The most each message is sent a second (the board's Attitude comes at 50 Hz: every one goes; the rest at what
# ground stations draw from: PX4's and ArduPilot's default rates for a telemetry link).
RATE_HZ = {"ATTITUDE": 50.0, "ALTITUDE": 10.0, "VFR_HUD": 10.0, "SCALED_PRESSURE": 5.0, "SERVO_OUTPUT_RAW": 10.0}
PERIODIC = ("HEARTBEAT", "SYS_STATUS", "BATTERY_STATUS")  # once a second each (``Telemetry.periodic``)
PWM_MIN_US = 1000  # a motor command 0..1000 is a PWM pulse 1000..2000 µs in SERVO_OUTPUT_RAW
SEA_LEVEL_PA = 101325.0
CELLS = 3  # the 3S LiPo of the report: battery_remaining is linear from BATTERY_LOW (0 %) to BATTERY_FULL (100 %)
# Words shortened so every name fits 16 characters (the test checks each is unique and fits).
_ABBREV = {"REACTION": "RXN", "TELEMETRY": "TELEM", "HEARTBEAT": "HB", "CALIBRATION": "CALIB",
           "COUNTDOWN": "CD"}
_ASCII = str.maketrans({"→": "->", "—": "-", "–": "-", "°": " deg", "µ": "u", "×": "x", "…": "...", "·": "-",
                        "²": "^2", "‘": "'", "’": "'", "“": '"', "”": '"'})
# Board events a ground station must not miss: MAV_SEVERITY_CRITICAL (the rest by term's severity).
_CRITICAL = frozenset({EventCode.TILT_LIMIT, EventCode.LOW_BATTERY, EventCode.CRASH, EventCode.LINK_LOST,
                       EventCode.LINK_TIMEOUT, EventCode.SENSOR_FAULT})


class MavlinkMissing(RuntimeError):
    """pymavlink is not installed (the message is INSTALL_HINT)."""


def dialect() -> Any:
    """pymavlink's ``common`` dialect, MAVLink 2 (MavlinkMissing without pymavlink)."""
    try:
        from pymavlink.dialects.v20 import common
    except ImportError:
        raise MavlinkMissing(INSTALL_HINT) from None
    return common


def codec(source_system: int = SYSTEM_ID, source_component: int = COMPONENT_ID) -> Any:
    """A MAVLink 2 codec: its ``*_encode`` build messages, ``pack`` turns one into bytes, ``parse_buffer`` reads."""
    mav = dialect().MAVLink(None, srcSystem=source_system, srcComponent=source_component)
    mav.robust_parsing = True  # a garbled byte costs its message, never the stream
    return mav


def pack(mav: Any, msg: Any) -> bytes:
    """``msg`` as bytes with ``mav``'s next sequence number (what ``MAVLink.send`` does, without a file)."""
    buf = msg.pack(mav)
    mav.seq = (mav.seq + 1) % 256
    return bytes(buf)


# --- parameters -------------------------------------------------------------------------------------------------


def mav_param_name(name: str) -> str:
    """``ctrl.yaw_p`` -> ``CTRL_YAW_P``; long words shortened (``_ABBREV``) until it fits 16 characters."""
    words = name.upper().replace(".", "_").split("_")
    out = "_".join(words)
    for i, w in enumerate(words):
        if len(out) <= PARAM_NAME_MAX:
            break
        if w in _ABBREV:
            words[i] = _ABBREV[w]
            out = "_".join(words)
    return out


PARAM_NAMES: dict[int, str] = {int(p): mav_param_name(spec.name) for p, spec in PARAMS.items()}
PARAM_BY_MAV: dict[str, ParamSpec] = {PARAM_NAMES[int(p)]: spec for p, spec in PARAMS.items()}
PARAM_ORDER: tuple[int, ...] = tuple(int(p) for p in PARAMS)  # param_index: the table's order


def param_float(spec: ParamSpec, raw: int) -> float:
    """The board's raw value as the REAL32 a ground station reads (numbers in their unit, enums raw, bools 0/1)."""
    if spec.kind in ("enum", "bool"):
        return float(raw)
    return float(spec.from_raw(raw))


def param_raw(spec: ParamSpec, value: float) -> tuple[int | None, str]:
    """A ground station's float for ``spec`` as the wire's raw value, or (None, why) if the table refuses it."""
    if not math.isfinite(value):
        return None, "not a number"
    if spec.kind in ("enum", "bool"):
        raw = round(value)
        if raw != value or not spec.accepts(raw):
            choices = ", ".join(f"{spec.base + i} {c}" for i, c in enumerate(spec.choices)) or "0 false, 1 true"
            return None, f"{value:g} is not one of {choices}"
        return raw, ""
    raw = round(value / spec.scale)
    if not spec.accepts(raw):
        return None, f"{value:g} outside {spec.text(spec.lo)}..{spec.text(spec.hi)} {spec.unit}".rstrip()
    return raw, ""


# --- modes and severities ---------------------------------------------------------------------------------------


def armed(mode: int | None) -> bool:
    """Out of SAFE the motors may turn: a flight mode, or PANIC's descent."""
    return mode is not None and (mode in FLIGHT_MODES or mode == Mode.PANIC)


def severity(code: int, term_severity: str) -> int:
    m = dialect()
    if code in _CRITICAL:
        return m.MAV_SEVERITY_CRITICAL
    return {"error": m.MAV_SEVERITY_ERROR, "warning": m.MAV_SEVERITY_WARNING}.get(term_severity,
                                                                                  m.MAV_SEVERITY_INFO)


def statustexts(mav: Any, sev: int, text: str, text_id: int) -> list[Any]:
    """``text`` as STATUSTEXT messages: one if it fits 50 bytes, else chunks sharing ``text_id`` (1..65535). In
    ASCII (MAVLink's char: ground stations show UTF-8 as garbage): term's arrows and units spelled out."""
    data = text.translate(_ASCII).encode("ascii", "replace")
    if len(data) <= STATUSTEXT_MAX:
        return [mav.statustext_encode(sev, data)]
    out = []
    for seq, i in enumerate(range(0, len(data), STATUSTEXT_MAX)):
        out.append(mav.statustext_encode(sev, data[i:i + STATUSTEXT_MAX], text_id, seq))
        if seq >= 255:
            break
    if len(data) % STATUSTEXT_MAX == 0:  # a full last chunk: an empty one says the text ended
        out.append(mav.statustext_encode(sev, b"", text_id, len(out)))
    return out


# --- telemetry --------------------------------------------------------------------------------------------------

_DEG = math.pi / 180.0
_RATE = 1.0 / GYRO_LSB_PER_DPS * _DEG  # raw gyro LSB to rad/s
_CENTI = 0.01  # 0.01° to °, cm to m (the packet table's scales, checked in the test)


class Telemetry:
    """Board packets to MAVLink messages (module docstring). Not thread-safe: one feeder at a time (the endpoint
    holds its lock)."""

    def __init__(self, mav: Any) -> None:
        self.mav = mav
        self.m = dialect()
        self.mode: int | None = None
        self.flags = 0
        self.cpu_load = 0
        self.battery: int | None = None  # 10 mV
        self.drop_pct: float | None = None  # the board's link: frames lost, %
        self.bad_frames = 0
        self.psi = 0.0
        self.motors = (0, 0, 0, 0)
        self._due: dict[str, float] = {}
        self._text_id = 0

    def stats(self, loss_pct: float | None, frames_bad: int) -> None:
        self.drop_pct, self.bad_frames = loss_pct, frames_bad

    def _due_now(self, name: str, t: float) -> bool:
        """Rate cap: True (and the next slot booked) if ``name`` may go at ``t`` (seconds)."""
        due = self._due.get(name, -1e9)
        if t < due:
            return False
        period = 1.0 / RATE_HZ[name]
        self._due[name] = max(due, t - period / 2) + period  # (half a period of jitter let through, no burst)
        return True

    def packet(self, pkt: Any, t: float) -> list[Any]:
        """The messages ``pkt`` makes at ``t`` (seconds since the session began: ``time_boot_ms``)."""
        kind = type(pkt)
        ms = max(0, int(t * 1000)) & 0xFFFFFFFF
        m = self.mav
        if kind is Attitude or kind is Compact:
            self.mode = pkt.mode
            self.psi = pkt.psi * _CENTI
            if kind is Compact:
                self.battery = pkt.battery
            if not self._due_now("ATTITUDE", t):
                return []
            rates = (pkt.sp * _RATE, pkt.sq * _RATE, pkt.sr * _RATE) if kind is Attitude else (0.0, 0.0, 0.0)
            return [m.attitude_encode(ms, pkt.phi * _CENTI * _DEG, pkt.theta * _CENTI * _DEG, pkt.psi * _CENTI * _DEG,
                                      *rates)]
        if kind is Height:
            self.battery = pkt.battery
            return self._height(pkt.height * _CENTI, pkt.vz * _CENTI, pkt.pressure, pkt.temperature, ms, t)
        if kind is Compact2:
            self.flags = pkt.flags
            self.motors = (pkt.ae1 * 4, pkt.ae2 * 4, pkt.ae3 * 4, pkt.ae4 * 4)
            return self._servos(ms, t) + self._height(pkt.height * _CENTI, pkt.vz * _CENTI, None, None, ms, t)
        if kind is Motion:
            self.motors = (pkt.ae1, pkt.ae2, pkt.ae3, pkt.ae4)
            return self._servos(ms, t)
        if kind is Status:
            self.flags, self.cpu_load = pkt.flags, pkt.cpu_load
            return []
        if kind is Event:
            return self.event(pkt.code, pkt.arg)
        return []

    def event(self, code: int, arg: int) -> list[Any]:
        if code == EventCode.MODE_CHANGED:
            self.mode = arg & 0xFF
        term_sev, text = event_text(code, arg, flying=self.mode in FLIGHT_MODES)
        self._text_id = self._text_id % 65535 + 1
        return statustexts(self.mav, severity(code, term_sev), text, self._text_id)

    def text(self, sev: int, text: str) -> list[Any]:
        """A line of term's own (a refusal, the handover) as STATUSTEXT."""
        self._text_id = self._text_id % 65535 + 1
        return statustexts(self.mav, sev, text, self._text_id)

    def _height(self, h: float, vz: float, pressure: int | None, temp: int | None, ms: int, t: float) -> list[Any]:
        m, out = self.mav, []
        if self._due_now("ALTITUDE", t):
            amsl = float("nan") if not pressure else 44330.0 * (1.0 - (pressure / SEA_LEVEL_PA) ** 0.1903)
            out.append(m.altitude_encode(ms * 1000, h, amsl, h, h, float("nan"), h))
        if self._due_now("VFR_HUD", t):
            throttle = round(sum(self.motors) / 40)  # mean motor command 0..1000 -> %
            out.append(m.vfr_hud_encode(0.0, 0.0, round(self.psi) % 360, throttle, h, vz))
        if pressure is not None and temp is not None and self._due_now("SCALED_PRESSURE", t):
            out.append(m.scaled_pressure_encode(ms, pressure / 100.0, 0.0, temp))
        return out

    def _servos(self, ms: int, t: float) -> list[Any]:
        if not self._due_now("SERVO_OUTPUT_RAW", t):
            return []
        pwm = [PWM_MIN_US + max(0, min(1000, a)) for a in self.motors]
        return [self.mav.servo_output_raw_encode(ms * 1000, 0, *pwm, 0, 0, 0, 0)]

    def periodic(self) -> list[Any]:
        """HEARTBEAT, SYS_STATUS, BATTERY_STATUS: once a second (the caller's timer)."""
        m, d = self.mav, self.m
        base = d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | d.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        if self.mode in (Mode.FULL, Mode.RAW, Mode.HEIGHT, Mode.YAW):
            base |= d.MAV_MODE_FLAG_STABILIZE_ENABLED
        state = d.MAV_STATE_STANDBY
        if armed(self.mode):
            base |= d.MAV_MODE_FLAG_SAFETY_ARMED
            state = d.MAV_STATE_EMERGENCY if self.mode == Mode.PANIC else d.MAV_STATE_ACTIVE
        elif self.mode is None:
            state = d.MAV_STATE_BOOT
        out = [m.heartbeat_encode(d.MAV_TYPE_QUADROTOR, d.MAV_AUTOPILOT_GENERIC, base,
                                  self.mode if self.mode is not None else 0, state, 3)]
        sensors = (d.MAV_SYS_STATUS_SENSOR_3D_GYRO | d.MAV_SYS_STATUS_SENSOR_3D_ACCEL
                   | d.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE | d.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                   | d.MAV_SYS_STATUS_SENSOR_BATTERY)
        health = sensors | d.MAV_SYS_STATUS_GEOFENCE  # (no fence: healthy, as ArduPilot says; MAVProxy's "breach")
        if self.flags & Flag.LOW_BATTERY:
            health &= ~d.MAV_SYS_STATUS_SENSOR_BATTERY
        volts_mv = 0xFFFF if self.battery is None else self.battery * 10
        remaining = -1 if self.battery is None else max(0, min(100, round(
            100 * (self.battery - BATTERY_LOW) / (BATTERY_FULL - BATTERY_LOW))))
        drop = 0 if self.drop_pct is None else max(0, min(10000, round(self.drop_pct * 100)))
        out.append(m.sys_status_encode(sensors, sensors, health, min(1000, self.cpu_load * 10), volts_mv, -1,
                                       remaining, drop, min(0xFFFF, self.bad_frames), 0, 0, 0, 0))
        cells = [0xFFFF] * 10
        if self.battery is not None:
            cells[0] = self.battery * 10
        out.append(m.battery_status_encode(0, d.MAV_BATTERY_FUNCTION_ALL, d.MAV_BATTERY_TYPE_LIPO, 0x7FFF, cells,
                                           -1, -1, -1, remaining))
        return out


def scales_agree() -> bool:
    """The centi-units above are the packet table's (a test holds this)."""
    return (field_scale(Attitude, "phi") == _CENTI and field_scale(Height, "height") == _CENTI
            and field_scale(Height, "vz") == _CENTI and EVENT_ARG_SCALE[EventCode.LOW_BATTERY][0] == _CENTI)
