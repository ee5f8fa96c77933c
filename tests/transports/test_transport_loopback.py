"""The faulty loopback: the sans-IO FaultyChannel on a fake clock, and the asyncio pair on the real one."""

from __future__ import annotations

import asyncio

import pytest

from term.core.protocol import Decoder, Encoder, Status
from term.transports.base import TransportClosed, TransportError
from term.transports.loopback import Faults, FaultyChannel, loopback_pair


def frames(n: int) -> tuple[bytes, list]:
    enc = Encoder()
    pkts = [Status(0, k & 0x7FFF, 0, 0, 0, 0, 0, 0) for k in range(n)]
    return enc.encode_many(pkts), pkts


def test_no_faults_delivers_everything_at_once_unchanged() -> None:
    ch = FaultyChannel()
    ch.send(b"\x01\x02\x00abc", 5.0)
    assert ch.next_arrival() == 5.0
    assert ch.receive(5.0) == b"\x01\x02\x00abc"
    assert ch.receive(6.0) == b"" and ch.next_arrival() is None


def test_pacing_spreads_bytes_at_ten_bits_each_and_queues_bursts() -> None:
    ch = FaultyChannel(baud=1000)  # 10 ms per byte
    ch.send(b"abcd", 0.0)
    assert ch.next_arrival() == pytest.approx(0.01)
    assert ch.receive(0.0099) == b""
    assert ch.receive(0.0201) == b"ab"  # a UART read in the middle of a burst gets part of it
    ch.send(b"ef", 0.021)  # the wire is still busy with c and d: e and f follow them
    assert ch.receive(0.0399) == b"c"
    assert ch.receive(0.0401) == b"d"
    assert ch.receive(0.0599) == b"e"
    assert ch.receive(0.0601) == b"f"
    ch.send(b"g", 1.0)  # an idle wire starts at once
    assert ch.next_arrival() == pytest.approx(1.01)


def test_pacing_at_115200_gives_the_line_rate() -> None:
    ch = FaultyChannel(baud=115200)
    data, _ = frames(1000)
    ch.send(data, 0.0)
    got = ch.receive(1.0)
    assert len(got) == pytest.approx(11520, abs=1)  # 11,520 bytes per second at 8N1
    assert got == data[: len(got)]


def test_delay_holds_bytes_back_and_jitter_never_reorders() -> None:
    ch = FaultyChannel(delay=0.05)
    ch.send(b"xy", 1.0)
    assert ch.receive(1.0499) == b"" and ch.receive(1.05) == b"xy"
    jit = FaultyChannel(delay=0.01, jitter=0.02, seed=3)
    data = bytes(range(1, 200))
    for k, b in enumerate(data):
        jit.send(bytes([b]), k * 0.001)
    out = b"".join(jit.receive(t / 1000) for t in range(400))
    assert out == data


def test_frame_drops_lose_whole_frames_at_the_set_rate() -> None:
    data, pkts = frames(5000)
    ch = FaultyChannel(drop=0.1, seed=1)
    ch.send(data, 0.0)
    dec = Decoder()
    got = dec.feed(ch.receive(0.0))
    assert ch.stats.frames_in == 5000
    assert 0.085 < ch.stats.frames_dropped / 5000 < 0.115
    assert len(got) == 5000 - ch.stats.frames_dropped
    assert dec.stats.frames_bad == 0  # whole frames vanish: nothing torn
    assert dec.stats.seq_gaps == ch.stats.frames_dropped or dec.stats.seq_gaps == ch.stats.frames_dropped - 1
    assert set(got) <= set(pkts)


def test_byte_drops_and_corruption_never_produce_a_packet_that_was_not_sent() -> None:
    data, pkts = frames(3000)
    sent = set(pkts)
    for faults in (Faults(drop=0.01, drop_unit="byte"), Faults(corrupt=0.01)):
        ch = FaultyChannel(faults, seed=2)
        ch.send(data, 0.0)
        dec = Decoder()
        got = dec.feed(ch.receive(0.0))
        assert set(got) <= sent
        damaged = ch.stats.bytes_dropped + ch.stats.bytes_corrupted
        assert 300 < damaged < 900  # ~1 % of 57,000 bytes
        assert len(got) >= 3000 - 2 * damaged  # a damaged byte costs at most two frames
        assert dec.stats.frames_bad > 0 or dec.stats.bytes_skipped > 0


def test_same_seed_same_faults() -> None:
    data, _ = frames(500)

    def run(seed: int) -> bytes:
        ch = FaultyChannel(drop=0.1, corrupt=0.01, jitter=0.01, seed=seed)
        ch.send(data, 0.0)
        return ch.receive(1.0)

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_bad_fault_settings_are_refused() -> None:
    for kwargs in ({"drop": 1.5}, {"corrupt": -0.1}, {"delay": -1.0}, {"baud": 0}, {"drop_unit": "bit"}):
        with pytest.raises(ValueError):
            Faults(**kwargs)  # type: ignore[arg-type]


# --- the asyncio pair ---------------------------------------------------------------------------------------


async def test_pair_moves_bytes_both_ways() -> None:
    a, b = loopback_pair()
    await a.open()
    await b.open()
    await a.write(b"ping\x00")
    assert await asyncio.wait_for(b.read(), 1.0) == b"ping\x00"
    await b.write(b"pong\x00")
    assert await asyncio.wait_for(a.read(), 1.0) == b"pong\x00"


async def test_pair_delivers_after_the_delay_without_polling() -> None:
    loop = asyncio.get_running_loop()
    a, b = loopback_pair(delay=0.03, clock=loop.time)
    await a.open()
    await b.open()
    reader = asyncio.create_task(b.read())  # already waiting when the bytes are sent
    await asyncio.sleep(0)
    t0 = loop.time()
    await a.write(b"late\x00")
    assert await asyncio.wait_for(reader, 1.0) == b"late\x00"
    assert loop.time() - t0 >= 0.03  # not before its time (never faster; how much later is not asserted)


async def test_peer_close_ends_reads_and_writes_with_transport_error() -> None:
    a, b = loopback_pair()
    await a.open()
    await b.open()
    reader = asyncio.create_task(a.read())
    await asyncio.sleep(0)
    await b.close()
    with pytest.raises(TransportError, match="other end closed") as exc:
        await asyncio.wait_for(reader, 1.0)
    assert not isinstance(exc.value, TransportClosed) and "\n" not in str(exc.value)
    with pytest.raises(TransportError, match="other end closed"):
        await a.write(b"x")


async def test_own_close_is_idempotent_and_wakes_a_pending_read() -> None:
    a, b = loopback_pair()
    await a.open()
    await b.open()
    reader = asyncio.create_task(a.read())
    await asyncio.sleep(0)
    await a.close()
    await a.close()
    with pytest.raises(TransportClosed):
        await asyncio.wait_for(reader, 1.0)


async def test_pair_bytes_sent_before_peer_close_are_still_read() -> None:
    a, b = loopback_pair()
    await a.open()
    await b.open()
    await b.write(b"last words\x00")
    await b.close()
    assert await a.read() == b"last words\x00"
    with pytest.raises(TransportError):
        await a.read()
