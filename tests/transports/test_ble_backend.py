"""Our bleak backend on bumble, through bleak's own API (BleakScanner, BleakClient), against the board's radio:
the simulator's second controller served as an HCI transport over TCP on 127.0.0.1, all in one process."""

from __future__ import annotations

import pytest
from bleak import BleakClient, BleakScanner
from bleak.exc import BleakDeviceNotFoundError, BleakError

from fcb_sim.board.wireless import WirelessLink
from fcb_sim.hosts.radio import start_radio
from term.core.protocol import (
    NUS_RX,
    NUS_SERVICE,
    NUS_TX,
    Ack,
    Compact,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    WirelessState,
)
from term.transports.bumble_backend import BumbleClient, BumbleHost, BumbleScanner
from tests.support.waits import until


@pytest.fixture
async def board():
    """The board's radio with its phone-side controller on tcp-server:127.0.0.1:<free port>."""
    link = WirelessLink()
    parsed: list[bytes] = []
    lost: list[bool] = []
    radio = await start_radio(
        link, board_id=5, hci="tcp-server:127.0.0.1:0", on_data=parsed.append, on_disconnect=lost.append
    )
    radio.parsed = parsed  # type: ignore[attr-defined]
    radio.lost = lost  # type: ignore[attr-defined]
    yield radio
    await radio.close()
    assert BumbleHost._open == {} or all(h.users == 0 for h in BumbleHost._open.values())


async def test_scan_connect_write_and_notify_through_bleak(board) -> None:
    hci = board.hci.client_spec
    found = await BleakScanner.find_device_by_name("Quadrupel 5", timeout=5.0, backend=BumbleScanner, hci=hci)
    assert found is not None and found.address == board.address

    link = board.link
    notes: list[bytearray] = []
    disconnected: list[BleakClient] = []
    client = BleakClient(found, disconnected.append, backend=BumbleClient, hci=hci)
    await client.connect()
    try:
        assert client.is_connected and client.mtu_size == 23
        service = client.services.get_service(NUS_SERVICE)
        assert service is not None
        rx = service.get_characteristic(NUS_RX)
        tx = service.get_characteristic(NUS_TX)
        assert "write-without-response" in rx.properties and "notify" in tx.properties
        assert rx.max_write_without_response_size == 20
        await client.start_notify(tx, lambda _char, data: notes.append(data))
        await until(lambda: link.is_connected)

        link.request_start()
        link.send(Heartbeat(1, 100))
        await until(lambda: len(notes) == 1)
        assert Decoder().feed(bytes(notes[0])) == [Heartbeat(1, 100)]

        answer = Encoder().encode(HeartbeatAck(1, 100))
        await client.write_gatt_char(NUS_RX, answer, response=False)
        await until(lambda: bool(board.parsed))
        assert board.parsed == [answer] and link.state is WirelessState.STARTED

        sent = [Compact(0, 2, i, i, i, 1150) for i in range(3)] + [Ack(i, 1, 0, i) for i in range(4)]
        sent.append(Heartbeat(2, 200))
        for pkt in sent:
            link.send(pkt)
        await until(lambda: len(notes) == 1 + link.stats.notifications - 1)
        assert all(len(n) <= 20 for n in notes)
        assert Decoder().feed(b"".join(bytes(n) for n in notes[1:])) == sent
    finally:
        await client.disconnect()
    assert not client.is_connected
    await until(lambda: bool(board.lost))
    assert board.lost == [True] and board.link.state is WirelessState.DISCONNECTED
    assert disconnected == []  # we asked for it: not an unsolicited disconnection


async def test_discover_reports_the_board_with_its_name(board) -> None:
    seen = await BleakScanner.discover(0.2, return_adv=True, backend=BumbleScanner, hci=board.hci.client_spec)
    assert board.address in seen
    device, adv = seen[board.address]
    assert device.name == adv.local_name == "Quadrupel 5"
    assert adv.rssi < 0


async def test_connect_by_address_string_scans_for_it(board) -> None:
    async with BleakClient(board.address, backend=BumbleClient, hci=board.hci.client_spec, timeout=5.0) as c:
        assert c.services.get_characteristic(NUS_TX) is not None
        await until(lambda: board.link.is_connected)


async def test_the_board_going_away_disconnects_the_client(board) -> None:
    hci = board.hci.client_spec
    disconnected: list[BleakClient] = []
    client = BleakClient(board.address, disconnected.append, backend=BumbleClient, hci=hci, timeout=5.0)
    await client.connect()
    await until(lambda: board.link.is_connected)
    await board.device.disconnect(board.connection, reason=0x13)
    await until(lambda: bool(disconnected))
    assert disconnected == [client] and not client.is_connected


async def test_unknown_address_is_not_found(board) -> None:
    client = BleakClient("F0:5A:00:00:99:99", backend=BumbleClient, hci=board.hci.client_spec, timeout=0.3)
    with pytest.raises(BleakDeviceNotFoundError, match="F0:5A:00:00:99:99"):
        await client.connect()


async def test_no_adapter_is_one_clear_error() -> None:
    with pytest.raises(BleakError, match=r"cannot open the Bluetooth adapter tcp-client:127\.0\.0\.1:1"):
        await BleakScanner.discover(0.1, backend=BumbleScanner, hci="tcp-client:127.0.0.1:1")
    with pytest.raises(BleakError, match="needs an HCI transport"):
        BleakScanner(backend=BumbleScanner)
