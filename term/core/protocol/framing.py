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
    text_bytes: int = 0  # text outside frames (a Decoder with keep_text): not damage, not in bytes_skipped

    @property
    def frames_bad(self) -> int:
        return self.crc_errors + self.malformed


# What a board prints outside frames (printf on the UART): printable ASCII, tab, CR and LF. A frame's first byte
# (its COBS code, at most MAX_FRAME - 1) is a control byte, so a piece that starts printable is no frame's start.
_TEXT_BYTES = b"\t\n\r" + bytes(range(0x20, 0x7F))
_PRINTABLE = frozenset(range(0x20, 0x7F))


def _is_text(data: bytes) -> bool:
    return not data.translate(None, _TEXT_BYTES)


class Decoder:
    """A streaming decoder: ``feed`` any chunking of the byte stream, get the packets in it.

    Never raises on bad input; what it drops is counted in ``stats``.

    ``keep_text``: the terminal's decoder also keeps the text a board prints between frames (printf on the UART;
    ``take_text``): a run of text bytes before a delimiter is text, and so is text followed by a whole frame with
    no delimiter between them (the frame is decoded, not lost); a pending run that is text and ends in a newline is
    handed out at once (a board that prints and stops); an over-long run of text is handed out as it comes. Text is
    counted in ``stats.text_bytes``, not as damage. Without it (the board's decoder, the C codec's twin) every byte
    outside a good frame is skipped and counted, exactly as the C decoder does.
    """

    # Anything longer than a frame without a delimiter is garbage: keep at most this many pending bytes.
    _MAX_PENDING = MAX_FRAME - 1

    def __init__(self, keep_text: bool = False) -> None:
        self.stats = DecoderStats()
        self._text: bytearray | None = bytearray() if keep_text else None
        self._pending = b""
        self._discarding = False  # inside an over-long run: drop bytes up to the next delimiter
        self._joined = False  # a delimiter has been seen: what follows starts on a frame boundary
        self._last_seq: int | None = None

    def take_text(self) -> bytes:
        """The text outside frames since the last call (always empty without ``keep_text``)."""
        if not self._text:
            return b""
        out = bytes(self._text)
        self._text.clear()
        return out

    def feed(self, data: bytes) -> list[Any]:
        if self._text is not None:
            return self._feed_text(data)
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

    def _feed_text(self, data: bytes) -> list[Any]:
        """``feed`` of a decoder that keeps text: piece by piece, a failed piece looked at again for text."""
        stats, text = self.stats, self._text
        assert text is not None
        stats.bytes_in += len(data)
        if self._pending:
            data = self._pending + data
        pieces = data.split(b"\x00")
        tail = pieces.pop()
        out: list[Any] = []
        if pieces and self._joined and not self._discarding:  # the usual case, frames only: the batch decode
            packets, crc_fail, mal, skipped, gaps, last = _decode_pieces(pieces, self._last_seq)
            if not crc_fail and not mal:
                stats.frames_ok += len(packets)
                stats.seq_gaps += gaps
                self._last_seq = last
                out, pieces = packets, []
        for piece in pieces:
            if self._discarding:
                stats.bytes_skipped += len(piece) + 1
                self._discarding = False
                continue
            first = not self._joined
            self._joined = True
            if not piece:
                continue
            if self._decode_one(piece, out, count_bad=False):
                continue
            head, frame = _split_text(piece)
            if head is not None:
                text += head
                stats.text_bytes += len(head)
                if frame:
                    self._decode_one(frame, out, count_bad=True)
                continue
            if first:  # joined mid-frame: the tail of a frame, not damage (as feed)
                stats.bytes_skipped += len(piece) + 1
                continue
            self._decode_one(piece, out, count_bad=True)
        if self._discarding:
            stats.bytes_skipped += len(tail)
            tail = b""
        elif len(tail) > self._MAX_PENDING:
            head, tail = tail[: -self._MAX_PENDING], tail[-self._MAX_PENDING :]
            if _is_text(head):  # a long line: out as it comes; a frame may start in the last MAX_FRAME - 1 bytes
                text += head
                stats.text_bytes += len(head)
            else:
                stats.bytes_skipped += len(head) + len(tail)
                tail = b""
                self._discarding = True
        if tail and tail[-1] == 0x0A and tail[0] in _PRINTABLE and _is_text(tail):
            text += tail  # a whole line and nothing after it: a board that printed and went quiet
            stats.text_bytes += len(tail)
            tail = b""
        self._pending = tail
        return out

    def _decode_one(self, piece: bytes, out: list[Any], count_bad: bool) -> bool:
        """Decode one delimiter-free piece into ``out``; its damage counted only if ``count_bad``."""
        stats = self.stats
        packets, crc_fail, mal, skipped, gaps, last = _decode_pieces([piece], self._last_seq)
        if packets:
            out += packets
            stats.frames_ok += 1
            stats.seq_gaps += gaps
            self._last_seq = last
            return True
        if count_bad:
            stats.crc_errors += crc_fail
            stats.malformed += mal
            stats.bytes_skipped += skipped
        return False

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


_PIECE_SIZES: tuple[int, ...] = ()  # a whole frame's length without its delimiter, per packet size (filled lazily)


def _split_text(piece: bytes) -> tuple[bytes | None, bytes]:
    """A piece that failed as a frame, looked at as text: ``(text, frame)`` where ``piece`` is text followed by a
    whole valid frame (or only text: ``frame`` empty); ``(None, b"")`` if it is neither."""
    global _PIECE_SIZES
    if not _PIECE_SIZES:
        _PIECE_SIZES = tuple(sorted({spec.struct.size + 5 for spec in PACKETS.values()}))
    n = len(piece)
    if _is_text(piece):
        return piece, b""
    for size in _PIECE_SIZES:
        k = n - size
        if k <= 0:
            break
        head = piece[:k]
        if _is_text(head) and _decode_pieces([piece[k:]], None)[0]:
            return head, piece[k:]
    return None, b""


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
