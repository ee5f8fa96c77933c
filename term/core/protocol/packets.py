"""The packet table: every packet's id, direction, rate and fields (wire format, unit, scale), the packet classes,
and the conversions through the table (``scaled``, ``field_scale``, ``field_limits``, ``saturated``).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, NamedTuple, get_type_hints

from term.core.protocol.facts import (
    ACC_LSB_PER_G,
    BOARD_TO_PC,
    BOTH,
    GYRO_LSB_PER_DPS,
    LOG_TIME_COLUMN,
    MAX_BODY,
    PC_TO_BOARD,
    EventCode,
)

# --- the packet table ---------------------------------------------------------------------------------------


_INT_LIMITS = {"B": (0, 0xFF), "b": (-0x80, 0x7F), "H": (0, 0xFFFF), "h": (-0x8000, 0x7FFF),
               "I": (0, 0xFFFFFFFF), "i": (-0x80000000, 0x7FFFFFFF), "e": (-65504, 65504)}


@dataclass(frozen=True, slots=True)
class F:
    """A packet field's wire format (a struct character), unit and meaning; used inside ``Annotated``.

    ``scale`` turns a raw value into ``scaled_unit`` (the unit the terminal shows; the raw unit if omitted)."""

    fmt: str
    unit: str = ""
    doc: str = ""
    scale: float = 1.0
    scaled_unit: str | None = None


@dataclass(frozen=True, slots=True)
class FieldSpec:
    name: str
    fmt: str
    unit: str
    doc: str
    scale: float = 1.0
    scaled_unit: str = ""

    @property
    def limits(self) -> tuple[int, int] | None:
        """The smallest and largest raw value the encoding holds (None for byte strings)."""
        return _INT_LIMITS.get(self.fmt)

    def saturated(self, raw: float) -> bool:
        """Whether ``raw`` sits at an end of the encoding, where the sender clips: the true value may lie beyond.
        The lower end counts for signed fields only (an unsigned field's 0 is a true zero)."""
        lim = self.limits
        if lim is None:
            return False
        return raw >= lim[1] or (lim[0] < 0 and raw <= lim[0])


@dataclass(frozen=True, slots=True)
class PacketSpec:
    type_id: int
    cls: type
    direction: str
    rate: str
    doc: str
    fields: tuple[FieldSpec, ...]
    struct: struct.Struct

    @property
    def body_size(self) -> int:
        return self.struct.size

    @property
    def frame_size(self) -> int:
        """Bytes on the wire for this packet, delimiter included: fixed per type because COBS adds one byte
        for every 254, and no body is that long."""
        return self.body_size + 6


PACKETS: dict[int, PacketSpec] = {}
SPEC_OF: dict[type, PacketSpec] = {}


def _typed_eq(self: tuple, other: object) -> bool:
    return type(self) is type(other) and tuple.__eq__(self, other)  # type: ignore[arg-type]


def _typed_ne(self: tuple, other: object) -> bool:
    return not _typed_eq(self, other)


def _typed_hash(self: tuple) -> int:
    return hash((type(self).__name__, tuple(self)))


def packet(type_id: int, direction: str, rate: str, doc: str) -> Callable[[type], type]:
    """Register a NamedTuple as a packet type; its ``Annotated[..., F(...)]`` fields define the body's layout.

    Packets are immutable tuples (cheap to build on the decoder's hot path) whose equality includes the type,
    so ``Heartbeat(1, 2) != HeartbeatAck(1, 2)``.
    """

    def register(cls: type) -> type:
        hints = get_type_hints(cls, include_extras=True)
        fields = []
        for name in cls._fields:  # type: ignore[attr-defined]
            meta = [m for m in getattr(hints[name], "__metadata__", ()) if isinstance(m, F)]
            if not meta:
                raise TypeError(f"{cls.__name__}.{name}: declare it as Annotated[type, F(...)]")
            f = meta[0]
            unit = f.unit if f.scaled_unit is None else f.scaled_unit
            fields.append(FieldSpec(name, f.fmt, f.unit, f.doc, f.scale, unit))
        layout = struct.Struct("<" + "".join(fs.fmt for fs in fields))
        if layout.size > MAX_BODY:
            raise ValueError(f"{cls.__name__}: body {layout.size} bytes > {MAX_BODY}")
        if type_id in PACKETS or not 0 < type_id < 256:
            raise ValueError(f"{cls.__name__}: bad or duplicate type id {type_id:#x}")
        cls.__eq__ = _typed_eq  # type: ignore[method-assign,assignment]
        cls.__ne__ = _typed_ne  # type: ignore[method-assign,assignment]
        cls.__hash__ = _typed_hash  # type: ignore[method-assign,assignment]
        spec = PacketSpec(type_id, cls, direction, rate, doc, tuple(fields), layout)
        PACKETS[type_id] = spec
        SPEC_OF[cls] = spec
        return cls

    return register


@packet(0x01, PC_TO_BOARD, "≤100 Hz; on change + 2 Hz keep-alive over BLE", "Absolute joystick position.")
class Joystick(NamedTuple):
    roll: Annotated[int, F("h", "stick", "axis 0, -32767 full left .. 32767 full right")]
    pitch: Annotated[int, F("h", "stick", "axis 1, -32767 forward (nose down) .. 32767 back")]
    yaw: Annotated[int, F("h", "stick", "axis 2 (twist), -32767 left .. 32767 right")]
    lift: Annotated[int, F("h", "stick", "axis 3 (throttle), 0 none .. 32767 full")]
    buttons: Annotated[int, F("B", "bits", "Button flags; bit 0 fire = PANIC")]


@packet(0x02, PC_TO_BOARD, "on key press; retried until acknowledged", "A keyboard command; the board answers Ack.")
class Command(NamedTuple):
    cmd_id: Annotated[int, F("B", "", "sender's command counter, echoed in the Ack")]
    op: Annotated[int, F("B", "Op", "the operation")]
    arg: Annotated[int, F("i", "", "operation argument, see Op")]


@packet(0x03, PC_TO_BOARD, "once per Heartbeat", "Answer to a Heartbeat, sent at once; the board measures RTT.")
class HeartbeatAck(NamedTuple):
    counter: Annotated[int, F("H", "", "the Heartbeat's counter")]
    board_ms: Annotated[int, F("I", "ms", "the Heartbeat's board time, echoed", 1e-3, "s")]


@packet(0x04, BOTH, "at connect", "Version handshake: each side sends its own; a mismatch is reported.")
class Hello(NamedTuple):
    protocol: Annotated[int, F("B", "", "PROTOCOL_VERSION of the sender")]
    role: Annotated[int, F("B", "Role", "0 terminal, 1 board")]
    major: Annotated[int, F("B", "", "software major version")]
    minor: Annotated[int, F("B", "", "software minor version")]
    board_id: Annotated[int, F("H", "", "board serial number (0 from a terminal)")]


@packet(0x10, BOARD_TO_PC, "10 Hz", "Heartbeat; the terminal answers HeartbeatAck at once.")
class Heartbeat(NamedTuple):
    counter: Annotated[int, F("H", "", "increments per heartbeat")]
    board_ms: Annotated[int, F("I", "ms", "board time since boot", 1e-3, "s")]
    rtt: Annotated[int, F("H", "0.1 ms", "previous Heartbeat's round trip to its HeartbeatAck; 0 if none",
                           1e-4, "s")] = 0


@packet(0x11, BOARD_TO_PC, "once per Command", "Command acknowledgement (status 0) or refusal (status = Nak).")
class Ack(NamedTuple):
    cmd_id: Annotated[int, F("B", "", "the Command's cmd_id")]
    op: Annotated[int, F("B", "Op", "the Command's op")]
    status: Annotated[int, F("B", "Nak", "0 accepted, else the reason for refusal")]
    value: Annotated[int, F("i", "", "resulting value (mode, trim, gain in milli-units) where one applies")]


@packet(0x12, BOARD_TO_PC, "50 Hz", "Attitude telemetry.")
class Attitude(NamedTuple):
    mode: Annotated[int, F("B", "Mode", "current mode")]
    phi: Annotated[int, F("h", "0.01°", "roll angle", 0.01, "°")]
    theta: Annotated[int, F("h", "0.01°", "pitch angle", 0.01, "°")]
    psi: Annotated[int, F("h", "0.01°", "yaw angle", 0.01, "°")]
    sp: Annotated[int, F("h", "LSB (16.4/°/s)", "roll rate", 1 / GYRO_LSB_PER_DPS, "°/s")]
    sq: Annotated[int, F("h", "LSB (16.4/°/s)", "pitch rate", 1 / GYRO_LSB_PER_DPS, "°/s")]
    sr: Annotated[int, F("h", "LSB (16.4/°/s)", "yaw rate", 1 / GYRO_LSB_PER_DPS, "°/s")]


@packet(0x13, BOARD_TO_PC, "50 Hz", "Accelerations and motor commands.")
class Motion(NamedTuple):
    sax: Annotated[int, F("h", "LSB (16384/g)", "body x acceleration", 1 / ACC_LSB_PER_G, "g")]
    say: Annotated[int, F("h", "LSB (16384/g)", "body y acceleration", 1 / ACC_LSB_PER_G, "g")]
    saz: Annotated[int, F("h", "LSB (16384/g)", "body z acceleration", 1 / ACC_LSB_PER_G, "g")]
    ae1: Annotated[int, F("H", "0..1000", "front motor command")]
    ae2: Annotated[int, F("H", "0..1000", "right motor command")]
    ae3: Annotated[int, F("H", "0..1000", "back motor command")]
    ae4: Annotated[int, F("H", "0..1000", "left motor command")]


@packet(0x14, BOARD_TO_PC, "20 Hz", "Barometer, height estimate and battery.")
class Height(NamedTuple):
    pressure: Annotated[int, F("I", "Pa", "barometric pressure")]
    height: Annotated[int, F("h", "cm", "estimated height above the reference", 0.01, "m")]
    setpoint: Annotated[int, F("h", "cm", "height set point (HEIGHT mode)", 0.01, "m")]
    vz: Annotated[int, F("h", "cm/s", "estimated vertical speed, up positive", 0.01, "m/s")]
    battery: Annotated[int, F("H", "10 mV", "battery voltage", 0.01, "V")]
    temperature: Annotated[int, F("h", "0.01 °C", "barometer temperature", 0.01, "°C")]


@packet(0x15, BOARD_TO_PC, "5 Hz", "Board status: flags, trims, load and log fill.")
class Status(NamedTuple):
    flags: Annotated[int, F("H", "Flag", "status bits")]
    trim_roll: Annotated[int, F("h", "stick", "keyboard roll trim")]
    trim_pitch: Annotated[int, F("h", "stick", "keyboard pitch trim")]
    trim_yaw: Annotated[int, F("h", "stick", "keyboard yaw trim")]
    trim_lift: Annotated[int, F("h", "stick", "keyboard lift trim")]
    cpu_load: Annotated[int, F("B", "%", "share of the loop spent in tasks")]
    log_fill: Annotated[int, F("B", "%", "flash log fill")]
    wireless: Annotated[int, F("B", "WirelessState", "BLE handover state")]


@packet(0x16, BOARD_TO_PC, "5 Hz", "Controller gains.")
class Gains(NamedTuple):
    yaw_p: Annotated[float, F("e", "", "yaw-rate P")]
    p1: Annotated[float, F("e", "", "roll/pitch angle P1")]
    p2: Annotated[float, F("e", "", "roll/pitch rate P2")]
    height_p: Annotated[float, F("e", "", "height P")]
    height_d: Annotated[float, F("e", "", "height D")]


@packet(0x17, BOARD_TO_PC, "on change", "A board event: refused transition, low battery, link timeout, ...")
class Event(NamedTuple):
    code: Annotated[int, F("B", "EventCode", "what happened")]
    arg: Annotated[int, F("i", "", "detail, see EventCode")]
    board_ms: Annotated[int, F("I", "ms", "board time", 1e-3, "s")]


@packet(0x18, BOARD_TO_PC, "on request, one per task", "Task profile: durations and period of one task.")
class Profile(NamedTuple):
    task: Annotated[int, F("B", "", "task id (board.TASKS order)")]
    mean_us: Annotated[int, F("H", "µs", "mean duration")]
    p99_us: Annotated[int, F("H", "µs", "99th percentile duration")]
    p999_us: Annotated[int, F("H", "µs", "99.9th percentile duration")]
    period_us: Annotated[int, F("I", "µs", "mean period")]
    misses: Annotated[int, F("H", "", "deadline misses since profiling started")]


@packet(0x19, BOARD_TO_PC, "on request; streamed during download", "Flash log status.")
class LogStatus(NamedTuple):
    state: Annotated[int, F("B", "LogState", "")]
    used: Annotated[int, F("I", "bytes", "bytes of flash used")]
    records: Annotated[int, F("I", "", "records written")]
    crc32: Annotated[int, F("I", "", "zlib.crc32 of the used bytes: the download's end-to-end check")]


@packet(0x1A, BOARD_TO_PC, "during download", "12 bytes of the flash log; chunk i holds bytes 12i .. 12i+11.")
class LogChunk(NamedTuple):
    index: Annotated[int, F("H", "", "chunk number")]
    data: Annotated[bytes, F("12s", "", "log bytes; the last chunk is padded with 0xFF (erased flash)")]


@packet(0x1B, BOARD_TO_PC, "4 per heartbeat over BLE (40 Hz)", "The phone's telemetry: mode, attitude, battery.")
class Compact(NamedTuple):
    mode: Annotated[int, F("B", "Mode", "")]
    wireless: Annotated[int, F("B", "WirelessState", "")]
    phi: Annotated[int, F("h", "0.01°", "", 0.01, "°")]
    theta: Annotated[int, F("h", "0.01°", "", 0.01, "°")]
    psi: Annotated[int, F("h", "0.01°", "", 0.01, "°")]
    battery: Annotated[int, F("H", "10 mV", "", 0.01, "V")]


@packet(0x1C, BOARD_TO_PC, "on PARAM_LIST, one per parameter", "One board parameter's value (PARAMS).")
class ParamValue(NamedTuple):
    param: Annotated[int, F("B", "Param", "the parameter's id")]
    value: Annotated[int, F("i", "raw", "its raw value (ParamSpec.from_raw gives it in its unit)")]
    index: Annotated[int, F("B", "", "0-based place in this listing")]
    count: Annotated[int, F("B", "", "parameters in this listing")]


@packet(0x1D, BOARD_TO_PC, "1 per heartbeat over BLE (10 Hz)",
        "The rest of the flight screen over BLE: motors, height, vertical speed, set point, flags, lift trim.")
class Compact2(NamedTuple):
    ae1: Annotated[int, F("B", "4 units", "front motor command / 4, rounded", 4, "0..1000")]
    ae2: Annotated[int, F("B", "4 units", "right motor command / 4, rounded", 4, "0..1000")]
    ae3: Annotated[int, F("B", "4 units", "back motor command / 4, rounded", 4, "0..1000")]
    ae4: Annotated[int, F("B", "4 units", "left motor command / 4, rounded", 4, "0..1000")]
    height: Annotated[int, F("h", "cm", "estimated height above the reference", 0.01, "m")]
    setpoint: Annotated[int, F("h", "cm", "height set point (HEIGHT mode)", 0.01, "m")]
    vz: Annotated[int, F("h", "cm/s", "estimated vertical speed, up positive", 0.01, "m/s")]
    flags: Annotated[int, F("H", "Flag", "status bits, as Status.flags")]
    trim_lift: Annotated[int, F("h", "stick", "keyboard lift trim")]


@packet(0x1E, BOARD_TO_PC, "on qb_log; a line in as many as it takes",
        "A piece of the board's own debug text (qb_log): a line longer than 13 bytes goes in several, in order.")
class Text(NamedTuple):
    info: Annotated[int, F("B", "bits", "bits 0-2 the level (1 debug .. 5 fatal, as foxglove.Log); bit 7: the "
                                        "line goes on in the next Text")]
    text: Annotated[bytes, F("13s", "", "UTF-8, padded with 0x00")]


LOG_CHUNK_BYTES = 12
TEXT_BYTES = 13  # of a line per Text packet
TEXT_MORE = 0x80  # Text.info: the line goes on in the next Text
TEXT_LEVEL_MASK = 0x07
LEVEL_DEBUG, LEVEL_INFO, LEVEL_WARNING, LEVEL_ERROR, LEVEL_FATAL = 1, 2, 3, 4, 5  # foxglove.Log's levels


def text_packets(line: str | bytes, level: int = LEVEL_INFO) -> list[Text]:
    """``line`` (one line, no newline) as Text packets: UTF-8 cut at 13 bytes, never inside a character; every
    packet but the last has TEXT_MORE set. An empty line is one empty packet. A NUL in the line goes as a space:
    NULs pad the packet's text, so one inside it could not be told from the padding."""
    data = line.encode("utf-8", "replace") if isinstance(line, str) else bytes(line)
    data = data.replace(b"\0", b" ")
    lvl = level & TEXT_LEVEL_MASK
    out: list[Text] = []
    while True:
        cut = min(len(data), TEXT_BYTES)
        while 0 < cut < len(data) and (data[cut] & 0xC0) == 0x80:  # a continuation byte: cut before its character
            cut -= 1
        if cut == 0:  # a 'character' longer than a packet (not UTF-8): cut anyway
            cut = min(len(data), TEXT_BYTES)
        piece, data = data[:cut], data[cut:]
        out.append(Text(lvl | (TEXT_MORE if data else 0), piece.ljust(TEXT_BYTES, b"\0")))
        if not data:
            return out


TELEMETRY = (Attitude, Motion, Height, Status, Gains)

# Event arguments that are quantities: the scale to the shown unit, per code (the rest are counts or ids).
EVENT_ARG_SCALE: dict[EventCode, tuple[float, str]] = {
    EventCode.LOW_BATTERY: (0.01, "V"),
    EventCode.LINK_TIMEOUT: (1e-3, "s"),
    EventCode.TILT_LIMIT: (0.01, "°"),
    EventCode.DEADLINE_MISS: (1.0, "µs"),
    EventCode.CRASH: (1e-3, "m/s"),
    EventCode.LINK_LOST: (1e-3, "s"),
    EventCode.LINK_REGAINED: (1e-3, "s"),
    EventCode.SIM_LAG: (1e-3, "s"),
    EventCode.HEADING_DRIFT: (0.01, "°"),
    EventCode.HEIGHT_SETPOINT: (1e-3, "m"),
}


# --- scales and limits: convert through the table -----------------------------------------------------------


def field_spec(cls: type, name: str) -> FieldSpec:
    """The table's entry for field ``name`` of packet class ``cls`` (KeyError if there is none)."""
    for fs in SPEC_OF[cls].fields:
        if fs.name == name:
            return fs
    raise KeyError(f"{cls.__name__} has no field {name!r}")


def field_scale(cls: type, name: str) -> float:
    """Multiply a raw ``cls.name`` by this to get it in ``field_unit(cls, name)``."""
    return field_spec(cls, name).scale


def field_unit(cls: type, name: str) -> str:
    """The unit of a scaled ``cls.name`` (degrees, m, V, s, ...)."""
    return field_spec(cls, name).scaled_unit


def field_limits(cls: type, name: str) -> tuple[int, int] | None:
    """The raw range the encoding of ``cls.name`` holds."""
    return field_spec(cls, name).limits


def scaled(pkt: Any, name: str) -> float:
    """Field ``name`` of ``pkt`` in its shown unit: ``getattr(pkt, name) * field_scale(type(pkt), name)``."""
    return getattr(pkt, name) * field_spec(type(pkt), name).scale


def saturated(pkt: Any, name: str) -> bool:
    """Whether field ``name`` of ``pkt`` sits at the end of its encoding (the board clips there: the true value
    may be beyond it; show it as a limit, e.g. ">= 32.8 m", not as a reading)."""
    return field_spec(type(pkt), name).saturated(getattr(pkt, name))


_COLUMN_PACKETS = (Attitude, Motion, Height, Status, Compact)


def column_scale(name: str) -> tuple[float, str]:
    """Scale and unit for a telemetry field or a flash-log column of that name (the log names its columns after
    the telemetry fields, in the same board units; its time column is LOG_TIME_COLUMN, µs)."""
    if name == LOG_TIME_COLUMN:
        return 1e-6, "s"
    for cls in _COLUMN_PACKETS:
        for fs in SPEC_OF[cls].fields:
            if fs.name == name:
                return fs.scale, fs.scaled_unit
    raise KeyError(f"no telemetry field named {name!r}")
