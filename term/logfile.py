"""The flash log on the PC side: reassembling a download from ``LogChunk`` packets, checking it end to end, and
writing it as CSV. Pure (time passed in); the app feeds it packets and writes the result.

A download (``Op.LOG_DOWNLOAD``, arg = first chunk) streams chunk i = bytes 12i..12i+11 of the used flash, plus
``LogStatus`` packets that give the total ``used`` and the ``crc32`` of those bytes. Chunks may be lost on the way:
``missing()`` names the first gap, and a new ``LOG_DOWNLOAD`` with that index resumes from it.

The record format inside the bytes is the board's (``fcb_sim/flash_log.py``, docs/flash_log.md): self-describing
segments of compressed records. The terminal may not import ``fcb_sim``, so the decoder section of that module is
vendored below. Bytes that do not decode are written as a hex dump, one 12-byte chunk per row, so a download is
never lost.
"""

from __future__ import annotations

import csv
import struct
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from term.protocol import LOG_CHUNK_BYTES, LogChunk, LogStatus


@dataclass
class LogDownload:
    """One download in progress. ``feed`` packets; ``done`` when every chunk up to ``used`` bytes is here."""

    started: float
    used: int | None = None  # bytes, from the first LogStatus
    crc32: int | None = None
    records: int | None = None
    chunks: dict[int, bytes] = field(default_factory=dict)
    last_progress: float = 0.0
    bytes_received: int = 0  # including duplicates: the transfer rate counts what crossed the link

    @property
    def total_chunks(self) -> int | None:
        if self.used is None:
            return None
        return (self.used + LOG_CHUNK_BYTES - 1) // LOG_CHUNK_BYTES

    def feed(self, pkt: Any, now: float) -> bool:
        """Take a LogStatus or LogChunk; returns True if it was one (and so changed the progress)."""
        if type(pkt) is LogStatus:
            self.used, self.crc32, self.records = pkt.used, pkt.crc32, pkt.records
            return True
        if type(pkt) is LogChunk:
            self.chunks[pkt.index] = pkt.data
            self.bytes_received += len(pkt.data)
            self.last_progress = now
            return True
        return False

    @property
    def fraction(self) -> float:
        total = self.total_chunks
        if not total:
            return 1.0 if total == 0 else 0.0
        return min(1.0, sum(1 for i in self.chunks if i < total) / total)

    def rate_kBps(self, now: float) -> float:
        span = max(now - self.started, 1e-6)
        return self.bytes_received / span / 1000.0

    @property
    def empty(self) -> bool:
        """The board's log holds nothing (its LOG_DOWNLOAD is refused with LOG_EMPTY)."""
        return self.used == 0

    @property
    def done(self) -> bool:
        total = self.total_chunks
        return bool(total) and all(i in self.chunks for i in range(total or 0))

    def missing(self) -> int | None:
        """The first chunk not received (where a resumed download starts), or None."""
        total = self.total_chunks
        if total is None:
            return 0 if not self.chunks else None
        for i in range(total):
            if i not in self.chunks:
                return i
        return None

    def data(self) -> bytes:
        """The used bytes, padding cut off; call when ``done``."""
        total = self.total_chunks or 0
        raw = b"".join(self.chunks[i] for i in range(total))
        return raw[: self.used or 0]

    def verify(self) -> str | None:
        """None if the data matches the board's CRC-32, else why not (one line)."""
        if not self.done:
            return f"incomplete: chunk {self.missing()} of {self.total_chunks} missing"
        got = zlib.crc32(self.data())
        if self.crc32 is not None and got != self.crc32:
            return f"CRC-32 mismatch: board {self.crc32:#010x}, received {got:#010x}"
        return None


# --- CSV ------------------------------------------------------------------------------------------------------

Decoder = Callable[[bytes], tuple[Sequence[str], Iterable[Sequence[Any]]]]


def hex_rows(data: bytes) -> tuple[list[str], list[list[Any]]]:
    """The fallback: raw bytes, one chunk per row (offset, hex)."""
    rows = [[off, data[off : off + LOG_CHUNK_BYTES].hex()] for off in range(0, len(data), LOG_CHUNK_BYTES)]
    return ["offset", "hex"], rows


def write_csv(data: bytes, path: Path, decoder: Decoder | None = None) -> int:
    """Write the log to ``path`` as CSV (decoded records if a decoder is given); returns the rows written."""
    header, rows = (decoder or hex_rows)(data)
    path.parent.mkdir(parents=True, exist_ok=True)
    n = 0
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in rows:
            w.writerow(row)
            n += 1
    return n


def log_filename(stamp: str) -> str:
    return f"quadrupel-log-{stamp}.csv"


# --- the board's log format --------------------------------------------------------------------------------
# Vendored unchanged from the decoder section of fcb_sim/flash_log.py (the terminal may not import fcb_sim);
# tests/test_app_log.py checks that it decodes what the board's encoder writes.

SCHEME_DELTA8 = 1
SCHEME_RICE = 2
MAGIC = b"QL"
FORMAT_VERSION = 1
HEADER = struct.Struct("<2sBBBBII")  # magic, version, scheme, n_vars, reserved, records, data length
VAR_ENTRY = struct.Struct("<8sHH")  # name (ASCII, NUL padded), scale, reserved
UNSET32 = 0xFFFFFFFF  # an erased header field: the segment was never closed
RICE_ESCAPE = 20
RICE_RESET = 64


class BitReader:
    def __init__(self, data: bytes) -> None:
        self.value = int.from_bytes(data, "big")
        self.total = len(data) * 8
        self.pos = 0

    def read(self, nbits: int) -> int:
        if self.pos + nbits > self.total:
            raise EOFError("log data ends inside a record")
        self.pos += nbits
        return (self.value >> (self.total - self.pos)) & ((1 << nbits) - 1)

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


def _unzigzag(z: int) -> int:
    return z >> 1 if not z & 1 else -((z + 1) >> 1)


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


def decode_to_rows(data: bytes) -> tuple[list[str], list[list[Any]]]:
    """Decoded records (a ``segment`` column, then the variables in board units) if the bytes hold the board's
    segment format; else the hex fallback, so a download is never lost."""
    try:
        segments = decode_log(data)
    except (ValueError, EOFError, struct.error, UnicodeDecodeError):
        return hex_rows(data)
    if not segments:
        return hex_rows(data)
    names = segments[0].names
    rows: list[list[Any]] = []
    for i, seg in enumerate(segments):
        if seg.names != names:
            break  # a later segment with other variables: the CSV keeps one header (the first segment's)
        rows.extend([i, *r] for r in seg.rows)
    return ["segment", *names], rows
