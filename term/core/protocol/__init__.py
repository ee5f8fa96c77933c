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
``BOARD_NAME_PREFIX``, the mode table (``MODE_TABLE``, ``FLIGHT_MODES``), the stick guards ``LIFT_ZERO`` and
``STICK_NEUTRAL``, the lift keys' fine band near hover (``LIFT_FINE_FROM``, ``LIFT_FINE_TO``, ``LIFT_FINE_DIVISOR``,
``lift_trim_after``), the battery thresholds, the board's parameter table (``Param``, ``PARAMS``: name, type, unit,
range, default, in flight or not; ``PRESETS``; ``param_arg``/``param_split``; docs/parameters.md is generated from it).
The flash-log payload codec lives in ``term.core.logformat``.

The package's modules, each importable alone: ``facts`` (the version, frame sizes, enumerations and shared facts),
``modes`` (the mode table: keys, labels, colours, the phone's buttons, FLIGHT_MODES), ``params`` (the parameter table
and the presets), ``packets`` (the packet table, the packet classes and their scales), ``framing`` (COBS, CRC, the
encoder and the streaming decoder) and ``instructor`` (the simulator's instructor vocabulary). Every public name is
also here, so ``from term.core.protocol import Mode`` reads as the one protocol it is. The tables' Markdown is written
by docs/protocol_tables.py.
"""

from __future__ import annotations

from term.core.protocol.facts import (  # noqa: F401
    ACC_LSB_PER_G,
    BATTERY_FULL,
    BATTERY_LOW,
    BATTERY_WARN,
    BAUD_RATE,
    BOARD_NAME_PREFIX,
    BOARD_TASKS,
    BOARD_TO_PC,
    BOTH,
    CRC_INIT,
    DELIMITER,
    GYRO_LSB_PER_DPS,
    HEIGHT_KEY_STEP_MM,
    HEIGHT_SETPOINT_MAX_MM,
    HEIGHT_SETPOINT_MIN_MM,
    LIFT_FINE_DIVISOR,
    LIFT_FINE_FROM,
    LIFT_FINE_TO,
    LIFT_ZERO,
    LOG_TIME_COLUMN,
    LOW_BATTERY_HOLD_S,
    MAX_BODY,
    MAX_FRAME,
    MOTOR_COUNT,
    MOTOR_TEST_LINK_MS,
    MOTOR_TEST_MAX_LEVEL,
    MOTOR_TEST_MAX_MS,
    NAK_TEXT,
    NUS_RX,
    NUS_SERVICE,
    NUS_TX,
    PC_TO_BOARD,
    PROTOCOL_VERSION,
    SCHEME_DELTA8,
    SCHEME_NAMES,
    SCHEME_RICE,
    STEP_OPS,
    STICK_MAX,
    STICK_NEUTRAL,
    Button,
    ContactKind,
    EventCode,
    Flag,
    LogState,
    Mode,
    MotorTestEnd,
    Nak,
    Op,
    Role,
    WirelessState,
    lift_trim_after,
    motor_test_arg,
    motor_test_split,
    nak_text,
)
from term.core.protocol.framing import (  # noqa: F401
    Decoder,
    DecoderStats,
    Encoder,
    ProtocolError,
    cobs_decode,
    cobs_encode,
    decode_frame,
    encode,
    frame_seq,
    from_dict,
    to_dict,
)
from term.core.protocol.instructor import (  # noqa: F401
    INSTRUCTOR_AUTH,
    INSTRUCTOR_MAX_CUT_S,
    INSTRUCTOR_MAX_OUTAGE_S,
    INSTRUCTOR_SITUATIONS,
    INSTRUCTOR_TOKEN_SEP,
    INSTRUCTOR_TRUTH,
    INSTRUCTOR_TRUTH_HZ,
    INSTRUCTOR_VERSION,
    ROOM_CEILING_M,
    ROOM_HALF_M,
    SIM_SCENARIOS,
    situation_problem,
)
from term.core.protocol.modes import FLIGHT_MODES, MODE_TABLE, ModeSpec  # noqa: F401
from term.core.protocol.packets import (  # noqa: F401
    EVENT_ARG_SCALE,
    LEVEL_DEBUG,
    LEVEL_ERROR,
    LEVEL_FATAL,
    LEVEL_INFO,
    LEVEL_WARNING,
    LOG_CHUNK_BYTES,
    PACKETS,
    SPEC_OF,
    TELEMETRY,
    TEXT_BYTES,
    TEXT_LEVEL_MASK,
    TEXT_MORE,
    Ack,
    Attitude,
    Command,
    Compact,
    Compact2,
    Event,
    F,
    FieldSpec,
    Gains,
    Heartbeat,
    HeartbeatAck,
    Height,
    Hello,
    Joystick,
    LogChunk,
    LogStatus,
    Motion,
    PacketSpec,
    ParamValue,
    Profile,
    Status,
    Text,
    column_scale,
    field_limits,
    field_scale,
    field_spec,
    field_unit,
    packet,
    saturated,
    scaled,
    text_packets,
)
from term.core.protocol.params import (  # noqa: F401
    ATTITUDE_FILTERS,
    GAIN_OPS,
    HEARTBEAT_S,
    HEIGHT_ESTIMATORS,
    LINK_TIMEOUT_RANGE_S,
    LINK_TIMEOUT_S,
    PARAM_BY_NAME,
    PARAM_RAW_BITS,
    PARAM_RULES,
    PARAMS,
    PRESETS,
    QUEUE_DISCARD_FRAMES,
    QUEUE_RULES,
    REPORT_PANIC_COUNTDOWN_MS,
    SCHEDULERS,
    SENSOR_PATHS,
    Param,
    ParamRule,
    ParamSpec,
    broken_rules,
    param_arg,
    param_split,
    preset_values,
    rule_order,
)
