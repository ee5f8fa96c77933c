"""The flash-log payload codec: what ``LogChunk`` packets carry (docs/flash_log.md).

The board's flash log is a sequence of self-describing segments of compressed records. Both ends need the
format: the board's encoder (``fcb_sim.board.flash_log``) mirrors the decoder state machines here, and the terminal
decodes downloads with ``decode_log``. Pure: standard library only, bytes in and rows out.

A segment is ``LOG_HEADER`` (magic ``QL``, format version, scheme, variable count, record count, data length),
one ``LOG_VAR_ENTRY`` per variable (name, quantisation scale), then the records: the first absolute (int32 per
variable), the rest coded by the segment's scheme:

- ``SCHEME_DELTA8``, the report's: one scaled signed byte per variable against the reconstruction;
- ``SCHEME_RICE``, ours: prediction from the reconstructed values and an adaptive Rice code (``RiceState``),
  the same error bound (scale/2), no slope overload.

A segment whose record count and length are still erased (``LOG_UNSET32``) was never closed: its records run to
the end of the data. The columns are named after the telemetry fields they log and carry their board units
(time in ``LOG_TIME_COLUMN``, µs): ``term.core.protocol.column_scale`` turns one into the unit the terminal shows.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

from term.core.protocol import LOG_TIME_COLUMN, SCHEME_DELTA8, SCHEME_NAMES, SCHEME_RICE  # noqa: F401 (re-exported)

LOG_MAGIC = b"QL"
LOG_FORMAT_VERSION = 2  # 2: the height column in cm, as the Height packet (1: mm)
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
        if magic != LOG_MAGIC:
            raise ValueError(f"no log segment at byte {pos}")
        if version != LOG_FORMAT_VERSION:
            raise ValueError(f"log format version {version} at byte {pos}, this decoder reads {LOG_FORMAT_VERSION}")
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
