"""The flash log on the PC side: reassembling a download from ``LogChunk`` packets, checking it end to end, and
writing it as CSV. Pure (time passed in); the app feeds it packets and writes the result.

A download (``Op.LOG_DOWNLOAD``, arg = first chunk) streams chunk i = bytes 12i..12i+11 of the used flash, plus
``LogStatus`` packets that give the total ``used`` and the ``crc32`` of those bytes. Chunks may be lost on the way:
``missing()`` names the first gap, and a new ``LOG_DOWNLOAD`` with that index resumes from it.

The record format inside the bytes (self-describing segments of compressed records, docs/flash_log.md) is part
of the protocol: ``term.core.logformat.decode_log``. Bytes that do not decode are written as a hex dump, one 12-byte
chunk per row, so a download is never lost.
"""

from __future__ import annotations

import csv
import errno
import struct
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from term.core.logformat import decode_log
from term.core.protocol import LOG_CHUNK_BYTES, LogChunk, LogStatus


@dataclass
class LogDownload:
    """The chunks of one download and what the board said about them. ``feed`` packets; ``done`` when every chunk
    up to ``used`` bytes is here. The retry policy around it is ``term.session.download.LogDownloader``."""

    started: float
    used: int | None = None  # bytes, from the LogStatus (or the Ack of LOG_STATUS)
    crc32: int | None = None  # only a LogStatus carries it
    records: int | None = None
    chunks: dict[int, bytes] = field(default_factory=dict)
    last_progress: float = 0.0  # when the last chunk arrived (new or not)
    bytes_received: int = 0  # including duplicates: the transfer rate counts what crossed the link
    n_chunks: int | None = None  # the chunk count from the Ack of LOG_DOWNLOAD, before any LogStatus came
    restarts: int = 0  # the board's log changed under the download (another size or CRC): chunks thrown away

    @property
    def total_chunks(self) -> int | None:
        if self.used is None:
            return self.n_chunks
        return (self.used + LOG_CHUNK_BYTES - 1) // LOG_CHUNK_BYTES

    def feed(self, pkt: Any, now: float) -> bool:
        """Take a LogStatus or LogChunk; returns True if it was one (and so changed the progress). A LogStatus
        that contradicts an earlier one (the log was recorded to or erased in between) starts the chunks afresh:
        old chunks would not match the new CRC-32."""
        if type(pkt) is LogStatus:
            if (self.used is not None and pkt.used != self.used) or (
                self.crc32 is not None and pkt.crc32 != self.crc32
            ):
                self.chunks.clear()
                self.restarts += 1
            self.used, self.crc32, self.records = pkt.used, pkt.crc32, pkt.records
            self.n_chunks = self.total_chunks
            return True
        if type(pkt) is LogChunk:
            self.chunks[pkt.index] = pkt.data
            self.bytes_received += len(pkt.data)
            self.last_progress = now
            return True
        return False

    def set_size(self, *, used: int | None = None, n_chunks: int | None = None) -> bool:
        """What an Ack says about the log's size (LOG_STATUS: bytes used; LOG_DOWNLOAD: chunks), taken only while
        no LogStatus has said it; returns True if it told something new."""
        if used is not None and self.used is None and used >= 0:
            self.used = used
            self.n_chunks = self.total_chunks
            return True
        if n_chunks is not None and self.total_chunks is None and n_chunks >= 0:
            self.n_chunks = n_chunks
            return True
        return False

    @property
    def received(self) -> int:
        """Distinct chunks here (of the ``total_chunks``, when known)."""
        total = self.total_chunks
        return len(self.chunks) if total is None else sum(1 for i in self.chunks if i < total)

    @property
    def fraction(self) -> float:
        total = self.total_chunks
        if not total:
            return 1.0 if total == 0 else 0.0
        return min(1.0, self.received / total)

    def rate_kBps(self, now: float) -> float:
        span = max(now - self.started, 1e-6)
        return self.bytes_received / span / 1000.0

    @property
    def empty(self) -> bool:
        """The board's log holds nothing (its LOG_DOWNLOAD is refused with LOG_EMPTY)."""
        return self.used == 0

    @property
    def done(self) -> bool:
        """Every chunk of ``used`` bytes is here (whether they match the CRC-32 is ``verify``'s question)."""
        total = self.total_chunks
        return self.used is not None and bool(total) and all(i in self.chunks for i in range(total or 0))

    def missing(self) -> int | None:
        """The first chunk not received (where a resumed download starts), or None (all here, or the size is not
        known yet and no gap shows)."""
        total = self.total_chunks
        if total is None:
            if not self.chunks:
                return 0
            gaps = [i for i in range(max(self.chunks)) if i not in self.chunks]
            return gaps[0] if gaps else None
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
        if self.used is None or self.crc32 is None:
            return "the board's LogStatus (size and CRC-32) has not arrived"
        if not self.done:
            return f"incomplete: chunk {self.missing()} of {self.total_chunks} missing"
        got = zlib.crc32(self.data())
        if got != self.crc32:
            return f"CRC-32 mismatch: board {self.crc32:#010x}, received {got:#010x}"
        return None


# --- CSV ------------------------------------------------------------------------------------------------------

Decoder = Callable[[bytes], tuple[Sequence[str], Iterable[Sequence[Any]]]]


def hex_rows(data: bytes) -> tuple[list[str], list[list[Any]]]:
    """The fallback: raw bytes, one chunk per row (offset, hex)."""
    rows = [[off, data[off : off + LOG_CHUNK_BYTES].hex()] for off in range(0, len(data), LOG_CHUNK_BYTES)]
    return ["offset", "hex"], rows


def check_directory(path: Path) -> str | None:
    """Why ``path`` (``~`` allowed) cannot hold downloaded logs, or None. It need not exist yet (the download makes
    it); a NUL character (no file system takes one), an unknown ~user or a file in its place is refused."""
    text = str(path)
    if "\0" in text:
        return f"log folder {text!r} holds a NUL character, which no path can"
    if not text.strip():
        return "log folder: the path is empty"
    try:
        path = path.expanduser()
    except RuntimeError:  # ~someone who is not a user here
        return f"log folder {text}: no such user's home"
    for p in (path, *path.parents):
        try:
            if p.exists():
                return None if p.is_dir() else f"log folder {path}: {p} is a file, not a folder"
        except OSError:
            return None  # not ours to judge (no permission to look): writing will say what is wrong
    return None


def write_csv(data: bytes, path: Path, decoder: Decoder | None = None) -> int:
    """Write the log to ``path`` as CSV (decoded records if a decoder is given); returns the rows written. A path
    that cannot be written is an ``OSError`` with a one-line ``strerror`` (the caller shows it), never another
    exception from deep in the file system calls."""
    why = check_directory(path.parent) or ("the file name holds a NUL character" if "\0" in path.name else None)
    if why:
        raise OSError(errno.EINVAL, why)
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
