"""The byte proxy (``FaultyTransport``) around a real transport, and the frame filter of ``FaultyChannel``: damage
both ways at once, whole frames of one type dropped, everything else passed in order."""

from __future__ import annotations

import asyncio

import pytest

from term.core.protocol import SPEC_OF, Decoder, Encoder, Heartbeat, LogStatus, cobs_decode
from term.transports.loopback import Faults, FaultyChannel, FaultyTransport, loopback_pair

STATUS = LogStatus(0, 1234, 5, 0xDEADBEEF)


def _is_logstatus(frame: bytes) -> bool:
    raw = cobs_decode(frame[:-1])
    return bool(raw) and raw[0] == SPEC_OF[LogStatus].type_id  # type: ignore[index]


def test_the_frame_filter_drops_whole_frames_of_one_type_whatever_the_write_sizes() -> None:
    enc = Encoder()
    packets = [Heartbeat(i, i * 100) if i % 3 else STATUS for i in range(30)]
    stream = b"".join(enc.encode(p) for p in packets)
    ch = FaultyChannel(Faults(drop_frame=_is_logstatus), seed=1)
    for i in range(0, len(stream), 7):  # frames split across writes
        ch.send(stream[i:i + 7], i * 1e-3)
    got = Decoder().feed(ch.receive(1.0))
    assert got == [p for p in packets if type(p) is not LogStatus]
    assert ch.stats.frames_filtered == 10 and ch.stats.bytes_out == len(stream) - 10 * len(enc.encode(STATUS))


async def test_the_proxy_damages_both_ways_and_passes_the_rest() -> None:
    pair = loopback_pair()
    proxy = FaultyTransport(pair.a, Faults(corrupt=1.0), Faults(corrupt=0.0, drop_frame=_is_logstatus), seed=3)
    await proxy.open()
    await pair.b.open()
    await proxy.write(b"\x01\x02\x03\x04")
    up = await asyncio.wait_for(pair.b.read(), 1.0)
    assert len(up) == 4 and all(a != b for a, b in zip(up, b"\x01\x02\x03\x04", strict=True))  # every byte hit
    enc = Encoder()
    await pair.b.write(enc.encode(STATUS) + enc.encode(Heartbeat(7, 700)))
    down = await asyncio.wait_for(proxy.read(), 1.0)
    assert Decoder().feed(down) == [Heartbeat(7, 700)]
    assert proxy.up.stats.bytes_corrupted == 4 and proxy.down.stats.frames_filtered == 1
    await proxy.close()
    await pair.b.close()


def test_the_proxy_refuses_timing_faults() -> None:
    pair = loopback_pair()
    with pytest.raises(ValueError, match="no delay"):
        FaultyTransport(pair.a, Faults(delay=0.01))
