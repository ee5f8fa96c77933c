"""The one protocol codec shared by the terminal and the board: packets, framing, CRC, streaming decoder, and
every fact both ends need. Pure and sans-IO: standard library only, bytes in and packets out.

A frame on the wire is ``COBS(type | seq | body | crc16) 0x00``:

- ``type``  one byte, the packet id from the table below; it fixes the body's length and layout;
- ``seq``   one byte, a per-direction counter (mod 256) that the receiver uses to count lost frames;
- ``body``  the packet's fields, little-endian, at most 14 bytes;
- ``crc16`` CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over type, seq and body, big-endian;
- COBS (consistent overhead byte stuffing) removes every 0x00 from the frame, so 0x00 only ever marks a frame's end.

A receiver that loses sync (a corrupted, lost or inserted byte) is back in step at the next 0x00: a corrupted byte
costs at most the two frames on either side of it, and the CRC keeps a damaged frame from being misread.
Every frame is at most 20 bytes, one BLE notification.

Each field in the packet table carries its wire format, its unit, and the ``scale`` that turns a raw value into
the unit the terminal shows (``scaled_unit``): convert with ``scaled(pkt, name)`` or ``field_scale(cls, name)``,
never with a retyped factor. ``field_limits`` and ``saturated`` tell a value pinned at the edge of its encoding
from a true one.

The shared facts (one home each; a test fails on a copy elsewhere): ``Role``, the Nordic UART Service UUIDs and
``BOARD_NAME_PREFIX``, ``FLIGHT_MODES``, the stick guards ``LIFT_ZERO`` and ``STICK_NEUTRAL``, the battery
thresholds, the board's parameter table (``Param``, ``PARAMS``: name, type, unit, range, default, in flight or not;
``PRESETS``; ``param_arg``/``param_split``; docs/parameters.md is generated from it). The flash-log payload codec
lives in ``term.logformat`` (re-exported here for older imports).
"""

from __future__ import annotations

import binascii
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from enum import IntEnum, IntFlag, unique
from typing import Annotated, Any, NamedTuple, get_type_hints

# The flash-log facts the parameter table and the log columns need; the payload codec is term.logformat.
SCHEME_DELTA8 = 1  # the report's: one scaled signed byte per variable, against the reconstruction
SCHEME_RICE = 2  # ours: prediction and an adaptive Rice code, the same error bound, no overload
SCHEME_NAMES = {SCHEME_DELTA8: "delta8", SCHEME_RICE: "rice"}
LOG_TIME_COLUMN = "t_us"  # the board time of each record, µs; the other columns are named after telemetry fields

PROTOCOL_VERSION = 3  # 3: the parameter table (SET_PARAM id 8 + value 24 bits, PARAM_GET, PARAM_LIST, ParamValue,
#   PARAM_CHANGED), Compact2 (the flight screen's figures over BLE); 2: Height in cm and cm/s (was mm: saturated at
#   32.77 m), crash flag, event and command
MAX_FRAME = 20  # bytes on the wire, delimiter included: one BLE notification
MAX_BODY = MAX_FRAME - 6  # type, seq, crc16 (2), COBS overhead (1), delimiter (1)
DELIMITER = b"\x00"
CRC_INIT = 0xFFFF

PC_TO_BOARD = "pc→board"
BOARD_TO_PC = "board→pc"
BOTH = "both"


# --- enumerations carried in packets ------------------------------------------------------------------------


@unique
class Mode(IntEnum):
    """The board's modes, numbered as the lab's keys select them."""

    SAFE = 0
    PANIC = 1
    MANUAL = 2
    CALIBRATION = 3
    YAW = 4
    FULL = 5
    RAW = 6
    HEIGHT = 7
    WIRELESS = 8


@unique
class Op(IntEnum):
    """Keyboard command operations (``Command.op``); ``arg`` meaning is given per op."""

    MODE = 1  # arg: the requested Mode
    TRIM_LIFT = 2  # arg: steps, +1 up / -1 down
    TRIM_ROLL = 3  # arg: steps
    TRIM_PITCH = 4  # arg: steps
    TRIM_YAW = 5  # arg: steps
    GAIN_YAW_P = 6  # arg: steps
    GAIN_P1 = 7  # arg: steps (roll/pitch angle gain)
    GAIN_P2 = 8  # arg: steps (roll/pitch rate gain)
    GAIN_HEIGHT_P = 9  # arg: steps
    GAIN_HEIGHT_D = 10  # arg: steps
    LOG_START = 11
    LOG_STOP = 12
    LOG_RESET = 13  # SAFE only
    LOG_DOWNLOAD = 14  # arg: first chunk to send (0, or where an interrupted download resumes); SAFE only
    LOG_STATUS = 15  # asks for a LogStatus packet
    PROFILE = 16  # asks for the Profile packets
    WIRELESS = 17  # arg: 1 hand over to BLE; 0 hand back to the cable
    SET_PARAM = 18  # arg = param_arg(Param, raw value); Ack.value: the raw value now in force; see PARAMS
    ACK_CRASH = 19  # the pilot has seen the crash (SAFE only); until then the board will not leave SAFE
    PARAM_GET = 20  # arg: a Param id; Ack.value: its raw value
    PARAM_LIST = 21  # Ack.value: how many parameters; then one ParamValue packet each


# Ops whose arg counts key presses: two of them in a row are the same as one with the args added (the link merges
# presses the board has not been sent yet, so a burst of keys is neither refused nor sent one round trip each).
STEP_OPS = frozenset({Op.TRIM_LIFT, Op.TRIM_ROLL, Op.TRIM_PITCH, Op.TRIM_YAW, Op.GAIN_YAW_P, Op.GAIN_P1, Op.GAIN_P2,
                      Op.GAIN_HEIGHT_P, Op.GAIN_HEIGHT_D})


@unique
class Nak(IntEnum):
    """Reasons a command is refused (``Ack.status``); 0 means accepted."""

    OK = 0
    LIFT_NOT_ZERO = 1
    STICKS_NOT_NEUTRAL = 2
    NOT_CALIBRATED = 3
    NOT_IN_SAFE = 4
    INVALID_TRANSITION = 5
    UNKNOWN_COMMAND = 6
    BAD_ARGUMENT = 7
    LOG_FULL = 8
    LOG_EMPTY = 9
    LOG_BUSY = 10
    BATTERY_LOW = 11
    NO_BLE_CONNECTION = 12
    BUSY = 13
    PANIC_ACTIVE = 14
    NOT_IMPLEMENTED = 15  # a board without the feature (the C reference board, firmware/examples/host_board.c)
    CRASHED = 16
    OUT_OF_RANGE = 17
    UNKNOWN_PARAM = 18


NAK_TEXT = {
    Nak.OK: "accepted",
    Nak.LIFT_NOT_ZERO: "lift not at zero",
    Nak.STICKS_NOT_NEUTRAL: "sticks not neutral",
    Nak.NOT_CALIBRATED: "not calibrated: run CALIBRATION (3) first",
    Nak.NOT_IN_SAFE: "only allowed in SAFE",
    Nak.INVALID_TRANSITION: "not allowed from the current mode",
    Nak.UNKNOWN_COMMAND: "unknown command",
    Nak.BAD_ARGUMENT: "bad argument",
    Nak.LOG_FULL: "log flash is full",
    Nak.LOG_EMPTY: "log is empty",
    Nak.LOG_BUSY: "log is busy",
    Nak.BATTERY_LOW: "battery low",
    Nak.NO_BLE_CONNECTION: "no BLE connection: connect the phone first",
    Nak.BUSY: "board busy",
    Nak.PANIC_ACTIVE: "PANIC in progress",
    Nak.NOT_IMPLEMENTED: "not implemented on this board",
    Nak.CRASHED: "crashed: check the craft, then acknowledge the crash",
    Nak.OUT_OF_RANGE: "value out of range",
    Nak.UNKNOWN_PARAM: "no such parameter on this board",
}


@unique
class EventCode(IntEnum):
    """Board events (``Event.code``), each with an ``arg`` whose meaning is given here."""

    BOOT = 1  # arg: protocol version
    MODE_CHANGED = 2  # arg: (old << 8) | new
    REFUSED = 3  # arg: (Nak reason << 8) | requested mode
    LOW_BATTERY = 4  # arg: battery in 10 mV
    LINK_TIMEOUT = 5  # arg: ms since the last byte
    TILT_LIMIT = 6  # arg: tilt in centidegrees
    PANIC_DONE = 7  # arg: 0
    CALIBRATION_DONE = 8  # arg: samples averaged
    LOG_FULL = 9  # arg: bytes used
    LOG_DONE = 10  # arg: chunks sent
    WIRELESS_STATE = 11  # arg: WirelessState
    DEADLINE_MISS = 12  # arg: period in µs
    SENSOR_FAULT = 13  # arg: sensor id
    OVERFLOW = 14  # arg: bytes dropped from a full receive queue
    CRASH = 15  # arg: impact speed in mm/s (the craft hit the ground or the ceiling); the motors are off
    PARAM_CHANGED = 16  # arg: param_arg(Param, raw value now in force): by SET_PARAM, a gain key or a trim step


@unique
class WirelessState(IntEnum):
    DISCONNECTED = 0
    STARTING = 1
    STARTED = 2


@unique
class LogState(IntEnum):
    IDLE = 0
    RECORDING = 1
    FULL = 2
    DOWNLOADING = 3


@unique
class Flag(IntFlag):
    """Board status bits (``Status.flags``)."""

    CALIBRATED = 1 << 0
    ARMED = 1 << 1  # motors may turn
    LOGGING = 1 << 2
    BLE_CONNECTED = 1 << 3
    WIRELESS_ACTIVE = 1 << 4  # the board reads its commands from BLE
    LOW_BATTERY = 1 << 5
    LINK_TIMEOUT = 1 << 6
    RAW_SENSORS = 1 << 7  # attitude from the on-board filter, not the DMP
    FIXED_POINT = 1 << 8
    PRIORITY_SCHEDULER = 1 << 9
    HEIGHT_HOLD = 1 << 10
    CRASHED = 1 << 11  # a crash not yet acknowledged (Op.ACK_CRASH): the board stays in SAFE


@unique
class Button(IntFlag):
    """Joystick button bits (``Joystick.buttons``)."""

    FIRE = 1 << 0  # PANIC


@unique
class Role(IntEnum):
    """Who sent a ``Hello``."""

    TERMINAL = 0
    BOARD = 1


# --- facts both ends need -----------------------------------------------------------------------------------

# The Nordic UART Service (Nordic's UUIDs): the phone or terminal writes RX, the board notifies TX. The board
# advertises as BOARD_NAME_PREFIX followed by a space and its board id.
NUS_SERVICE = "6e400001-b5a3-f393-e0a9-e50e24dcca9e"
NUS_RX = "6e400002-b5a3-f393-e0a9-e50e24dcca9e"  # write / write without response: terminal to board
NUS_TX = "6e400003-b5a3-f393-e0a9-e50e24dcca9e"  # notify only: board to terminal
BOARD_NAME_PREFIX = "Quadrupel"

# Modes in which the motors may turn under the flight core (PANIC drives them too, from its own profile).
FLIGHT_MODES = frozenset({Mode.MANUAL, Mode.YAW, Mode.FULL, Mode.RAW, Mode.HEIGHT})

# Stick guards for leaving SAFE, in stick units (Joystick and Status trims): the board refuses with a Nak and
# the terminal, which checks first to name the fix at once, uses the same numbers.
STICK_MAX = 32767
LIFT_ZERO = 500  # joystick lift plus lift trim at most this (1.5 %) counts as zero lift
STICK_NEUTRAL = 1000  # |joystick + trim| at most this on roll, pitch and yaw (3 %) counts as neutral

# Battery thresholds in the Height/Compact ``battery`` unit (10 mV), for a 3S LiPo.
BATTERY_LOW = 1050  # 10.5 V: under this while flying (for LOW_BATTERY_HOLD_S) the board PANICs
BATTERY_WARN = 1110  # 11.1 V: nominal; time to land
BATTERY_FULL = 1260  # 12.6 V: fully charged
LOW_BATTERY_HOLD_S = 0.2  # the voltage must stay low this long (sag under a motor step is not a flat battery)

# Raw MPU6050 scales at the board's full-scale settings, as the Attitude and Motion fields carry them.
GYRO_LSB_PER_DPS = 16.4  # FS_SEL = 3, +-2000 °/s
ACC_LSB_PER_G = 16384  # AFS_SEL = 0, +-2 g


@unique
class Param(IntEnum):
    """Board parameter ids (1..127), one per row of ``PARAMS``: ``SET_PARAM`` (``param_arg``), ``PARAM_GET``,
    ``PARAM_LIST``, ``EventCode.PARAM_CHANGED`` and the ``ParamValue`` packet name them by this number."""

    LINK_TIMEOUT_MS = 1
    SCHEDULER = 2
    TELEMETRY_HZ = 3
    SENSOR_PATH = 4
    LOG_SCHEME = 5
    YAW_P = 6
    P1 = 7
    P2 = 8
    HEIGHT_P = 9
    HEIGHT_D = 10
    HEIGHT_I = 11
    ATTITUDE_FILTER = 12
    K_GYRO = 13
    FIXED_POINT = 14
    HEIGHT_ESTIMATOR = 15
    STICK_REACTION = 16
    QUEUE_RULE = 17
    TRIM_STEP = 18
    LIFT_STEP = 19


SCHEDULERS = ("round-robin", "priority")  # Param.SCHEDULER value -> the board's scheduler
SENSOR_PATHS = ("auto", "dmp", "raw")  # Param.SENSOR_PATH value -> the sensor path ("auto" follows the mode)
ATTITUDE_FILTERS = ("complementary", "kalman", "kalman-cov", "qgate", "ikf")  # the RAW path's filter, by name
HEIGHT_ESTIMATORS = ("complementary", "kalman")  # the height estimator: the report's Figure 10, or ours
QUEUE_RULES = ("bounded", "discard-20")  # the receive queue: drop what does not fit; the report's rule
QUEUE_DISCARD_FRAMES = 20  # "discard-20": the whole receive queue goes when this many frames wait in it
PARAM_RAW_BITS = 24  # SET_PARAM and PARAM_CHANGED carry a signed 24-bit raw value under an 8-bit id
_RAW_MAX = (1 << (PARAM_RAW_BITS - 1)) - 1
_KINDS = ("int", "float", "bool", "enum")


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """One board parameter. ``value`` is what a pilot reads and types (a number in ``unit``, a name for an enum, a
    bool); ``raw`` the int32 the wire carries: ``round(value / scale)`` for numbers, the choice's number for an enum
    (``choices[raw - base]``), 0 or 1 for a bool. ``lo``..``hi`` (inclusive, in ``unit``) is what the board accepts;
    ``in_flight`` False: refused (Nak.NOT_IN_SAFE) outside SAFE. ``step``: one press of its key (gains, trims)."""

    param: Param
    name: str  # "group.name": ctrl (gains), est (estimators), sched, link, log, trim
    kind: str  # "int", "float", "bool", "enum"
    unit: str
    default: float | str | bool
    doc: str
    lo: float = 0
    hi: float = 0
    scale: float = 1.0
    choices: tuple[str, ...] = ()
    base: int = 0  # the raw number of the first choice
    in_flight: bool = True
    step: float = 0.0

    @property
    def safe_only(self) -> bool:
        return not self.in_flight

    @property
    def raw_range(self) -> tuple[int, int]:
        if self.kind == "enum":
            return self.base, self.base + len(self.choices) - 1
        if self.kind == "bool":
            return 0, 1
        return round(self.lo / self.scale), round(self.hi / self.scale)

    def accepts(self, raw: int) -> bool:
        lo, hi = self.raw_range
        return lo <= raw <= hi

    def to_raw(self, value: float | str | bool) -> int:
        """The wire's int for ``value`` (a choice's name for an enum). ValueError (one line) if it is not one."""
        if self.kind == "enum":
            if value not in self.choices:
                raise ValueError(f"{self.name}: {value!r} is not one of {', '.join(self.choices)}")
            return self.base + self.choices.index(str(value))
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise ValueError(f"{self.name}: give true or false, got {value!r}")
            return int(value)
        bad = isinstance(value, bool) or not isinstance(value, int | float)
        if bad or value != value or abs(value) == float("inf"):
            raise ValueError(f"{self.name}: give a number, got {value!r}")
        if self.kind == "int" and value != int(value):
            raise ValueError(f"{self.name}: give a whole number, got {value!r}")
        return round(value / self.scale)

    def from_raw(self, raw: int) -> float | str | bool:
        """The value for the wire's ``raw`` (an enum's raw out of its range is shown as its number)."""
        if self.kind == "enum":
            i = raw - self.base
            return self.choices[i] if 0 <= i < len(self.choices) else str(raw)
        if self.kind == "bool":
            return bool(raw)
        if self.kind == "int":
            return int(raw * self.scale)
        return round(raw * self.scale, _decimals(self.scale))  # 99900 * 1e-5 is 0.999, not 0.9990000000000001

    def text(self, value: float | str | bool) -> str:
        """``value`` as the pilot reads it (no unit)."""
        if self.kind == "bool":
            return "true" if value else "false"
        if self.kind == "float" and isinstance(value, int | float):
            return f"{value:.{_decimals(self.scale)}f}".rstrip("0").rstrip(".") if value == value else "nan"
        return str(value)

    def limits_text(self) -> str:
        if self.kind == "enum":
            return ", ".join(self.choices)
        if self.kind == "bool":
            return "true, false"
        return f"{self.text(self.lo)}..{self.text(self.hi)}"


def _decimals(scale: float) -> int:
    d = 0
    while d < 9 and abs(round(scale * 10**d) - scale * 10**d) > 1e-9:
        d += 1
    return d


def _p(param: Param, name: str, kind: str, unit: str, default: float | str | bool, doc: str,
       **kw: Any) -> ParamSpec:
    return ParamSpec(param, name, kind, unit, default, doc, **kw)


# The one parameter table: the board's defaults come from here, the terminal's screen and files, docs/parameters.md.
PARAMS: dict[Param, ParamSpec] = {p.param: p for p in (
    _p(Param.YAW_P, "ctrl.yaw_p", "float", "ae²/LSB", 800.0, "yaw-rate P (Table 1: magnitude of -800)",
       lo=0, hi=5000, scale=0.01, step=50.0),
    _p(Param.P1, "ctrl.p1", "float", "LSB/LSB", 0.4, "roll/pitch angle P1: rate set point per angle error "
       "(Table 1: 0.4)", lo=0, hi=10, scale=0.0001, step=0.05),
    _p(Param.P2, "ctrl.p2", "float", "ae²/LSB", 111.0, "roll/pitch rate P2 (Table 1: magnitude of 111 and -111)",
       lo=0, hi=1000, scale=0.01, step=5.0),
    _p(Param.HEIGHT_P, "ctrl.height_p", "float", "ae²/mm", 400.0, "height P around the set point (HEIGHT)",
       lo=0, hi=5000, scale=0.1, step=10.0),
    _p(Param.HEIGHT_D, "ctrl.height_d", "float", "ae²/(mm/s)", 400.0, "height D on the vertical speed (HEIGHT)",
       lo=0, hi=5000, scale=0.1, step=10.0),
    _p(Param.HEIGHT_I, "ctrl.height_i", "float", "ae²/(mm·s)", 100.0, "height I: takes out the battery's sag "
       "(0: the report's PD)", lo=0, hi=1000, scale=0.1),
    _p(Param.ATTITUDE_FILTER, "est.attitude", "enum", "", "ikf", "RAW path attitude filter: complementary (report "
       "eq. 1, K from est.k_gyro), kalman and kalman-cov (Table 2), qgate, ikf (ours)", choices=ATTITUDE_FILTERS,
       in_flight=False),
    _p(Param.K_GYRO, "est.k_gyro", "float", "", 0.999, "the complementary filter's K_gyro (report: 0.999 flown, "
       "0.9 in Table 2)", lo=0.5, hi=0.99999, scale=0.00001, in_flight=False),
    _p(Param.FIXED_POINT, "est.fixed_point", "bool", "", False, "RAW filter in Q16.16 fixed point (qgate has "
       "none)", in_flight=False),
    _p(Param.HEIGHT_ESTIMATOR, "est.height", "enum", "", "kalman", "height estimator: complementary (the "
       "report's Figure 10) or kalman (robust to the barometer's spikes)", choices=HEIGHT_ESTIMATORS,
       in_flight=False),
    _p(Param.SENSOR_PATH, "est.sensor_path", "enum", "", "auto", "sensor path: auto follows the mode (RAW in "
       "RAW), dmp, raw", choices=SENSOR_PATHS),
    _p(Param.SCHEDULER, "sched.scheduler", "enum", "", "round-robin", "task scheduler: round-robin (the "
       "report's) or priority", choices=SCHEDULERS),
    _p(Param.STICK_REACTION, "sched.stick_reaction", "bool", "", True, "a changed stick moves the motors in the "
       "parse task (false: only the control step, as the report's firmware)", in_flight=False),
    _p(Param.LINK_TIMEOUT_MS, "link.timeout_ms", "int", "ms", 500, "link silence longer than this in a flight "
       "mode means PANIC", lo=50, hi=60000),
    _p(Param.TELEMETRY_HZ, "link.telemetry_hz", "int", "Hz", 50, "Attitude and Motion rate over the UART",
       lo=1, hi=100),
    _p(Param.QUEUE_RULE, "link.queue_rule", "enum", "", "bounded", "the receive queue: bounded (what does not "
       "fit is dropped) or discard-20 (the report's: the whole queue goes at 20 frames)", choices=QUEUE_RULES,
       in_flight=False),
    _p(Param.LOG_SCHEME, "log.scheme", "enum", "", "rice", "flash-log compression; needs an empty log (else "
       "Nak.LOG_BUSY)", choices=tuple(SCHEME_NAMES[k] for k in sorted(SCHEME_NAMES)), base=min(SCHEME_NAMES),
       in_flight=False),
    _p(Param.TRIM_STEP, "trim.step", "int", "stick", 256, "roll, pitch and yaw trim per key press (0.8 %)",
       lo=1, hi=4096),
    _p(Param.LIFT_STEP, "trim.lift_step", "int", "stick", 328, "lift trim per key press (1 %)", lo=1, hi=4096),
)}
PARAM_BY_NAME: dict[str, ParamSpec] = {p.name: p for p in PARAMS.values()}
# The gain keys (u/j, i/k, o/l, t/g, y/h) step these parameters by their ``step``.
GAIN_OPS: dict[int, Param] = {Op.GAIN_YAW_P: Param.YAW_P, Op.GAIN_P1: Param.P1, Op.GAIN_P2: Param.P2,
                              Op.GAIN_HEIGHT_P: Param.HEIGHT_P, Op.GAIN_HEIGHT_D: Param.HEIGHT_D}


def param_arg(param: int, raw: int) -> int:
    """``Command.arg`` for ``Op.SET_PARAM`` (and ``EventCode.PARAM_CHANGED``'s arg): the id (1..127) in the top 8
    bits, the raw value as a signed 24-bit number in the low 24."""
    if not 0 <= int(param) <= 0x7F or not -_RAW_MAX - 1 <= raw <= _RAW_MAX:
        raise ValueError(f"SET_PARAM {param}={raw}: id must be 0..127 and the raw value a signed 24-bit number")
    return (int(param) << PARAM_RAW_BITS) | (raw & ((1 << PARAM_RAW_BITS) - 1))


def param_split(arg: int) -> tuple[int, int]:
    """The (id, raw value) inside a ``SET_PARAM`` arg (the inverse of ``param_arg``)."""
    raw = arg & ((1 << PARAM_RAW_BITS) - 1)
    if raw > _RAW_MAX:
        raw -= 1 << PARAM_RAW_BITS
    return (arg >> PARAM_RAW_BITS) & 0xFF, raw


# Presets: whole sets of values by name (a value per parameter it changes; the rest keep their defaults).
PRESETS: dict[str, dict[Param, float | str | bool]] = {
    "default": {},  # the team's best: every parameter at its default
    "report": {  # the board of the lab report: Table 1's gains, the complementary filter flown (K_gyro 0.999), the
        # Figure 10 height estimator on the gains it was tuned for (PD, no integral), round robin, the report's
        # queue rule, and no stick reaction (only the control step moves the motors)
        Param.YAW_P: 800.0, Param.P1: 0.4, Param.P2: 111.0,
        Param.ATTITUDE_FILTER: "complementary", Param.K_GYRO: 0.999, Param.FIXED_POINT: False,
        Param.HEIGHT_ESTIMATOR: "complementary", Param.HEIGHT_P: 120.0, Param.HEIGHT_D: 320.0, Param.HEIGHT_I: 0.0,
        Param.SCHEDULER: "round-robin", Param.STICK_REACTION: False, Param.QUEUE_RULE: "discard-20",
    },
}


def preset_values(name: str) -> dict[Param, float | str | bool]:
    """Every parameter's value in preset ``name`` (KeyError, naming the presets, for an unknown one)."""
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    return {p: PRESETS[name].get(p, spec.default) for p, spec in PARAMS.items()}


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


LOG_CHUNK_BYTES = 12
TELEMETRY = (Attitude, Motion, Height, Status, Gains)

# Event arguments that are quantities: the scale to the shown unit, per code (the rest are counts or ids).
EVENT_ARG_SCALE: dict[EventCode, tuple[float, str]] = {
    EventCode.LOW_BATTERY: (0.01, "V"),
    EventCode.LINK_TIMEOUT: (1e-3, "s"),
    EventCode.TILT_LIMIT: (0.01, "°"),
    EventCode.DEADLINE_MISS: (1.0, "µs"),
    EventCode.CRASH: (1e-3, "m/s"),
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


# --- framing ------------------------------------------------------------------------------------------------


class ProtocolError(ValueError):
    """Raised by ``encode`` for a packet that cannot be sent (never by the decoder)."""


def cobs_encode(raw: bytes) -> bytes:
    """COBS-encode ``raw`` (shorter than 254 bytes), without the delimiter."""
    return b"".join(bytes((len(block) + 1,)) + block for block in raw.split(b"\x00"))


def cobs_decode(data: bytes) -> bytes | None:
    """Undo ``cobs_encode``; None if ``data`` is not valid COBS."""
    out = bytearray()
    i, n = 0, len(data)
    while i < n:
        code = data[i]
        end = i + code
        if code == 0 or end > n:
            return None
        out += data[i + 1 : end]
        if end < n and code != 0xFF:
            out.append(0)
        i = end
    return bytes(out)


def encode(pkt: Any, seq: int = 0) -> bytes:
    """One whole frame for ``pkt`` with sequence number ``seq``, delimiter included."""
    try:
        spec = SPEC_OF[type(pkt)]
    except KeyError:
        raise ProtocolError(f"not a packet: {pkt!r}") from None
    try:
        body = spec.struct.pack(*pkt)
    except (struct.error, OverflowError) as exc:
        raise ProtocolError(f"{type(pkt).__name__}: {exc}") from None
    raw = bytes((spec.type_id, seq & 0xFF)) + body
    raw += binascii.crc_hqx(raw, CRC_INIT).to_bytes(2, "big")
    return cobs_encode(raw) + DELIMITER


class Encoder:
    """Encodes packets for one direction of a link, owning its sequence number."""

    def __init__(self) -> None:
        self.seq = 0
        self.frames = 0
        self.bytes = 0

    def encode(self, pkt: Any) -> bytes:
        frame = encode(pkt, self.seq)
        self.seq = (self.seq + 1) & 0xFF
        self.frames += 1
        self.bytes += len(frame)
        return frame

    def encode_many(self, pkts: Iterable[Any]) -> bytes:
        return b"".join(self.encode(p) for p in pkts)


@dataclass
class DecoderStats:
    frames_ok: int = 0
    crc_errors: int = 0
    malformed: int = 0  # bad COBS, unknown type, wrong length
    bytes_skipped: int = 0  # bytes discarded outside a good frame
    seq_gaps: int = 0  # frames missing according to the sequence numbers
    bytes_in: int = 0

    @property
    def frames_bad(self) -> int:
        return self.crc_errors + self.malformed


class Decoder:
    """A streaming decoder: ``feed`` any chunking of the byte stream, get the packets in it.

    Never raises on bad input; what it drops is counted in ``stats``.
    """

    # Anything longer than a frame without a delimiter is garbage: keep at most this many pending bytes.
    _MAX_PENDING = MAX_FRAME - 1

    def __init__(self) -> None:
        self.stats = DecoderStats()
        self._pending = b""
        self._discarding = False  # inside an over-long run: drop bytes up to the next delimiter
        self._joined = False  # a delimiter has been seen: what follows starts on a frame boundary
        self._last_seq: int | None = None

    def feed(self, data: bytes) -> list[Any]:
        stats = self.stats
        stats.bytes_in += len(data)
        if self._pending:
            data = self._pending + data
        pieces = data.split(b"\x00")
        tail = pieces.pop()
        out: list[Any] = []
        if pieces:
            if self._discarding:
                stats.bytes_skipped += len(pieces[0]) + 1
                pieces[0] = b""
                self._discarding = False
            if not self._joined:
                # Before the first delimiter a receiver may have started listening mid-frame (a port opened
                # while the board talks): a first piece that is no frame is the tail of one, skipped, not damage.
                self._joined = True
                first, ok = pieces[0], _decode_pieces(pieces[:1], self._last_seq)[0]
                if first and not ok:
                    stats.bytes_skipped += len(first) + 1
                    pieces[0] = b""
            packets, crc_fail, mal, skipped, gaps, last = _decode_pieces(pieces, self._last_seq)
            out = packets
            stats.frames_ok += len(packets)
            stats.crc_errors += crc_fail
            stats.malformed += mal
            stats.bytes_skipped += skipped
            stats.seq_gaps += gaps
            self._last_seq = last
        if len(tail) > self._MAX_PENDING:
            stats.bytes_skipped += len(tail)
            tail = b""
            self._discarding = True
        elif self._discarding:
            stats.bytes_skipped += len(tail)
            tail = b""
        self._pending = tail
        return out

    def reset_sequence(self) -> None:
        """Forget the last sequence number (the peer restarted), so no false gap is counted."""
        self._last_seq = None


def _decode_pieces(
    pieces: list[bytes], last_seq: int | None
) -> tuple[list[Any], int, int, int, int, int | None]:
    """Decode delimiter-separated pieces. The hot path: locals only, COBS undone in place, no copies."""
    packets: list[Any] = []
    crc_fail = malformed = skipped = gaps = 0
    crc = binascii.crc_hqx
    table = PACKETS
    new = tuple.__new__
    for piece in pieces:
        n = len(piece)
        if n == 0:
            continue  # back-to-back delimiters: an idle line or a resync marker
        if n < 5 or n >= MAX_FRAME:
            malformed += 1
            skipped += n + 1
            continue
        # COBS: every code byte after the first stands where the frame had a zero; the chain must end exactly.
        buf = bytearray(piece)
        pos = buf[0]
        while pos < n:
            step = buf[pos]
            buf[pos] = 0
            pos += step
        if pos != n:
            malformed += 1
            skipped += n + 1
            continue
        view = memoryview(buf)[1:]
        if crc(view, CRC_INIT) != 0:  # the CRC over data followed by its own big-endian CRC is zero
            crc_fail += 1
            skipped += n + 1
            continue
        spec = table.get(buf[1])
        if spec is None or n != spec.struct.size + 5:
            malformed += 1
            skipped += n + 1
            continue
        seq = buf[2]
        if last_seq is not None:
            gaps += (seq - last_seq - 1) & 0xFF
        last_seq = seq
        packets.append(new(spec.cls, spec.struct.unpack_from(buf, 3)))
    return packets, crc_fail, malformed, skipped, gaps, last_seq


def decode_frame(frame: bytes) -> Any:
    """Decode exactly one whole frame (delimiter optional); raises ProtocolError if it is not one."""
    dec = Decoder()
    frame = frame if frame.endswith(DELIMITER) else frame + DELIMITER
    pkts = dec.feed(frame)
    if len(pkts) != 1 or dec.stats.frames_bad:
        raise ProtocolError(f"not one valid frame: {frame.hex()}")
    return pkts[0]


def frame_seq(frame: bytes) -> int:
    """The sequence number inside a whole frame."""
    raw = cobs_decode(frame.rstrip(DELIMITER))
    if raw is None or len(raw) < 4:
        raise ProtocolError(f"not a frame: {frame.hex()}")
    return raw[1]


def to_dict(pkt: Any) -> dict[str, Any]:
    """A packet as a JSON-friendly dict with its type name (bytes as hex)."""
    d: dict[str, Any] = {"type": type(pkt).__name__}
    for fs in SPEC_OF[type(pkt)].fields:
        v = getattr(pkt, fs.name)
        d[fs.name] = v.hex() if isinstance(v, bytes) else v
    return d


def from_dict(d: dict[str, Any]) -> Any:
    """Inverse of ``to_dict``."""
    by_name = {spec.cls.__name__: spec for spec in PACKETS.values()}
    spec = by_name[d["type"]]
    kwargs = {}
    for fs in spec.fields:
        v = d[fs.name]
        kwargs[fs.name] = bytes.fromhex(v) if fs.fmt.endswith("s") else v
    return spec.cls(**kwargs)


def spec_markdown() -> str:
    """The packet table as Markdown: the generated part of docs/protocol.md."""
    lines: list[str] = []
    for spec in sorted(PACKETS.values(), key=lambda s: s.type_id):
        name = spec.cls.__name__
        lines.append(f"### `{spec.type_id:#04x}` {name}")
        lines.append("")
        lines.append(f"{spec.doc} Direction: {spec.direction}. Rate: {spec.rate}. "
                     f"Body {spec.body_size} bytes, frame {spec.frame_size} bytes.")
        lines.append("")
        lines.append("| offset | field | type | unit | shown as | meaning |")
        lines.append("|---|---|---|---|---|---|")
        offset = 0
        for fs in spec.fields:
            size = struct.calcsize("<" + fs.fmt)
            shown = f"× {fs.scale:.6g} {fs.scaled_unit}" if fs.scale != 1.0 else ""
            lines.append(f"| {offset} | `{fs.name}` | {_C_TYPE.get(fs.fmt, fs.fmt)} | {fs.unit} | {shown} "
                         f"| {fs.doc} |")
            offset += size
        lines.append("")
    return "\n".join(lines)


_C_TYPE = {
    "B": "uint8",
    "b": "int8",
    "H": "uint16",
    "h": "int16",
    "I": "uint32",
    "i": "int32",
    "e": "float16 (IEEE 754 half)",
    "f": "float32",
    "12s": "uint8[12]",
}


def enum_markdown() -> str:
    """The enumerations as Markdown tables."""
    lines: list[str] = []
    for enum in (Mode, Op, Nak, EventCode, WirelessState, LogState, Flag, Button, Role, Param):
        lines.append(f"### {enum.__name__}")
        lines.append("")
        lines.append("| value | name |" + (" text |" if enum is Nak else ""))
        lines.append("|---|---|" + ("---|" if enum is Nak else ""))
        for member in enum:
            extra = f" {NAK_TEXT[member]} |" if enum is Nak else ""
            lines.append(f"| {int(member)} | {member.name} |{extra}")
        lines.append("")
    return "\n".join(lines)



def params_markdown() -> str:
    """The parameter table as Markdown (docs/protocol.md and docs/parameters.md): one row per parameter, by name."""
    lines = ["| id | name | type | unit | range | default | raw = value / | in flight | meaning |",
             "|---|---|---|---|---|---|---|---|---|"]
    for ps in sorted(PARAMS.values(), key=lambda p: p.name):
        raw = f"{ps.scale:g}" if ps.kind == "float" else ("choice" if ps.kind == "enum" else "")
        if ps.kind == "enum":
            raw = ", ".join(f"{ps.base + i} {c}" for i, c in enumerate(ps.choices))
        lines.append(f"| {int(ps.param)} | `{ps.name}` | {ps.kind} | {ps.unit} | {ps.limits_text()} | "
                     f"{ps.text(ps.default)} | {raw} | {'yes' if ps.in_flight else 'SAFE only'} | {ps.doc} |")
    return "\n".join(lines) + "\n"


def presets_markdown() -> str:
    """The presets as Markdown: each preset's values where they differ from the defaults."""
    names = list(PRESETS)
    changed = sorted({p for values in PRESETS.values() for p in values}, key=lambda p: PARAMS[p].name)
    lines = ["| parameter | " + " | ".join(f"`{n}`" for n in names) + " |", "|---|" + "---|" * len(names)]
    for p in changed:
        spec = PARAMS[p]
        cells = [spec.text(preset_values(n)[p]) for n in names]
        lines.append(f"| `{spec.name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def facts_markdown() -> str:
    """The facts both ends share, as Markdown."""
    modes = ", ".join(m.name for m in sorted(FLIGHT_MODES))
    events = ", ".join(f"{c.name} × {k:g} {u}" for c, (k, u) in EVENT_ARG_SCALE.items())
    rows = [
        ("NUS service", f"`{NUS_SERVICE}`"),
        ("NUS RX (terminal writes; write, write without response)", f"`{NUS_RX}`"),
        ("NUS TX (board notifies; notify only)", f"`{NUS_TX}`"),
        ("board name", f"`{BOARD_NAME_PREFIX} <board id>`"),
        ("flight modes (motors under the flight core)", modes),
        ("stick range", f"±{STICK_MAX} (lift 0..{STICK_MAX})"),
        ("zero lift (leaving SAFE, going back to SAFE)", f"joystick lift + lift trim ≤ {LIFT_ZERO}"),
        ("neutral sticks (leaving SAFE)", f"joystick + trim within ±{STICK_NEUTRAL} on roll, pitch and yaw each"),
        ("battery: PANIC while flying", f"< {BATTERY_LOW} (× 10 mV) for {LOW_BATTERY_HOLD_S:g} s"),
        ("battery: time to land / full", f"< {BATTERY_WARN} / {BATTERY_FULL} (× 10 mV)"),
        ("gyro / accelerometer words", f"{GYRO_LSB_PER_DPS:g} LSB per °/s, {ACC_LSB_PER_G} LSB per g"),
        ("event arguments with a unit", events),
    ]
    lines = ["| fact | value |", "|---|---|", *(f"| {k} | {v} |" for k, v in rows)]
    return "\n".join(lines) + "\n"


# --- the simulator's instructor channel (term --sim only) -----------------------------------------------------
# Beside the board's link, never on it: a real board has no truth and takes no situations. fcb_sim/instructor.py
# serves it (`fcb-sim serve --instructor tcp-server:HOST:PORT`), term/instructor.py reads it; one JSON object per
# line each way. The simulator says {"kind": "hello", "version", "hz"}, then a {"kind": "truth", ...} line with the
# fields below INSTRUCTOR_TRUTH_HZ times a second; term sends {"do": SITUATION, ARG: value, ...} lines and gets
# {"kind": "error", "do", "why"} back for one it cannot carry out.

INSTRUCTOR_VERSION = 1
INSTRUCTOR_TRUTH_HZ = 50.0
INSTRUCTOR_TRUTH: dict[str, str] = {  # field: unit and meaning (earth NED, body FRD: docs/architecture.md)
    "t": "s: the board's clock",
    "n": "m: north of the pad", "e": "m: east of the pad", "h": "m: above the floor",
    "vn": "m/s north", "ve": "m/s east", "vd": "m/s down",
    "phi": "rad: roll", "theta": "rad: pitch", "psi": "rad: heading, 0 north, positive clockwise",
    "p": "rad/s: roll rate", "q": "rad/s: pitch rate", "r": "rad/s: yaw rate",
    "on_ground": "bool: resting on its feet",
    "volts": "V: the pack under load", "soc": "0..1: the pack's state of charge",
    "landings": "touch-downs since the start", "touchdown": "m/s: the last touch-down's downward speed",
    "crashes": "impacts too fast or too tilted since the start",
    "cable": "bool: the cable carries bytes (false while the instructor cuts it)",
    "wind_n": "m/s: the mean wind towards north", "wind_e": "m/s: towards east", "gust": "m/s: gusts' std",
}
INSTRUCTOR_SITUATIONS: dict[str, tuple[str, ...]] = {  # verb: its arguments (all optional)
    "reset": ("soc",),  # on the pad, nose north, fresh pack at soc, still air, no fault (on the floor in SAFE)
    "wind": ("n", "e", "gust"),  # mean wind north and east (m/s) and gusts' std (m/s)
    "battery": ("soc", "drain"),  # set the state of charge; a failing cell drains this much more per second
    "motor": ("motor", "level"),  # motor 1..4 can no longer exceed level (0..1000); level -1 frees it
    "cable": ("cuts",),  # [[after s, for s], ...] from now: the cable carries nothing then; [] clears
    "radio": ("cut",),  # out of range for this many seconds: the BLE connection drops
}
