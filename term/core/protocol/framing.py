"""Framing: ``COBS(type | seq | body | crc16) 0x00``, the encoder, the streaming decoder and its statistics, and
the dict form of packets (recordings, test vectors).
"""

from __future__ import annotations

import binascii
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from term.core.protocol.facts import CRC_INIT, DELIMITER, MAX_FRAME
from term.core.protocol.packets import PACKETS, SPEC_OF

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
