"""Facts both ends of the link share: the protocol version and frame sizes, the enumerations carried in
packets (modes, ops, NAK reasons and their text, events, flags, roles), the NUS UUIDs, the stick and battery
guards and the sensor scales. Standard library only.
"""

from __future__ import annotations

from enum import IntEnum, IntFlag, unique

SCHEME_DELTA8 = 1  # the report's: one scaled signed byte per variable, against the reconstruction
SCHEME_RICE = 2  # ours: prediction and an adaptive Rice code, the same error bound, no overload
SCHEME_NAMES = {SCHEME_DELTA8: "delta8", SCHEME_RICE: "rice"}
LOG_TIME_COLUMN = "t_us"  # the board time of each record, µs; the other columns are named after telemetry fields

PROTOCOL_VERSION = 5  # 5: the Text packet (the board's own debug lines, qb_log), Op.MOTOR_TEST, event MOTOR_TEST,
#   flag MOTOR_TEST; 4: link.telemetry_hz in 0.01 Hz (was whole Hz), the failsafe's and the report preset's
#   parameters (ids 20-23), NAK ONLY_SHORTER_IN_FLIGHT, events LINK_LOST, LINK_REGAINED, SIM_LAG; 3: the parameter
#   table (SET_PARAM id 8 + value 24 bits, PARAM_GET, PARAM_LIST, ParamValue, PARAM_CHANGED), Compact2 (the flight
#   screen's figures over BLE); 2: Height in cm and cm/s (was mm: saturated at 32.77 m), crash flag, event, command
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
    TRIM_LIFT = 2  # arg: steps, +1 up / -1 down (finer near hover: lift_trim_after)
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
    MOTOR_TEST = 22  # arg = motor_test_arg(motors, level): spin the motors in the mask (bit 0 ae1 .. bit 3 ae4) at
    #   level (0..MOTOR_TEST_MAX_LEVEL) for at most MOTOR_TEST_MAX_MS; level 0 stops. SAFE only, lift at zero, props off


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
    ONLY_SHORTER_IN_FLIGHT = 19  # a link timeout made longer outside SAFE (it may only shrink in flight)
    PARAM_RULE = 20  # a set that breaks a rule between parameters (PARAM_RULES; the Ack's value: the rule's index)


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
    Nak.ONLY_SHORTER_IN_FLIGHT: "in flight a link timeout can only be made shorter: land (SAFE) to lengthen it",
    Nak.PARAM_RULE: "breaks a rule between parameters (docs/parameters.md)",
}


def nak_text(nak: int) -> str:
    """What a refusal means, for the pilot (a reason newer than this table: its number)."""
    try:
        return NAK_TEXT[Nak(nak)]
    except (ValueError, KeyError):
        return getattr(nak, "name", f"NAK {int(nak)}")


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
    # The two-stage link failsafe (docs/modes.md): stage 1 after link.timeout_ms of silence in a flight mode holds
    # level with the lift it had; the link back within link.failsafe_ms gives control back; else stage 2, PANIC
    # (LINK_TIMEOUT). With link.failsafe_ms 0 (the report's board) LINK_TIMEOUT and PANIC come at once.
    LINK_LOST = 17  # arg: ms since the last frame (stage 1 begins: holding level, PANIC after link.failsafe_ms)
    LINK_REGAINED = 18  # arg: ms stage 1 lasted (a frame came back in time: control is the pilot's again)
    SIM_LAG = 19  # arg: ms the simulated board runs behind real time (fcb-sim only: its process was starved)
    MOTOR_TEST = 20  # arg: MotorTestEnd, why a motor test stopped (the motors are off again)
    CONTACT = 21  # arg: (ContactKind << 16) | the estimated speed into it in mm/s: a hard stop the board felt
    HEADING_DRIFT = 22  # arg: 0.01° of heading drift taken out since calibration (no compass: the heading is relative)
    HEIGHT_SETPOINT = 23  # arg: HEIGHT's set point in mm after a lift key moved it (the lift trim is left alone)


@unique
class MotorTestEnd(IntEnum):
    """Why the board stopped a motor test (``Event.arg`` of ``EventCode.MOTOR_TEST``)."""

    TIME_UP = 1  # MOTOR_TEST_MAX_MS passed: the board's own limit
    STOPPED = 2  # a MOTOR_TEST command with level 0
    LINK_SILENT = 3  # nothing from the terminal for MOTOR_TEST_LINK_MS
    MODE = 4  # a mode change (any: SAFE again, PANIC, ...)
    LIFT = 5  # the lift (joystick plus trim) left zero


@unique
class ContactKind(IntEnum):
    """What stopped the craft (``EventCode.CONTACT``), as the accelerometer tells it: a jolt against the motion."""

    GROUND = 1  # a stop going down: a landing
    CEILING = 2  # a stop going up
    WALL = 3  # a sideways jolt


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
    MOTOR_TEST = 1 << 12  # a motor test runs (SAFE, Op.MOTOR_TEST): the motors turn on the bench
    HEIGHT_UNSURE = 1 << 13  # the height estimate is unsure (after a hard stop, until the barometer confirms it)


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

# FLIGHT_MODES, the modes the flight core drives the motors in, is a column of the mode table (modes.py).

# Stick guards for leaving SAFE, in stick units (Joystick and Status trims): the board refuses with a Nak and
# the terminal, which checks first to name the fix at once, uses the same numbers.
STICK_MAX = 32767  # full deflection (lift: full throttle)
LIFT_ZERO = 500  # joystick lift plus lift trim at most this (1.5 %) counts as zero lift
STICK_NEUTRAL = 1000  # |joystick + trim| at most this on roll, pitch and yaw (3 %) counts as neutral

# The lift keys step finer near hover (issue 22): one press of a/z moves the lift trim by trim.lift_step (1 %), but
# by a LIFT_FINE_DIVISOR-th of it while the lift (joystick + trim) is in [LIFT_FINE_FROM, LIFT_FINE_TO): about
# 40-60 %, where the craft hovers (about 50 %). At hover 1 % of lift is 4 % of the thrust, 0.4 m/s² per press;
# a quarter is 0.1 m/s². bench.keyboard has the figures; lift_trim_after is the rule both ends apply.
LIFT_FINE_FROM = 13107  # 40 %
LIFT_FINE_TO = 19661  # 60 %
LIFT_FINE_DIVISOR = 4
# In HEIGHT the lift keys move the height set point (issue 34: a silent lift trim there changed nothing the pilot
# saw, then dropped the craft on leaving HEIGHT): HEIGHT_KEY_STEP_MM per press, kept within
# HEIGHT_SETPOINT_MIN_MM..HEIGHT_SETPOINT_MAX_MM (the lab's room is 3 m high); the lift trim stays as it was.
HEIGHT_KEY_STEP_MM = 100
HEIGHT_SETPOINT_MIN_MM = 200
HEIGHT_SETPOINT_MAX_MM = 2500


def lift_trim_after(trim: int, steps: int, lift_step: int, joystick_lift: int = 0) -> int:
    """The lift trim after ``steps`` presses of a (positive) or z (negative), each moving the lift (``joystick_lift``
    plus the trim) by ``lift_step``, or by ``max(1, lift_step // LIFT_FINE_DIVISOR)`` while the press starts and
    ends within the fine band; the trim stays in 0..STICK_MAX. Closed form per stretch: a merged burst or Z's
    -32767 costs a few loops, not one per press."""
    fine, coarse = max(1, lift_step // LIFT_FINE_DIVISOR), max(1, lift_step)
    lo, hi = LIFT_FINE_FROM, LIFT_FINE_TO
    level = joystick_lift + trim
    floor_, top = joystick_lift, joystick_lift + STICK_MAX  # the trim's clip, as a lift
    n = abs(steps)
    while n > 0 and (floor_ < level if steps < 0 else level < top):
        if steps > 0:
            if lo <= level and level + fine <= hi:
                k = min(n, (hi - level) // fine)  # fine presses that stay in the band
                level += k * fine
            elif level < lo:
                k = min(n, max(1, -(-(lo - level) // coarse)))  # coarse presses up to (or just into) the band
                level += k * coarse
            else:
                k = min(n, max(1, -(-(top - level) // coarse)))
                level += k * coarse
        else:
            if level <= hi and level - fine >= lo:
                k = min(n, (level - lo) // fine)
                level -= k * fine
            elif level > hi:
                k = min(n, max(1, -(-(level - hi) // coarse)))
                level -= k * coarse
            else:
                k = min(n, max(1, -(-(level - floor_) // coarse)))
                level -= k * coarse
        n -= k
    return max(0, min(STICK_MAX, level - joystick_lift))


# The motor test (Op.MOTOR_TEST): a bench check of wiring, order and direction, props off. The level is capped under
# hover (about 400), so even all four motors with props on cannot lift the craft; the board stops by itself after
# MOTOR_TEST_MAX_MS, and after MOTOR_TEST_LINK_MS without a frame from the terminal (which answers 10 heartbeats a
# second, so five missed answers).
MOTOR_TEST_MAX_LEVEL = 300
MOTOR_TEST_MAX_MS = 3000
MOTOR_TEST_LINK_MS = 500
MOTOR_COUNT = 4


def motor_test_arg(motors: int, level: int) -> int:
    """Op.MOTOR_TEST's arg: ``motors`` a mask (bit 0 ae1 front .. bit 3 ae4 left), ``level`` 0..1000 (the board
    refuses above MOTOR_TEST_MAX_LEVEL)."""
    return ((motors & 0xFF) << 16) | (level & 0xFFFF)


def motor_test_split(arg: int) -> tuple[int, int]:
    """(motors mask, level) from Op.MOTOR_TEST's arg."""
    return (arg >> 16) & 0xFF, arg & 0xFFFF


# The UART's speed (8N1): the board's wire and the terminal's default.
BAUD_RATE = 115_200

# Battery thresholds in the Height/Compact ``battery`` unit (10 mV), for a 3S LiPo.
BATTERY_LOW = 1050  # 10.5 V: under this while flying (for LOW_BATTERY_HOLD_S) the board PANICs
BATTERY_WARN = 1110  # 11.1 V: nominal; time to land
BATTERY_FULL = 1260  # 12.6 V: fully charged
LOW_BATTERY_HOLD_S = 0.2  # the voltage must stay low this long (sag under a motor step is not a flat battery)

# The board's tasks, in the order of the Profile packet's ``task`` ids (the board's task table, the terminal's
# profile screen and the C board's enum qb_task all read this).
BOARD_TASKS = ("parse", "sensor", "control", "baro", "telemetry", "heartbeat", "logging")

# Raw MPU6050 scales at the board's full-scale settings, as the Attitude and Motion fields carry them.
GYRO_LSB_PER_DPS = 16.4  # FS_SEL = 3, +-2000 °/s
ACC_LSB_PER_G = 16384  # AFS_SEL = 0, +-2 g
