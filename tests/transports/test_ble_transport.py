"""BleTransport, the Transport of term.transports over bleak's API, against the board's radio through our bumble
backend (the simulator's phone-side controller on 127.0.0.1): protocol frames both ways, 20-byte writes,
the handover's consequences, and the one-line errors."""

from __future__ import annotations

import asyncio

import pytest

from fcb_sim.board.wireless import WirelessLink
from fcb_sim.hosts.radio import start_radio
from term.core.protocol import (
    Ack,
    Compact,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Joystick,
    Op,
    WirelessState,
)
from term.transports.base import TransportClosed, TransportError
from term.transports.ble import BleTransport, scan
from tests.support.waits import until


@pytest.fixture
async def board():
    link = WirelessLink()
    decoder = Decoder()
    received: list = []
    lost: list[bool] = []
    radio = await start_radio(
        link,
        board_id=9,
        hci="tcp-server:127.0.0.1:0",
        on_data=lambda data: received.extend(decoder.feed(data)),
        on_disconnect=lost.append,
    )
    radio.received = received  # type: ignore[attr-defined]
    radio.lost = lost  # type: ignore[attr-defined]
    yield radio
    await radio.close()


async def read_packets(transport: BleTransport, count: int) -> list:
    decoder = Decoder()
    packets: list = []
    async with asyncio.timeout(5.0):
        while len(packets) < count:
            packets += decoder.feed(await transport.read())
    return packets


async def test_round_trip_with_protocol_frames(board) -> None:
    link = board.link
    transport = BleTransport(board.address, hci=board.hci.client_spec, timeout=5.0)
    await transport.open()
    try:
        assert transport.name == f"BLE {board.address} via {board.hci.client_spec}"
        await until(lambda: link.is_connected)
        link.request_start()  # the wireless key, pressed on the cable
        link.send(Heartbeat(1, 100))
        assert await read_packets(transport, 1) == [Heartbeat(1, 100)]

        enc = Encoder()
        await transport.write(enc.encode(HeartbeatAck(1, 100)))
        await until(lambda: bool(board.received))
        assert link.state is WirelessState.STARTED

        # Three frames in one write: 42 bytes leave as writes of at most 20 bytes, and arrive whole.
        frames = [enc.encode(Joystick(i, -i, 0, 100 * i, 0)) for i in range(3)]
        before = transport.writes
        await transport.write(b"".join(frames))
        assert transport.writes - before == 3
        await until(lambda: len(board.received) == 4)
        assert board.received[1:] == [Joystick(i, -i, 0, 100 * i, 0) for i in range(3)]

        replies = [Ack(1, Op.MODE, 0, 2)] + [Compact(2, 2, i, i, i, 1100) for i in range(3)] + [Heartbeat(2, 200)]
        for pkt in replies:
            link.send(pkt)
        assert await read_packets(transport, len(replies)) == replies
        assert transport.notifications == link.stats.notifications
    finally:
        await transport.close()
    with pytest.raises(TransportClosed):
        await transport.read()


async def test_a_dropped_connection_is_one_line_and_reopen_reconnects(board) -> None:
    transport = BleTransport(board.address, hci=board.hci.client_spec, timeout=5.0)
    await transport.open()
    await until(lambda: board.link.is_connected)
    await board.device.disconnect(board.connection, reason=0x13)  # the board resets / goes out of range
    with pytest.raises(TransportError) as err:
        await asyncio.wait_for(transport.read(), 5.0)
    assert "lost" in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(TransportError):
        await transport.write(b"\x01")
    await transport.open()  # the reconnect path
    await until(lambda: board.link.is_connected)
    assert transport.is_open
    await transport.close()


async def test_scan_lists_the_board(board) -> None:
    boards = await scan(hci=board.hci.client_spec, timeout=0.2)
    assert [(b.address, b.name) for b in boards] == [(board.address, "Quadrupel 9")]
    assert str(boards[0]) == f"Quadrupel 9      {board.address}  -50 dBm"


async def test_unknown_address(board) -> None:
    transport = BleTransport("F0:5A:00:00:77:77", hci=board.hci.client_spec, timeout=0.3)
    with pytest.raises(TransportError, match="no board with address F0:5A:00:00:77:77 found") as err:
        await transport.open()
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("hci", "text"),
    [
        ("tcp-client:127.0.0.1:1", "cannot open the Bluetooth adapter tcp-client:127.0.0.1:1"),
        ("nonsense:0", "cannot open the Bluetooth adapter nonsense:0"),
    ],
)
async def test_no_adapter(hci: str, text: str) -> None:
    with pytest.raises(TransportError, match=text) as err:
        await BleTransport("F0:5A:00:00:00:01", hci=hci).open()
    assert "\n" not in str(err.value) and "--hci" in str(err.value)
    with pytest.raises(TransportError, match=text):
        await scan(hci=hci, timeout=0.1)


async def test_the_simulator_going_away_is_a_lost_connection(board) -> None:
    """fcb-sim stops (its HCI server closes): the terminal's HCI transport is gone, reads fail in one line."""
    transport = BleTransport(board.address, hci=board.hci.client_spec, timeout=5.0)
    await transport.open()
    await until(lambda: board.link.is_connected)
    await board.hci.close()
    with pytest.raises(TransportError, match="lost") as err:
        await asyncio.wait_for(transport.read(), 5.0)
    assert "\n" not in str(err.value)
    await transport.close()


RADIO_PROCESS = """
import asyncio, sys
from fcb_sim.board.wireless import WirelessLink
from fcb_sim.hosts.radio import start_radio
from term.core.protocol import Heartbeat

async def main():
    link = WirelessLink()
    radio = await start_radio(link, board_id=6, hci="tcp-server:127.0.0.1:0")
    print(radio.hci.client_spec, flush=True)
    counter = 0
    while True:  # hand over as soon as a phone connects, then heartbeat at 10 Hz
        if link.is_connected:
            link.request_start()
        counter += 1
        link.send(Heartbeat(counter, counter * 100))
        await asyncio.sleep(0.1)

asyncio.run(main())
"""


async def test_the_radio_in_another_process() -> None:
    """As with fcb-sim serve --ble-hci: the radio in its own process, the terminal's BLE path in this one."""
    import sys

    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-c", RADIO_PROCESS, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.DEVNULL
    )
    try:
        spec = (await asyncio.wait_for(proc.stdout.readline(), 20.0)).decode().strip()
        assert spec.startswith("tcp-client:127.0.0.1:")
        [found] = await scan(hci=spec, timeout=0.3)
        assert found.name == "Quadrupel 6"
        transport = BleTransport(found.address, hci=spec, timeout=5.0)
        await transport.open()
        try:
            packets = await read_packets(transport, 1)
            assert type(packets[0]) is Heartbeat
        finally:
            await transport.close()
    finally:
        proc.kill()
        await proc.wait()
