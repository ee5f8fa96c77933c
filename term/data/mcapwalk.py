"""The records of an MCAP file read from memory, with damage skipped (term/data/recording.py reads sessions with it).

Contract: ``Walk(raw, damage).records()`` yields the records of ``raw`` (the whole file, magic included) as small
tuples: ``("m", channel id, log time, data)``, ``("c", id, topic)``, ``("meta", name, map)``, ``("footer",)``; a
chunk's records in its place (decompressed, its CRC checked). A closed file's channel records are yielded first,
from its summary (found through its footer), so a channel whose own record was in a damaged chunk keeps its
messages. Then, in file order:

- a cut-short tail (a record with a known opcode running past the end, nothing readable after it; or zeros never
  written) ends the walk, not an error (``complete`` False);
- a chunk whose CRC or compression fails, or a record that does not parse, is skipped whole (its length is known)
  and appended to ``damage`` as a ``Damage(start, end, what)``;
- bytes that are no record (an unknown opcode, a length past the end with records after it, a first record that
  is no Header) are skipped to where records start again: a record that fits followed by another that fits or by
  the end of the file (noise passes that about once in 10^30 tries);
- the footer ends the walk (``complete`` True). ``pos``: where the readable part ends; ``read_any``: whether a
  record besides the header was read (a file with damage and nothing read is for the caller to refuse).

Sizes are checked before anything is allocated: a chunk claiming more than ``CHUNK_MAX_BYTES`` decompressed is
damage, never an allocation.
"""

from __future__ import annotations

import re
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.opcode import Opcode

MAGIC = b"\x89MCAP0\r\n"
RECORD_MAX_BYTES = 64 * 1024 * 1024  # no record of a session file is longer than a part may be (MAX_FILE_BYTES)


@dataclass(frozen=True)
class Damage:
    """Bytes ``start``..``end`` of a file that were skipped: ``what`` they should have been."""

    start: int
    end: int
    what: str


def damage_text(path: Path, damage: list[Damage], orphans: int = 0) -> str:
    """``path``'s skipped damage in one line: how many places, where the first is, the bytes lost."""
    if not damage and not orphans:
        return ""
    parts = []
    if damage:
        first = damage[0]
        lost = sum(d.end - d.start for d in damage)
        parts.append(f"{len(damage)} damaged part{'s' * (len(damage) > 1)} skipped ({lost:,} bytes; the first "
                     f"at byte {first.start:,}: {first.what})")
    if orphans:
        parts.append(f"{orphans:,} messages of a channel whose record was lost")
    return f"{path.name}: " + ", ".join(parts)


_HEAD = struct.Struct("<BQ")  # a record's opcode and length
_INSIDE = [0]  # _walk's ``at`` inside a chunk
CHUNK_MAX_BYTES = 64 * 1024 * 1024  # a chunk's records, decompressed (the recorder's and the exports' are ~1 MB)
_MSG = struct.Struct("<HIQQ")  # a Message's channel id, sequence, log time, publish time
_CHUNK = struct.Struct("<QQQI")  # a Chunk's start and end times, uncompressed size and CRC


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return str(buf[pos + 4 : pos + 4 + n], "utf-8"), pos + 4 + n


def _map(buf: memoryview, pos: int) -> dict[str, str]:
    (n,) = struct.unpack_from("<I", buf, pos)
    out, end, pos = {}, pos + 4 + n, pos + 4
    while pos < end:
        k, pos = _string(buf, pos)
        out[k], pos = _string(buf, pos)
    return out


def _decompress(compression: str, data: memoryview, size: int) -> bytes:
    if compression == "":
        return bytes(data)
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.decompress(data)  # type: ignore[no-any-return]
    raise ValueError(f"unknown compression {compression!r}")


def _walk(buf: memoryview, start: int, end: int, at: list[int]) -> Iterator[tuple[Any, ...]]:
    """The records of ``buf[start:end]`` as small tuples: ("m", channel id, log time, data), ("c", id, topic),
    ("meta", name, map), ("footer",); a chunk's records in its place (decompressed, its CRC checked). ``at[0]``
    is where the record being read starts (for an error's message)."""
    pos = start
    while pos < end:
        at[0] = pos
        opcode, length = _HEAD.unpack_from(buf, pos)
        body = pos + 9
        pos = body + length
        if opcode == Opcode.MESSAGE:
            ch, _, log_time, _ = _MSG.unpack_from(buf, body)
            yield ("m", ch, log_time, bytes(buf[body + 22 : pos]))
        elif opcode == Opcode.CHUNK and at is not _INSIDE:  # (a chunk holds no chunk: no nesting to recurse on)
            _, _, size, crc = _CHUNK.unpack_from(buf, body)
            if size > CHUNK_MAX_BYTES:  # a hostile size would be allocated before a byte is checked
                raise ValueError("chunk too large")
            compression, q = _string(buf, body + 28)
            (n,) = struct.unpack_from("<Q", buf, q)
            inner = _decompress(compression, buf[q + 8 : q + 8 + n], size)
            if len(inner) != size or (crc and zlib.crc32(inner) != crc):
                raise ValueError("chunk CRC")
            yield from _walk(memoryview(inner), 0, len(inner), _INSIDE)
        elif opcode == Opcode.CHANNEL:
            (cid,) = struct.unpack_from("<H", buf, body)
            topic, _ = _string(buf, body + 4)
            yield ("c", cid, topic)
        elif opcode == Opcode.METADATA:
            name, q = _string(buf, body)
            yield ("meta", name, _map(buf, q))
        elif opcode == Opcode.FOOTER:
            yield ("footer",)
            return


_OPCODES = frozenset(int(op) for op in Opcode)
_CANDIDATE = re.compile(rb"[\x01-\x0f]")  # a byte that could open a record (MCAP's opcodes)


def _fits(buf: memoryview, pos: int, end: int) -> int | None:
    """Where the record that ``buf[pos]`` would open ends, if it has a known opcode and fits the file; else None."""
    if pos + 9 > end:
        return None
    opcode, length = _HEAD.unpack_from(buf, pos)
    nxt = pos + 9 + length
    return nxt if opcode in _OPCODES and nxt <= end else None


def _resync(buf: memoryview, raw: bytes, pos: int, end: int) -> int | None:
    """The first offset from ``pos`` where records start again: a record that fits, followed by another that fits
    or by the end of the file (two in a row: random bytes pass that about once in 10^30 tries)."""
    for m in _CANDIDATE.finditer(raw, pos, end):
        p = m.start()
        nxt = _fits(buf, p, end)
        if nxt is not None and (nxt == end or _fits(buf, nxt, end) is not None):
            return p
    return None


def _summary_channels(buf: memoryview, end: int) -> list[tuple[Any, ...]]:
    """The channel records of a closed file's summary section (found through its footer), so a channel whose
    record was in a damaged chunk still has its messages read; [] if the file has no usable footer."""
    try:
        if bytes(buf[end - len(MAGIC) : end]) != MAGIC:
            return []
        footer = end - len(MAGIC) - 29
        opcode, length, start = struct.unpack_from("<BQQ", buf, footer)
        if opcode != Opcode.FOOTER or length != 20 or not len(MAGIC) <= start <= footer:
            return []
        return [r for r in _walk(buf, start, footer, [0]) if r[0] == "c"]
    except (struct.error, ValueError, UnicodeDecodeError):
        return []


class Walk:
    """One pass over a file's records (module docstring)."""

    def __init__(self, raw: bytes, damage: list[Damage]) -> None:
        self.raw = raw
        self.damage = damage
        self.pos = len(MAGIC)
        self.complete = False
        self.read_any = False

    def records(self) -> Iterator[tuple[Any, ...]]:
        raw = self.raw
        buf, end, pos = memoryview(raw), len(raw), len(MAGIC)
        yield from _summary_channels(buf, end)
        while pos + 9 <= end:
            opcode, length = _HEAD.unpack_from(buf, pos)
            nxt = pos + 9 + length
            if opcode == 0 and not raw[pos:].strip(b"\0"):
                break  # zeros: a tail never written
            if opcode not in _OPCODES or nxt > end or (pos == len(MAGIC) and opcode != Opcode.HEADER):
                again = _resync(buf, raw, pos + 1, end)
                if again is None and opcode in _OPCODES and length <= RECORD_MAX_BYTES and pos > len(MAGIC):
                    break  # the record being written when the recorder stopped (a crash): cut short
                what = ("the header record" if pos == len(MAGIC) else "a record") + (
                    f" (opcode {opcode:#04x}, {length:,} bytes in a file of {end:,})")
                self.damage.append(Damage(pos, again if again is not None else end, what))
                if again is None:
                    pos = end
                    break
                pos = again
                continue
            try:
                records = list(_walk(buf, pos, nxt, [pos]))
            except Exception as exc:  # a damaged chunk (CRC, zstd) or record: skipped whole, the next one read
                self.damage.append(Damage(pos, nxt, f"{Opcode(opcode).name.lower()} ({type(exc).__name__})"))
                pos = nxt
                continue
            self.read_any = self.read_any or opcode != Opcode.HEADER
            pos = nxt
            self.pos = pos
            yield from records
            if opcode == Opcode.FOOTER:
                self.complete = True
                break
        self.pos = pos
