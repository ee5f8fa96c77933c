"""The board's 128 KB flash log (report 3.5): compressed records at the control rate, downloaded in chunks.

Two record codecs share one self-describing segment format (docs/flash_log.md):

- ``SCHEME_DELTA8``, the report's: the first record absolute (int32 per variable), then one signed byte per
  variable: the change since the last *reconstructed* value, divided by the variable's scale. Coding against
  the reconstruction (the report's "error term") keeps quantisation errors from adding up: the error stays
  within scale/2, except while a change is too big for one byte (slope overload), which the next records catch
  up on.
- ``SCHEME_RICE``, ours, the way flight-data recorders and lossless audio coders do it: each value is quantised
  to the same scale (so the same error bound, scale/2, but now always), predicted from the previous
  reconstructed values (previous value or linear extrapolation, whichever has been doing better lately, decided
  from past data so the decoder makes the same choice), and the prediction residual is written with an
  adaptive Rice code (LOCO-I's parameter rule): a few bits for the small residuals of a smooth signal, an escape
  for any jump. There is no overload.

Flash behaves as NOR flash: erased bytes are 0xFF and programming can only clear bits; each programmed byte
costs 15 µs on the board (the report's figure), which is why compression matters: it is CPU time in the control
loop. A segment's record count and length are programmed into its header when logging stops, the way a real
log does it without rewriting flash.

This module is the board side: the flash, the logger and the record encoder. The format itself (segment header,
the decoders whose state machines the encoder mirrors) is shared with the terminal, in ``term.core.logformat``,
because the terminal decodes what ``LogChunk`` packets carry with it.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from term.core.logformat import (
    LOG_FORMAT_VERSION,
    LOG_HEADER,
    LOG_MAGIC,
    LOG_UNSET32,
    LOG_VAR_ENTRY,
    RICE_ESCAPE,
    SCHEME_DELTA8,
    SCHEME_RICE,
    RiceState,
    quantise,
    zigzag,
)
from term.core.protocol import LOG_CHUNK_BYTES, LogChunk, LogState, LogStatus, Nak

FLASH_BYTES = 128 * 1024
FLASH_US_PER_BYTE = 15  # report 3.5: each byte takes 15 µs to write

SCHEMES = {"delta8": SCHEME_DELTA8, "rice": SCHEME_RICE}


@dataclass(frozen=True)
class LogVar:
    name: str
    scale: int  # quantisation step in board units; worst reconstruction error is scale // 2
    doc: str = ""


# What the board logs every control period, in board units (docs/architecture.md).
LOG_VARS: tuple[LogVar, ...] = (
    LogVar("t_us", 32, "board time, µs"),
    LogVar("mode", 1, "Mode"),
    LogVar("phi", 2, "roll, 0.01°"),
    LogVar("theta", 2, "pitch, 0.01°"),
    LogVar("psi", 2, "yaw, 0.01°"),
    LogVar("sp", 4, "roll rate, LSB (16.4 per °/s)"),
    LogVar("sq", 4, "pitch rate, LSB"),
    LogVar("sr", 4, "yaw rate, LSB"),
    LogVar("sax", 8, "body x acceleration, LSB (16384 per g)"),
    LogVar("say", 8, "body y acceleration, LSB"),
    LogVar("saz", 8, "body z acceleration, LSB"),
    LogVar("ae1", 1, "front motor, 0..1000"),
    LogVar("ae2", 1, "right motor"),
    LogVar("ae3", 1, "back motor"),
    LogVar("ae4", 1, "left motor"),
    LogVar("height", 1, "estimated height, cm (the Height packet's unit)"),
    LogVar("pressure", 1, "barometer, Pa"),
    LogVar("battery", 1, "battery, 10 mV"),
)


# --- bits ---------------------------------------------------------------------------------------------------


class BitWriter:
    """MSB-first bit packer; complete bytes are taken out as they fill."""

    def __init__(self) -> None:
        self.acc = 0
        self.nbits = 0
        self.out = bytearray()

    def write(self, value: int, nbits: int) -> None:
        self.acc = (self.acc << nbits) | (value & ((1 << nbits) - 1))
        self.nbits += nbits
        if self.nbits >= 8:
            whole = self.nbits >> 3
            rest = self.nbits & 7
            self.out += (self.acc >> rest).to_bytes(whole, "big")
            self.acc &= (1 << rest) - 1
            self.nbits = rest

    def take(self) -> bytes:
        data = bytes(self.out)
        self.out.clear()
        return data

    def flush(self) -> bytes:
        """The complete bytes plus the last partial byte, padded with 1 bits (erased flash)."""
        if self.nbits:
            pad = 8 - self.nbits
            self.write((1 << pad) - 1, pad)
        return self.take()


# --- codecs: one state machine per direction, mirrored exactly --------------------------------------------


class RecordEncoder:
    """Encodes records of one segment into bits. ``encode(values)`` returns the bytes completed by it."""

    def __init__(self, scheme: int, scales: Sequence[int]) -> None:
        if scheme not in (SCHEME_DELTA8, SCHEME_RICE):
            raise ValueError(f"unknown log scheme {scheme}")
        self.scheme = scheme
        self.scales = tuple(scales)
        self.bits = BitWriter()
        self.count = 0
        self._recon: list[int] = []
        self._rice: list[RiceState] = []

    def worst_bytes(self) -> int:
        """An upper bound on the bytes one record may add (for the flash-full check)."""
        n = len(self.scales)
        if self.scheme == SCHEME_DELTA8:
            return 4 * n
        return (n * (RICE_ESCAPE + 32 + 40) + 7) // 8 + 1

    def encode(self, values: Sequence[int]) -> bytes:
        w = self.bits
        if self.count == 0:
            # The first record is absolute (exact, int32): both schemes start from the true values.
            for v in values:
                w.write(int(v) & LOG_UNSET32, 32)
            self._recon = [int(v) for v in values]
            if self.scheme == SCHEME_RICE:
                self._rice = [RiceState(quantise(int(v), s)) for v, s in zip(values, self.scales, strict=True)]
                self._recon = [st.prev1 * s for st, s in zip(self._rice, self.scales, strict=True)]
        elif self.scheme == SCHEME_DELTA8:
            recon = self._recon
            for i, (v, s) in enumerate(zip(values, self.scales, strict=True)):
                q = max(-127, min(127, quantise(int(v) - recon[i], s)))
                recon[i] += q * s  # the error term: the next delta is taken from what the decoder will hold
                w.write(q & 0xFF, 8)
        else:
            for st, v, s in zip(self._rice, values, self.scales, strict=True):
                q = quantise(int(v), s)
                z = zigzag(q - st.predict())
                k = st.k()
                top = z >> k
                if top < RICE_ESCAPE:
                    w.write(((1 << top) - 1) << 1, top + 1)  # unary: top ones and a zero
                    if k:
                        w.write(z, k)
                else:
                    w.write((1 << RICE_ESCAPE) - 1, RICE_ESCAPE)
                    w.write(z, 32)
                st.update(q, z)
        self.count += 1
        return w.take()

    def flush(self) -> bytes:
        return self.bits.flush()


def segment_header(scheme: int, variables: Sequence[LogVar], records: int = LOG_UNSET32,
                   length: int = LOG_UNSET32) -> bytes:
    head = LOG_HEADER.pack(LOG_MAGIC, LOG_FORMAT_VERSION, scheme, len(variables), 0xFF, records, length)
    return head + b"".join(LOG_VAR_ENTRY.pack(v.name.encode("ascii")[:8], v.scale, 0xFFFF) for v in variables)


# --- the flash and the logger (board side) ------------------------------------------------------------------


class Flash:
    """NOR flash: erased to 0xFF; programming ANDs bits in; counts programmed bytes (each costs 15 µs)."""

    def __init__(self, size: int = FLASH_BYTES) -> None:
        self.size = size
        self.mem = bytearray(b"\xff" * size)
        self.programmed = 0

    def erase(self) -> None:
        self.mem[:] = b"\xff" * self.size

    def program(self, addr: int, data: bytes) -> None:
        if addr < 0 or addr + len(data) > self.size:
            raise ValueError("flash write out of range")
        for i, b in enumerate(data):
            self.mem[addr + i] &= b
        self.programmed += len(data)


class FlashLog:
    """The logger: segments of records in a ``Flash``; start/stop by command; stops itself when full.

    ``append`` returns the number of bytes it programmed, which the board charges at 15 µs each.
    """

    def __init__(self, size: int = FLASH_BYTES, scheme: str | int = "rice",
                 variables: Sequence[LogVar] = LOG_VARS) -> None:
        self.flash = Flash(size)
        self.scheme = SCHEMES[scheme] if isinstance(scheme, str) else int(scheme)
        self.variables = tuple(variables)
        self.state = LogState.IDLE
        self.used = 0  # bytes of flash in use (closed segments plus the open one)
        self.records = 0  # records in all segments
        self._seg_start = 0
        self._seg_records = 0
        self._data_start = 0
        self._encoder: RecordEncoder | None = None

    @property
    def recording(self) -> bool:
        return self.state == LogState.RECORDING

    @property
    def fill_pct(self) -> int:
        return min(100, self.used * 100 // self.flash.size)

    @property
    def n_chunks(self) -> int:
        return (self.used + LOG_CHUNK_BYTES - 1) // LOG_CHUNK_BYTES

    def start(self) -> tuple[Nak, int]:
        """Open a new segment. Returns (reason, bytes programmed)."""
        if self.state == LogState.RECORDING:
            return Nak.OK, 0
        if self.state == LogState.DOWNLOADING:
            return Nak.LOG_BUSY, 0
        header = segment_header(self.scheme, self.variables)
        encoder = RecordEncoder(self.scheme, [v.scale for v in self.variables])
        if self.used + len(header) + encoder.worst_bytes() > self.flash.size:
            self.state = LogState.FULL
            return Nak.LOG_FULL, 0
        self._seg_start = self.used
        self.flash.program(self.used, header)
        self.used += len(header)
        self._data_start = self.used
        self._seg_records = 0
        self._encoder = encoder
        self.state = LogState.RECORDING
        return Nak.OK, len(header)

    def append(self, values: Sequence[int]) -> int:
        """Log one record if recording; returns the bytes programmed. Stops (FULL) when the next record might
        not fit."""
        enc = self._encoder
        if self.state != LogState.RECORDING or enc is None:
            return 0
        if self.used + enc.worst_bytes() + 1 > self.flash.size:
            return self._close(LogState.FULL)
        data = enc.encode(values)
        self.flash.program(self.used, data)
        self.used += len(data)
        self._seg_records += 1
        self.records += 1
        return len(data)

    def stop(self) -> tuple[Nak, int]:
        if self.state != LogState.RECORDING:
            return Nak.OK, 0
        return Nak.OK, self._close(LogState.IDLE)

    def _close(self, state: LogState) -> int:
        """Flush the last partial byte and program the segment's record count and length into its header."""
        assert self._encoder is not None
        tail = self._encoder.flush()
        self.flash.program(self.used, tail)
        self.used += len(tail)
        fields = struct.pack("<II", self._seg_records, self.used - self._data_start)
        self.flash.program(self._seg_start + 6, fields)
        self._encoder = None
        self.state = state
        return len(tail) + len(fields)

    def reset(self, in_safe: bool) -> Nak:
        if not in_safe:
            return Nak.NOT_IN_SAFE
        if self.state in (LogState.RECORDING, LogState.DOWNLOADING):
            return Nak.LOG_BUSY
        self.flash.erase()
        self.used = self.records = 0
        self.state = LogState.IDLE
        return Nak.OK

    def contents(self) -> bytes:
        return bytes(self.flash.mem[: self.used])

    def crc32(self) -> int:
        return zlib.crc32(self.flash.mem[: self.used]) & LOG_UNSET32

    def chunk(self, index: int) -> bytes:
        """Chunk ``index``: bytes 12i .. 12i+11 of the used flash, the last one padded with 0xFF."""
        start = index * LOG_CHUNK_BYTES
        return bytes(self.flash.mem[start : start + LOG_CHUNK_BYTES]).ljust(LOG_CHUNK_BYTES, b"\xff")

    def status(self, state: LogState | None = None) -> LogStatus:
        """The LogStatus packet: state (the log's own unless given), bytes used, records, CRC-32."""
        return LogStatus(int(self.state if state is None else state), self.used, self.records, self.crc32())


class Download:
    """The board's side of a log download (docs/flash_log.md): ``LogStatus`` (DOWNLOADING), then the chunks in
    order from the first one asked for, as many per telemetry run as the transmit buffer takes (the wire paces
    the download), then ``LogStatus`` again. ``send`` is the board's packet output."""

    def __init__(self) -> None:
        self.next: int | None = None  # the next chunk to send, or None when no download runs
        self.sent = 0  # chunks sent by this download

    @property
    def active(self) -> bool:
        return self.next is not None

    @staticmethod
    def refusal(log: FlashLog, first: int) -> Nak:
        """Why a download from chunk ``first`` cannot start now (Nak.OK if it can; SAFE is the board's check)."""
        if log.recording:
            return Nak.LOG_BUSY
        if log.used == 0:
            return Nak.LOG_EMPTY
        if not 0 <= first < log.n_chunks:
            return Nak.BAD_ARGUMENT
        return Nak.OK

    def begin(self, first: int, log: FlashLog, send: Callable[[Any], None]) -> None:
        self.next = first
        self.sent = 0
        send(log.status(LogState.DOWNLOADING))

    def step(self, log: FlashLog, has_room: Callable[[], bool], send: Callable[[Any], None]) -> tuple[int, bool]:
        """Send chunks while ``has_room()``; returns (chunks sent now, whether the last one went)."""
        count = 0
        n = log.n_chunks
        while self.next is not None and has_room():
            i = self.next
            send(LogChunk(i, log.chunk(i)))
            self.sent += 1
            count += 1
            self.next = i + 1 if i + 1 < n else None
            if self.next is None:
                return count, True
        return count, False

    def end(self, log: FlashLog, send: Callable[[Any], None]) -> None:
        """Stop (done, or the board left SAFE) and say where the log stands."""
        self.next = None
        send(log.status())


def encode_log(rows: Iterable[Sequence[int]], scheme: str | int = "rice",
               variables: Sequence[LogVar] = LOG_VARS) -> bytes:
    """Log ``rows`` into a flash just large enough for them and return its contents (benchmarks, tests)."""
    rows = list(rows)
    code = SCHEMES[scheme] if isinstance(scheme, str) else int(scheme)
    worst = RecordEncoder(code, [v.scale for v in variables]).worst_bytes()
    size = len(segment_header(code, variables)) + (len(rows) + 2) * worst + 64
    log = FlashLog(size=size, scheme=scheme, variables=variables)
    log.start()
    for row in rows:
        log.append(row)
    log.stop()
    return log.contents()
