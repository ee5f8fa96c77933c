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

The second half of this module (the decoder section) is the PC side: chunk reassembly with resume after loss,
the whole-log CRC check, segment decoding and CSV. It uses only the standard library and nothing else of
fcb_sim, so the terminal may vendor it unchanged.
"""

from __future__ import annotations

import csv
import io
import struct
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from term.protocol import LOG_CHUNK_BYTES, LogState, Nak

FLASH_BYTES = 128 * 1024
FLASH_US_PER_BYTE = 15  # report 3.5: each byte takes 15 µs to write

SCHEME_DELTA8 = 1
SCHEME_RICE = 2
SCHEMES = {"delta8": SCHEME_DELTA8, "rice": SCHEME_RICE}

MAGIC = b"QL"
FORMAT_VERSION = 1
HEADER = struct.Struct("<2sBBBBII")  # magic, version, scheme, n_vars, reserved, records, data length
VAR_ENTRY = struct.Struct("<8sHH")  # name (ASCII, NUL padded), scale, reserved
UNSET32 = 0xFFFFFFFF  # an erased header field: the segment was never closed (records run to the end of data)

RICE_ESCAPE = 20  # a unary quotient this long is an escape: 32 raw bits of the zigzagged residual follow
RICE_RESET = 64  # LOCO-I: halve the statistics every this many samples so the code adapts


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
    LogVar("height", 2, "estimated height, mm"),
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


# --- codecs: one state machine per direction, mirrored exactly --------------------------------------------


def quantise(x: int, scale: int) -> int:
    """Nearest multiple index (ties up); |x - q*scale| <= scale // 2."""
    return (x + scale // 2) // scale


class _RiceState:
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


def _zigzag(r: int) -> int:
    return 2 * r if r >= 0 else -2 * r - 1


def _unzigzag(z: int) -> int:
    return z >> 1 if not z & 1 else -((z + 1) >> 1)


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
        self._rice: list[_RiceState] = []

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
                w.write(int(v) & UNSET32, 32)
            self._recon = [int(v) for v in values]
            if self.scheme == SCHEME_RICE:
                self._rice = [_RiceState(quantise(int(v), s)) for v, s in zip(values, self.scales, strict=True)]
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
                z = _zigzag(q - st.predict())
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


def decode_records(scheme: int, scales: Sequence[int], data: bytes, count: int | None) -> list[tuple[int, ...]]:
    """Decode ``count`` records (None: as many as the data holds) of one segment."""
    r = BitReader(data)
    n = len(scales)
    out: list[tuple[int, ...]] = []
    if count == 0 or len(data) < 4 * n:
        return out
    first = [r.read(32) for _ in range(n)]
    first = [v - (1 << 32) if v & 0x80000000 else v for v in first]
    if scheme == SCHEME_RICE:
        states = [_RiceState(quantise(v, s)) for v, s in zip(first, scales, strict=True)]
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
                    q = st.predict() + _unzigzag(z)
                    st.update(q, z)
                    row.append(q * s)
                out.append(tuple(row))
        except EOFError:
            if count is not None:
                raise
            break
    return out


def segment_header(scheme: int, variables: Sequence[LogVar], records: int = UNSET32,
                   length: int = UNSET32) -> bytes:
    head = HEADER.pack(MAGIC, FORMAT_VERSION, scheme, len(variables), 0xFF, records, length)
    return head + b"".join(VAR_ENTRY.pack(v.name.encode("ascii")[:8], v.scale, 0xFFFF) for v in variables)


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
        return zlib.crc32(self.flash.mem[: self.used]) & UNSET32

    def chunk(self, index: int) -> bytes:
        """Chunk ``index``: bytes 12i .. 12i+11 of the used flash, the last one padded with 0xFF."""
        start = index * LOG_CHUNK_BYTES
        return bytes(self.flash.mem[start : start + LOG_CHUNK_BYTES]).ljust(LOG_CHUNK_BYTES, b"\xff")


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


# ============================================================================================================
# Decoder section: the PC side. Standard library only and nothing else of fcb_sim (the terminal may vendor it).
# ============================================================================================================


@dataclass
class Segment:
    scheme: int
    names: tuple[str, ...]
    scales: tuple[int, ...]
    rows: list[tuple[int, ...]]
    closed: bool  # False: logging never stopped cleanly (records decoded up to the end of the data)


def decode_log(data: bytes) -> list[Segment]:
    """All segments in a downloaded log (the used bytes of the flash). Raises ValueError on a corrupt log."""
    segments: list[Segment] = []
    pos = 0
    while pos + HEADER.size <= len(data):
        magic, version, scheme, n_vars, _res, records, length = HEADER.unpack_from(data, pos)
        if magic != MAGIC or version != FORMAT_VERSION:
            raise ValueError(f"no log segment at byte {pos}")
        pos += HEADER.size
        names, scales = [], []
        for _ in range(n_vars):
            name, scale, _r = VAR_ENTRY.unpack_from(data, pos)
            names.append(name.rstrip(b"\x00").decode("ascii"))
            scales.append(scale)
            pos += VAR_ENTRY.size
        closed = length != UNSET32
        body = data[pos : pos + length] if closed else data[pos:]
        rows = decode_records(scheme, scales, body, records if closed else None)
        segments.append(Segment(scheme, tuple(names), tuple(scales), rows, closed))
        if not closed:
            break
        pos += length
    return segments


def write_csv(segments: Sequence[Segment], out: io.TextIOBase | None = None) -> str:
    """The log as CSV: a ``segment`` column, then the variables in board units. Returns the text (and writes
    it to ``out`` if given)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    header_written: tuple[str, ...] | None = None
    for i, seg in enumerate(segments):
        if seg.names != header_written:
            w.writerow(("segment", *seg.names))
            header_written = seg.names
        for row in seg.rows:
            w.writerow((i, *row))
    text = buf.getvalue()
    if out is not None:
        out.write(text)
    return text


class LogAssembler:
    """Reassembles a download from LogChunk packets in any order, with loss: tell it what the board's LogStatus
    said (``used`` bytes, ``crc32``), feed it chunks, ask ``next_request()`` for the chunk to resume from (send
    ``Command(op=LOG_DOWNLOAD, arg=that)``), and take ``data()`` once ``complete``."""

    CHUNK = 12

    def __init__(self, used: int, crc32: int) -> None:
        self.used = used
        self.crc32 = crc32
        self.n_chunks = (used + self.CHUNK - 1) // self.CHUNK
        self._chunks: dict[int, bytes] = {}

    def add(self, index: int, data: bytes) -> bool:
        """Store one chunk; returns False for one outside the log (a stale download)."""
        if not 0 <= index < self.n_chunks:
            return False
        self._chunks[index] = bytes(data[: self.CHUNK])
        return True

    def missing(self) -> list[int]:
        return [i for i in range(self.n_chunks) if i not in self._chunks]

    def next_request(self) -> int | None:
        """The first chunk not yet received (resume from there), or None when all are in."""
        for i in range(self.n_chunks):
            if i not in self._chunks:
                return i
        return None

    @property
    def received(self) -> int:
        return len(self._chunks)

    @property
    def complete(self) -> bool:
        return len(self._chunks) == self.n_chunks

    def data(self) -> bytes:
        """The whole log, checked against the board's CRC32; ValueError if incomplete or corrupt."""
        if not self.complete:
            raise ValueError(f"log incomplete: {len(self.missing())} of {self.n_chunks} chunks missing")
        data = b"".join(self._chunks[i] for i in range(self.n_chunks))[: self.used]
        if zlib.crc32(data) & 0xFFFFFFFF != self.crc32:
            raise ValueError("log CRC32 mismatch: download it again")
        return data
