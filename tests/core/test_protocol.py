"""The codec: vectors both ways, framing properties under chunking, garbage, corruption and loss."""

from __future__ import annotations

import json
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from term.core import protocol as p
from tests.support.paths import VECTORS

VECTORS = json.loads((VECTORS / "protocol.json").read_text())

# --- strategies built from the packet table itself ----------------------------------------------------------

_INT_RANGES = {
    "B": (0, 0xFF),
    "b": (-0x80, 0x7F),
    "H": (0, 0xFFFF),
    "h": (-0x8000, 0x7FFF),
    "I": (0, 0xFFFFFFFF),
    "i": (-0x80000000, 0x7FFFFFFF),
}


def _field_strategy(fmt: str) -> st.SearchStrategy:
    if fmt in _INT_RANGES:
        lo, hi = _INT_RANGES[fmt]
        return st.integers(lo, hi)
    if fmt == "e":  # half floats: only values a half float holds exactly round-trip
        return st.floats(width=16, allow_nan=False)
    if fmt.endswith("s"):
        n = int(fmt[:-1])
        return st.binary(min_size=n, max_size=n)
    raise AssertionError(f"no strategy for {fmt}")


def _packet_strategy(spec: p.PacketSpec) -> st.SearchStrategy:
    return st.builds(spec.cls, *[_field_strategy(fs.fmt) for fs in spec.fields])


packets = st.one_of([_packet_strategy(spec) for spec in p.PACKETS.values()])


def _chunked(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    bounds = [0, *points, len(data)]
    return [data[a:b] for a, b in zip(bounds, bounds[1:], strict=False)]


def _is_subsequence(got: list, sent: list) -> bool:
    it = iter(sent)
    return all(any(g == s for s in it) for g in got)


# --- vectors ------------------------------------------------------------------------------------------------


def test_vectors_cover_every_packet_type() -> None:
    assert {v["packet"]["type"] for v in VECTORS} == {spec.cls.__name__ for spec in p.PACKETS.values()}


@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v["packet"]["type"])
def test_vector_encodes_to_its_bytes(vector: dict) -> None:
    assert p.encode(p.from_dict(vector["packet"]), vector["seq"]).hex() == vector["hex"]


@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v["packet"]["type"])
def test_vector_bytes_decode_to_its_packet(vector: dict) -> None:
    frame = bytes.fromhex(vector["hex"])
    assert p.decode_frame(frame) == p.from_dict(vector["packet"])
    assert p.frame_seq(frame) == vector["seq"]


def test_crc_is_ccitt_false() -> None:
    # The catalogued check value of CRC-16/CCITT-FALSE.
    import binascii

    assert binascii.crc_hqx(b"123456789", p.CRC_INIT) == 0x29B1


# --- framing properties -------------------------------------------------------------------------------------


@given(packets)
def test_every_frame_fits_one_notification(pkt) -> None:
    frame = p.encode(pkt, 255)
    assert len(frame) <= p.MAX_FRAME
    assert len(frame) == p.SPEC_OF[type(pkt)].frame_size
    assert frame.index(0) == len(frame) - 1  # the delimiter is the only zero


def test_frame_size_of_every_type_is_within_limit() -> None:
    assert max(spec.frame_size for spec in p.PACKETS.values()) <= p.MAX_FRAME


@given(st.lists(packets, max_size=30), st.lists(st.integers(0, 10_000), max_size=40))
def test_round_trip_under_any_chunking(sent, cuts) -> None:
    stream = p.Encoder().encode_many(sent)
    dec = p.Decoder()
    got = [pkt for chunk in _chunked(stream, cuts) for pkt in dec.feed(chunk)]
    assert got == sent
    assert dec.stats.frames_ok == len(sent)
    assert dec.stats.frames_bad == dec.stats.bytes_skipped == dec.stats.seq_gaps == 0


@given(st.lists(st.tuples(st.binary(max_size=40), packets), max_size=15), st.binary(max_size=40),
       st.lists(st.integers(0, 10_000), max_size=20))
def test_garbage_never_raises_nor_invents_packets(pairs, trailing, cuts) -> None:
    enc = p.Encoder()
    stream = b"".join(garbage + enc.encode(pkt) for garbage, pkt in pairs) + trailing
    sent = [pkt for _, pkt in pairs]
    dec = p.Decoder()
    got = [pkt for chunk in _chunked(stream, cuts) for pkt in dec.feed(chunk)]
    assert _is_subsequence(got, sent)


@given(st.lists(packets, min_size=1, max_size=20), st.data())
def test_one_corrupted_byte_costs_at_most_two_frames(sent, data) -> None:
    stream = bytearray(p.Encoder().encode_many(sent))
    where = data.draw(st.integers(0, len(stream) - 1))
    stream[where] ^= data.draw(st.integers(1, 255))
    got = p.Decoder().feed(bytes(stream))
    assert _is_subsequence(got, sent)
    assert len(got) >= len(sent) - 2


@given(st.lists(packets, min_size=1, max_size=20), st.data())
def test_one_lost_or_inserted_byte_costs_at_most_two_frames(sent, data) -> None:
    stream = bytearray(p.Encoder().encode_many(sent))
    where = data.draw(st.integers(0, len(stream) - 1))
    if data.draw(st.booleans()):
        del stream[where]
    else:
        stream.insert(where, data.draw(st.integers(0, 255)))
    got = p.Decoder().feed(bytes(stream))
    assert _is_subsequence(got, sent)
    assert len(got) >= len(sent) - 2


@settings(max_examples=50)
@given(st.integers(2, 700), st.data())
def test_sequence_gaps_are_counted_modulo_256(total, data) -> None:
    enc = p.Encoder()
    frames = [enc.encode(p.Heartbeat(i & 0xFFFF, i)) for i in range(total)]
    drawn = sorted(data.draw(st.sets(st.integers(0, total - 1), min_size=1)))
    # A run of 256 or more lost frames is indistinguishable from none: keep every gap shorter.
    kept: list[int] = []
    for k in drawn:
        while kept and k - kept[-1] > 255:
            kept.append(kept[-1] + 200)
        kept.append(k)
    dec = p.Decoder()
    dec.feed(b"".join(frames[i] for i in kept))
    assert dec.stats.seq_gaps == (kept[-1] - kept[0] + 1) - len(kept)


# --- decoder details ----------------------------------------------------------------------------------------


def test_overlong_run_without_delimiter_is_skipped_then_resyncs() -> None:
    dec = p.Decoder()
    assert dec.feed(b"\x01" * 100) == []
    assert dec.feed(b"\x01" * 5) == []  # still inside the garbage run
    pkt = p.Joystick(1, 2, 3, 4, 0)
    assert dec.feed(b"\x00" + p.encode(pkt)) == [pkt]
    assert dec.stats.bytes_skipped == 106


def test_joining_mid_frame_is_not_damage() -> None:
    frame = p.encode(p.Heartbeat(1, 2))
    dec = p.Decoder()
    assert dec.feed(frame[5:] + frame) == [p.Heartbeat(1, 2)]  # the tail of a frame we missed the start of
    assert dec.stats.frames_bad == 0 and dec.stats.bytes_skipped == len(frame) - 5
    assert dec.feed(frame[5:] + frame) == [p.Heartbeat(1, 2)]  # later, the same tail is a damaged frame
    assert dec.stats.frames_bad == 1


def test_wrong_length_and_unknown_type_are_malformed() -> None:
    dec = p.Decoder()
    dec.feed(b"\x00")  # joined: what follows starts on a frame boundary
    raw = bytes((0xEE, 0)) + b"\x01\x02\x03"
    import binascii

    raw += binascii.crc_hqx(raw, p.CRC_INIT).to_bytes(2, "big")
    assert dec.feed(p.cobs_encode(raw) + b"\x00") == []
    assert dec.stats.malformed == 1 and dec.stats.crc_errors == 0


def test_crc_failure_is_counted() -> None:
    frame = bytearray(p.encode(p.Heartbeat(1, 2)))
    frame[3] ^= 0x40
    dec = p.Decoder()
    dec.feed(p.encode(p.Heartbeat(0, 0)))
    assert dec.feed(bytes(frame)) == []
    assert dec.stats.crc_errors == 1


def test_packets_of_different_types_are_never_equal() -> None:
    assert p.Heartbeat(1, 2) != p.HeartbeatAck(1, 2)
    assert p.Heartbeat(1, 2) == p.Heartbeat(1, 2)
    assert len({p.Heartbeat(1, 2), p.HeartbeatAck(1, 2), p.Heartbeat(1, 2)}) == 2


@pytest.mark.parametrize("bad", [p.Joystick(40000, 0, 0, 0, 0), p.Command(1, 300, 0), "not a packet"])
def test_encode_refuses_what_it_cannot_send(bad) -> None:
    with pytest.raises(p.ProtocolError):
        p.encode(bad)


@given(st.binary(max_size=30))
def test_cobs_round_trip(raw: bytes) -> None:
    enc = p.cobs_encode(raw)
    assert b"\x00" not in enc
    assert p.cobs_decode(enc) == raw


def test_encoder_counts_and_wraps_sequence() -> None:
    enc = p.Encoder()
    frames = [enc.encode(p.Heartbeat(0, 0)) for _ in range(257)]
    assert [p.frame_seq(f) for f in frames[254:]] == [254, 255, 0]
    assert enc.frames == 257 and enc.bytes == sum(map(len, frames))


def test_body_layout_is_little_endian() -> None:
    frame = p.encode(p.Heartbeat(0x0102, 0x03040506), 0)
    raw = p.cobs_decode(frame[:-1])
    assert raw is not None
    assert raw[2:8] == struct.pack("<HI", 0x0102, 0x03040506)
