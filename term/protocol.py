"""The one protocol codec shared by the terminal and the board: packets, framing, CRC, streaming decoder.

Pure and sans-IO: standard library only, bytes in and packets out.

A frame on the wire is ``COBS(type | seq | body | crc16) 0x00``:

- ``type``  one byte, the packet id from the table below; it fixes the body's length and layout;
- ``seq``   one byte, a per-direction counter (mod 256) that the receiver uses to count lost frames;
- ``body``  the packet's fields, little-endian, at most 14 bytes;
- ``crc16`` CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over type, seq and body, big-endian;
- COBS (consistent overhead byte stuffing) removes every 0x00 from the frame, so 0x00 only ever marks a frame's end.

A receiver that loses sync (a corrupted, lost or inserted byte) is back in step at the next 0x00: a corrupted byte
costs at most the two frames on either side of it, and the CRC keeps a damaged frame from being misread.
Every frame is at most 20 bytes, one BLE notification.
"""

from __future__ import annotations

import binascii
import struct
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import Annotated, Any, NamedTuple, get_type_hints

PROTOCOL_VERSION = 1
MAX_FRAME = 20  # bytes on the wire, delimiter included: one BLE notification
MAX_BODY = MAX_FRAME - 6  # type, seq, crc16 (2), COBS overhead (1), delimiter (1)
DELIMITER = b"\x00"
CRC_INIT = 0xFFFF

PC_TO_BOARD = "pc→board"
BOARD_TO_PC = "board→pc"
BOTH = "both"


# --- enumerations carried in packets ------------------------------------------------------------------------


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
    SET_PARAM = 18  # generic set: arg = (param id << 16) | (value & 0xFFFF)


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
}


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


class WirelessState(IntEnum):
    DISCONNECTED = 0
    STARTING = 1
    STARTED = 2


class LogState(IntEnum):
    IDLE = 0
    RECORDING = 1
    FULL = 2
    DOWNLOADING = 3


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


class Button(IntFlag):
    """Joystick button bits (``Joystick.buttons``)."""

    FIRE = 1 << 0  # PANIC


# --- the packet table ---------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class F:
    """A packet field's wire format (a struct character), unit and meaning; used inside ``Annotated``."""

    fmt: str
    unit: str = ""
    doc: str = ""


@dataclass(frozen=True, slots=True)
class FieldSpec:
    name: str
    fmt: str
    unit: str
    doc: str


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
            fields.append(FieldSpec(name, meta[0].fmt, meta[0].unit, meta[0].doc))
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
    board_ms: Annotated[int, F("I", "ms", "the Heartbeat's board time, echoed")]


@packet(0x04, BOTH, "at connect", "Version handshake: each side sends its own; a mismatch is reported.")
class Hello(NamedTuple):
    protocol: Annotated[int, F("B", "", "PROTOCOL_VERSION of the sender")]
    role: Annotated[int, F("B", "", "0 terminal, 1 board")]
    major: Annotated[int, F("B", "", "software major version")]
    minor: Annotated[int, F("B", "", "software minor version")]
    board_id: Annotated[int, F("H", "", "board serial number (0 from a terminal)")]


@packet(0x10, BOARD_TO_PC, "10 Hz", "Heartbeat; the terminal answers HeartbeatAck at once.")
class Heartbeat(NamedTuple):
    counter: Annotated[int, F("H", "", "increments per heartbeat")]
    board_ms: Annotated[int, F("I", "ms", "board time since boot")]
    rtt: Annotated[int, F("H", "0.1 ms", "previous Heartbeat's round trip to its HeartbeatAck; 0 if none")] = 0


@packet(0x11, BOARD_TO_PC, "once per Command", "Command acknowledgement (status 0) or refusal (status = Nak).")
class Ack(NamedTuple):
    cmd_id: Annotated[int, F("B", "", "the Command's cmd_id")]
    op: Annotated[int, F("B", "Op", "the Command's op")]
    status: Annotated[int, F("B", "Nak", "0 accepted, else the reason for refusal")]
    value: Annotated[int, F("i", "", "resulting value (mode, trim, gain in milli-units) where one applies")]


@packet(0x12, BOARD_TO_PC, "50 Hz", "Attitude telemetry.")
class Attitude(NamedTuple):
    mode: Annotated[int, F("B", "Mode", "current mode")]
    phi: Annotated[int, F("h", "0.01°", "roll angle")]
    theta: Annotated[int, F("h", "0.01°", "pitch angle")]
    psi: Annotated[int, F("h", "0.01°", "yaw angle")]
    sp: Annotated[int, F("h", "LSB (16.4/°/s)", "roll rate")]
    sq: Annotated[int, F("h", "LSB (16.4/°/s)", "pitch rate")]
    sr: Annotated[int, F("h", "LSB (16.4/°/s)", "yaw rate")]


@packet(0x13, BOARD_TO_PC, "50 Hz", "Accelerations and motor commands.")
class Motion(NamedTuple):
    sax: Annotated[int, F("h", "LSB (16384/g)", "body x acceleration")]
    say: Annotated[int, F("h", "LSB (16384/g)", "body y acceleration")]
    saz: Annotated[int, F("h", "LSB (16384/g)", "body z acceleration")]
    ae1: Annotated[int, F("H", "0..1000", "front motor command")]
    ae2: Annotated[int, F("H", "0..1000", "right motor command")]
    ae3: Annotated[int, F("H", "0..1000", "back motor command")]
    ae4: Annotated[int, F("H", "0..1000", "left motor command")]


@packet(0x14, BOARD_TO_PC, "20 Hz", "Barometer, height estimate and battery.")
class Height(NamedTuple):
    pressure: Annotated[int, F("I", "Pa", "barometric pressure")]
    height: Annotated[int, F("h", "mm", "estimated height above the reference")]
    setpoint: Annotated[int, F("h", "mm", "height set point (HEIGHT mode)")]
    vz: Annotated[int, F("h", "mm/s", "estimated vertical speed, up positive")]
    battery: Annotated[int, F("H", "10 mV", "battery voltage")]
    temperature: Annotated[int, F("h", "0.01 °C", "barometer temperature")]


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
    board_ms: Annotated[int, F("I", "ms", "board time")]


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


@packet(0x1B, BOARD_TO_PC, "3 per heartbeat over BLE (30 Hz)", "The phone's telemetry: mode, attitude, battery.")
class Compact(NamedTuple):
    mode: Annotated[int, F("B", "Mode", "")]
    wireless: Annotated[int, F("B", "WirelessState", "")]
    phi: Annotated[int, F("h", "0.01°", "")]
    theta: Annotated[int, F("h", "0.01°", "")]
    psi: Annotated[int, F("h", "0.01°", "")]
    battery: Annotated[int, F("H", "10 mV", "")]


LOG_CHUNK_BYTES = 12
TELEMETRY = (Attitude, Motion, Height, Status, Gains)


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


# --- the flash-log payload ----------------------------------------------------------------------------------
# What LogChunk packets carry: the board's flash log, a sequence of self-describing segments of compressed
# records (docs/flash_log.md). Both ends need it: the board's encoder (fcb_sim.flash_log) mirrors the state
# machines below, and the terminal decodes downloads with them.

SCHEME_DELTA8 = 1  # the report's: one scaled signed byte per variable, against the reconstruction
SCHEME_RICE = 2  # ours: prediction and an adaptive Rice code, the same error bound, no overload

LOG_MAGIC = b"QL"
LOG_FORMAT_VERSION = 1
LOG_HEADER = struct.Struct("<2sBBBBII")  # magic, version, scheme, n_vars, reserved, records, data length
LOG_VAR_ENTRY = struct.Struct("<8sHH")  # name (ASCII, NUL padded), scale, reserved
LOG_UNSET32 = 0xFFFFFFFF  # an erased header field: the segment was never closed (records run to the end)

RICE_ESCAPE = 20  # a unary quotient this long is an escape: 32 raw bits of the zigzagged residual follow
RICE_RESET = 64  # LOCO-I: halve the statistics every this many samples so the code adapts


class BitReader:
    def __init__(self, data: bytes) -> None:
        self.data = bytes(data)
        self.total = len(data) * 8
        self.pos = 0

    def read(self, nbits: int) -> int:
        pos, end = self.pos, self.pos + nbits
        if end > self.total:
            raise EOFError("log data ends inside a record")
        first, last = pos >> 3, (end + 7) >> 3
        self.pos = end
        return (int.from_bytes(self.data[first:last], "big") >> ((last << 3) - end)) & ((1 << nbits) - 1)

    def unary(self, limit: int) -> int:
        """Count 1 bits up to a 0 (consumed) or ``limit`` ones (no 0 follows)."""
        n = 0
        while n < limit:
            if self.read(1) == 0:
                return n
            n += 1
        return n


def quantise(x: int, scale: int) -> int:
    """Nearest multiple index (ties up); |x - q*scale| <= scale // 2."""
    return (x + scale // 2) // scale


class RiceState:
    """Per-variable adaptive state, identical in encoder and decoder."""

    __slots__ = ("prev1", "prev2", "e1", "e2", "a", "n")

    def __init__(self, first: int) -> None:
        self.prev1 = first
        self.prev2 = first
        self.e1 = 0  # decayed sums of |residual| of each predictor
        self.e2 = 0
        self.a = 4  # LOCO-I: sum of |zigzagged residual| ...
        self.n = 1  # ... over this many samples

    def predict(self) -> int:
        return self.prev1 if self.e1 <= self.e2 else 2 * self.prev1 - self.prev2

    def k(self) -> int:
        k = 0
        while (self.n << k) < self.a:
            k += 1
        return k

    def update(self, q: int, z: int) -> None:
        p1, p2 = self.prev1, 2 * self.prev1 - self.prev2
        self.e1 += abs(q - p1) - (self.e1 >> 4)
        self.e2 += abs(q - p2) - (self.e2 >> 4)
        self.prev2, self.prev1 = self.prev1, q
        self.a += z
        self.n += 1
        if self.n >= RICE_RESET:
            self.a = max(1, self.a >> 1)
            self.n >>= 1


def zigzag(r: int) -> int:
    return 2 * r if r >= 0 else -2 * r - 1


def unzigzag(z: int) -> int:
    return z >> 1 if not z & 1 else -((z + 1) >> 1)


def decode_log_records(scheme: int, scales: Sequence[int], data: bytes, count: int | None) -> list[tuple[int, ...]]:
    """Decode ``count`` records (None: as many as the data holds) of one segment."""
    r = BitReader(data)
    n = len(scales)
    out: list[tuple[int, ...]] = []
    if count == 0 or len(data) < 4 * n:
        return out
    first = [r.read(32) for _ in range(n)]
    first = [v - (1 << 32) if v & 0x80000000 else v for v in first]
    if scheme == SCHEME_RICE:
        states = [RiceState(quantise(v, s)) for v, s in zip(first, scales, strict=True)]
        out.append(tuple(st.prev1 * s for st, s in zip(states, scales, strict=True)))
    elif scheme == SCHEME_DELTA8:
        out.append(tuple(first))
        recon = list(first)
    else:
        raise ValueError(f"unknown log scheme {scheme}")
    while count is None or len(out) < count:
        try:
            if scheme == SCHEME_DELTA8:
                for i in range(n):
                    b = r.read(8)
                    recon[i] += (b - 256 if b & 0x80 else b) * scales[i]
                out.append(tuple(recon))
            else:
                row = []
                for st, s in zip(states, scales, strict=True):
                    k = st.k()
                    top = r.unary(RICE_ESCAPE)
                    z = r.read(32) if top == RICE_ESCAPE else (top << k) | (r.read(k) if k else 0)
                    q = st.predict() + unzigzag(z)
                    st.update(q, z)
                    row.append(q * s)
                out.append(tuple(row))
        except EOFError:
            if count is not None:
                raise
            break
    return out


@dataclass
class LogSegment:
    scheme: int
    names: tuple[str, ...]
    scales: tuple[int, ...]
    rows: list[tuple[int, ...]]
    closed: bool  # False: logging never stopped cleanly (records decoded up to the end of the data)


def decode_log(data: bytes) -> list[LogSegment]:
    """All segments in a downloaded log (the used bytes of the flash). Raises ValueError on a corrupt log."""
    segments: list[LogSegment] = []
    pos = 0
    while pos + LOG_HEADER.size <= len(data):
        magic, version, scheme, n_vars, _res, records, length = LOG_HEADER.unpack_from(data, pos)
        if magic != LOG_MAGIC or version != LOG_FORMAT_VERSION:
            raise ValueError(f"no log segment at byte {pos}")
        pos += LOG_HEADER.size
        names, scales = [], []
        for _ in range(n_vars):
            name, scale, _r = LOG_VAR_ENTRY.unpack_from(data, pos)
            names.append(name.rstrip(b"\x00").decode("ascii"))
            scales.append(scale)
            pos += LOG_VAR_ENTRY.size
        closed = length != LOG_UNSET32
        body = data[pos : pos + length] if closed else data[pos:]
        rows = decode_log_records(scheme, scales, body, records if closed else None)
        segments.append(LogSegment(scheme, tuple(names), tuple(scales), rows, closed))
        if not closed:
            break
        pos += length
    return segments


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
        lines.append("| offset | field | type | unit | meaning |")
        lines.append("|---|---|---|---|---|")
        offset = 0
        for fs in spec.fields:
            size = struct.calcsize("<" + fs.fmt)
            lines.append(f"| {offset} | `{fs.name}` | {_C_TYPE.get(fs.fmt, fs.fmt)} | {fs.unit} | {fs.doc} |")
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
    for enum in (Mode, Op, Nak, EventCode, WirelessState, LogState, Flag, Button):
        lines.append(f"### {enum.__name__}")
        lines.append("")
        lines.append("| value | name |" + (" text |" if enum is Nak else ""))
        lines.append("|---|---|" + ("---|" if enum is Nak else ""))
        for member in enum:
            extra = f" {NAK_TEXT[member]} |" if enum is Nak else ""
            lines.append(f"| {int(member)} | {member.name} |{extra}")
        lines.append("")
    return "\n".join(lines)

