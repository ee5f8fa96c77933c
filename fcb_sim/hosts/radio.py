"""The board's radio on the air: ``BoardRadio`` puts a ``WirelessLink`` (fcb_sim/board/wireless.py) on a bumble
device with the Nordic UART Service, on a ``LocalLink`` of virtual controllers, optionally with a second controller
served as an HCI transport over TCP (``HciTcpServer``) so a bumble host in another process can scan, connect and
fly. ``start_radio()`` is the one call for ``fcb-sim serve``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Any

from fcb_sim.board.wireless import ATT_MTU, WirelessLink, board_name
from fcb_sim.errors import parse_tcp_server
from fcb_sim.hosts.listeners import Door, GuardedServer
from term.core.protocol import NUS_RX, NUS_SERVICE, NUS_TX, WirelessState

log = logging.getLogger(__name__)

MAX_WAITING_HOSTS = 2  # HCI hosts waiting for the radio at once; the next is refused (hosts/listeners.py)
MAX_HELD = 65536  # bytes kept for a waiting host
HOST_WAIT_S = 30.0  # a host that has waited this long without getting the radio is dropped


def board_address(board_id: int) -> str:
    """The board's static random address: the top two bits set (static), the id in the last two bytes."""
    return f"F0:5A:00:00:{(board_id >> 8) & 0xFF:02X}:{board_id & 0xFF:02X}"


class BoardRadio:
    """The board's BLE radio: a bumble ``Device`` named "Quadrupel <id>" advertising the Nordic UART Service,
    on a bumble controller attached to ``local_link`` (a fresh ``LocalLink`` if None), wired to ``link``.

    - with ``board`` (an object with ``ble_connected()``, ``ble_disconnected()``, ``ble_receive(data)``: the
      board, which drives its own ``link``), connection events and written bytes go to the board;
    - without it, the radio drives ``link`` itself: ``link.connected()`` / ``link.disconnected()``, and what
      the phone writes goes through ``link.ble_receive()``, the bytes for the parser to ``on_data``;
    - either way ``on_disconnect(was_started)`` is called after a disconnection (True: the board was flown
      over BLE), and the link's notifications are sent on TX as soon as it has them (``link.on_ready``).

    One phone at a time (like the nRF51's S110): advertising stops while connected and restarts after.
    """

    def __init__(
        self,
        link: WirelessLink,
        *,
        board_id: int = 1,
        board: Any = None,
        on_data: Callable[[bytes], None] | None = None,
        on_disconnect: Callable[[bool], None] | None = None,
        local_link: Any = None,
        advertising_interval_ms: float = 20.0,
    ) -> None:
        self.link = link
        self.board = board
        self.board_id = board_id
        self.name = board_name(board_id)
        self.address = board_address(board_id)
        self.on_data = on_data
        self.on_disconnect = on_disconnect
        self.advertising_interval_ms = advertising_interval_ms
        self.local_link = local_link
        self.device: Any = None
        self.controller: Any = None
        self.connection: Any = None
        self.hci: HciTcpServer | None = None  # the second controller's HCI server, if exposed
        self._transport: Any = None  # a real HCI transport for the board's own controller, if used
        self._tx_char: Any = None
        self._wake = asyncio.Event()
        self._sender: asyncio.Task[None] | None = None
        self.notify_errors = 0
        self.refused_writes = 0  # writes to a characteristic that does not declare them (TX is notify-only)

    async def start(self, hci_transport: str | None = None) -> None:
        """Power the radio on and advertise. ``hci_transport`` puts the board's own radio on a real HCI
        transport (e.g. ``usb:0``: a phone can connect to the simulator); None: a virtual controller."""
        from bumble.controller import Controller
        from bumble.device import Device
        from bumble.gatt import Characteristic, CharacteristicValue, Service
        from bumble.hci import Address
        from bumble.link import LocalLink

        if hci_transport is None:
            if self.local_link is None:
                self.local_link = LocalLink()
            self.controller = Controller(f"board-{self.board_id}", link=self.local_link)
            source = sink = self.controller
        else:
            from bumble.transport import open_transport

            self._transport = await open_transport(hci_transport)
            source, sink = self._transport.source, self._transport.sink
        device = Device.with_hci(self.name, Address(self.address), source, sink)
        device.gatt_server.max_mtu = ATT_MTU  # the S110 keeps the default MTU: 20-byte notifications
        declared = _declared_characteristic_class(self._refuse_write)
        rx = declared(
            NUS_RX,
            Characteristic.WRITE_WITHOUT_RESPONSE | Characteristic.WRITE,
            Characteristic.WRITEABLE,
            CharacteristicValue(write=self._on_write),
        )
        self._tx_char = declared(NUS_TX, Characteristic.NOTIFY, Characteristic.READABLE, b"")
        device.add_service(Service(NUS_SERVICE, [rx, self._tx_char]))
        self._drop_undeclared_write_commands(device.gatt_server)
        device.on("connection", self._on_connection)
        self.device = device
        self.link.on_ready = self._wake.set
        await device.power_on()
        await self._advertise()
        self._sender = asyncio.create_task(self._send_loop(), name=f"{self.name} notifications")

    def _refuse_write(self) -> None:
        self.refused_writes += 1

    def _drop_undeclared_write_commands(self, server: Any) -> None:
        """A write command (no response) to a characteristic that does not declare WRITE_WITHOUT_RESPONSE is
        dropped here, as the spec wants, counted; bumble would pass it to the value (it checks no permissions)."""
        from bumble.gatt import Characteristic

        accept = server.on_att_write_command

        def on_att_write_command(bearer: Any, request: Any) -> None:
            attribute = server.get_attribute(request.attribute_handle)
            props = getattr(attribute, "properties", None)
            if props is not None and not props & Characteristic.WRITE_WITHOUT_RESPONSE:
                self.refused_writes += 1
                return
            accept(bearer, request)

        server.on_att_write_command = on_att_write_command

    async def _advertise(self) -> None:
        from bumble.core import UUID, AdvertisingData

        # Name and flags in the advertisement, the NUS UUID in the scan response (31 bytes hold not both),
        # as Nordic's ble_app_uart does.
        adv = AdvertisingData(
            [
                (AdvertisingData.FLAGS, bytes([0x06])),  # LE general discoverable, BR/EDR not supported
                (AdvertisingData.COMPLETE_LOCAL_NAME, self.name.encode()),
            ]
        )
        scan_rsp = AdvertisingData(
            [(AdvertisingData.COMPLETE_LIST_OF_128_BIT_SERVICE_CLASS_UUIDS, bytes(UUID(NUS_SERVICE)))]
        )
        await self.device.start_advertising(
            advertising_data=bytes(adv),
            scan_response_data=bytes(scan_rsp),
            auto_restart=True,
            advertising_interval_min=self.advertising_interval_ms,
            advertising_interval_max=self.advertising_interval_ms,
        )

    async def advertise(self) -> None:
        """Advertise again after ``device.stop_advertising()`` (the instructor's radio cut, hosts/instructor.py)."""
        await self._advertise()

    def _on_connection(self, connection: Any) -> None:
        if self.connection is not None:  # one phone at a time
            asyncio.ensure_future(connection.disconnect())
            return
        self.connection = connection
        connection.on("disconnection", lambda reason: self._on_disconnection(connection, reason))
        if self.board is not None:
            self.board.ble_connected()
        else:
            self.link.connected()

    def _on_disconnection(self, connection: Any, reason: int) -> None:
        if connection is not self.connection:
            return
        self.connection = None
        if self.board is not None:
            was_started = self.link.state is WirelessState.STARTED
            self.board.ble_disconnected()
        else:
            was_started = self.link.disconnected()
        log.info("%s: phone disconnected (reason %#x)%s", self.name, reason, ", was flying over BLE" * was_started)
        if self.on_disconnect is not None:
            self.on_disconnect(was_started)

    def _on_write(self, connection: Any, value: bytes) -> None:
        if connection is not self.connection:
            return
        if self.board is not None:
            self.board.ble_receive(bytes(value))
            return
        data = self.link.ble_receive(bytes(value))
        if data and self.on_data is not None:
            self.on_data(data)

    async def _send_loop(self) -> None:
        while True:
            await self._wake.wait()
            self._wake.clear()
            for note in self.link.notifications():
                connection = self.connection
                if connection is None:
                    break
                try:
                    await self.device.notify_subscriber(connection, self._tx_char, note)
                except Exception as exc:  # a connection torn down under us: the disconnection event follows
                    self.notify_errors += 1
                    log.debug("%s: notification failed: %s", self.name, exc)

    async def expose_hci(self, spec: str) -> str:
        """Attach a second virtual controller to the radio's LocalLink and serve it as an HCI transport on
        ``spec`` (``tcp-server:HOST:PORT``, PORT 0 for any free port). Returns the transport a bumble host
        uses to reach it (``tcp-client:HOST:PORT``)."""
        if self.local_link is None:
            raise RuntimeError("start the radio first (with a virtual controller)")
        host, port = parse_tcp_server(spec, "--ble-hci", "tcp-server:127.0.0.1:9000")
        self.hci = HciTcpServer(self.local_link, name=f"phone-side of {self.name}")
        await self.hci.start(host, port)
        return self.hci.client_spec

    async def close(self) -> None:
        if self._sender is not None:
            self._sender.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._sender
            self._sender = None
        if self.hci is not None:
            await self.hci.close()
            self.hci = None
        if self.device is not None:
            with contextlib.suppress(Exception):
                await self.device.power_off()
        if self._transport is not None:
            await self._transport.close()
            self._transport = None
        self.link.on_ready = None


def _declared_characteristic_class(on_refused_write: Callable[[], None]) -> type:
    """A bumble Characteristic that keeps its declared properties (bumble checks no permissions): a read without
    READ and a write request without WRITE are answered with the ATT error (refused writes are reported)."""
    from bumble import att
    from bumble.gatt import Characteristic

    class DeclaredCharacteristic(Characteristic):  # type: ignore[misc,type-arg]
        async def read_value(self, bearer: Any) -> bytes:
            if not self.properties & Characteristic.READ:
                raise att.ATT_Error(att.ATT_READ_NOT_PERMITTED_ERROR, self.handle)
            return await super().read_value(bearer)

        async def write_value(self, bearer: Any, value: bytes) -> None:
            if not self.properties & Characteristic.WRITE:
                on_refused_write()
                raise att.ATT_Error(att.ATT_WRITE_NOT_PERMITTED_ERROR, self.handle)
            await super().write_value(bearer, value)

    return DeclaredCharacteristic


class HciTcpServer:
    """A virtual bumble controller on ``local_link``, served as an H4 HCI transport over TCP to one host at a
    time, like bumble's ``tcp-server`` transport but aware of the host. A second host waits (``hosts_waiting``;
    what it sends is kept) until the first has gone, and is then served: taking the radio from the first would
    drop its BLE connection, and a board flown over it would PANIC; a terminal that reconnects at once gets the
    radio as soon as its old connection is closed. At most ``MAX_WAITING_HOSTS`` wait, each at most ``HOST_WAIT_S``;
the next is refused at once, and no descriptor past what serve's select() watches is kept (the door of
hosts/listeners.py). When the host goes away (the terminal quit or crashed), its BLE
    connections are dropped as a real radio's supervision timeout would, so the board sees the disconnection; its
    scanning and advertising stop."""

    def __init__(self, local_link: Any, name: str = "hci") -> None:
        from bumble.controller import Controller
        from bumble.transport.common import StreamPacketSource

        self._source = StreamPacketSource()
        self._peer: asyncio.Transport | None = None
        self.controller = Controller(name, host_source=self._source, host_sink=self, link=local_link)
        self._server: GuardedServer | None = None
        self.host = ""
        self.port = 0
        self.hosts_served = 0
        self._waiting: list[Any] = []  # hosts waiting for the radio, oldest first
        self.door = Door(f"{name} (HCI)", log, max_pending=MAX_WAITING_HOSTS, pending_timeout_s=HOST_WAIT_S)

    @property
    def client_spec(self) -> str:
        return f"tcp-client:{self.host}:{self.port}"

    # The controller's host sink: HCI packets to the host.
    def on_packet(self, packet: bytes) -> None:
        if self._peer is not None:
            self._peer.write(packet)

    async def start(self, host: str, port: int) -> None:
        from fcb_sim.errors import UsageError

        server = self

        class _Host(asyncio.Protocol):
            transport: asyncio.Transport | None = None

            held = b""  # what a waiting host sent before it got the radio

            def connection_made(self, transport: asyncio.BaseTransport) -> None:
                self.transport = transport  # type: ignore[assignment]
                if server._peer is not None:  # one host per controller: the next one waits its turn
                    log.info("%s: a second HCI host waits (one is attached)", server.controller.name)
                    server._waiting.append(self)
                    return
                server._attach(self.transport)  # type: ignore[arg-type]

            def data_received(self, data: bytes) -> None:
                if self.transport is not None and server._peer is self.transport:
                    server._source.data_received(data)
                elif self in server._waiting and len(self.held) < MAX_HELD:
                    self.held += data  # (a host that floods while it waits loses the rest: it is no real host)

            def connection_lost(self, exc: Exception | None) -> None:
                if self in server._waiting:
                    server._waiting.remove(self)
                elif self.transport is not None and server._peer is self.transport:
                    server._detach()
                    server._next_host()

        try:
            self._server = await GuardedServer.start(host, port, _Host, self.door)
        except OSError as exc:
            raise UsageError(f"cannot serve the BLE HCI on {host}:{port}: {exc.strerror or exc}") from None
        self.host = host
        self.port = self._server.sockets[0].getsockname()[1]

    def _attach(self, transport: asyncio.Transport) -> None:
        self.door.authenticated(transport)  # the radio is its: no more waiting clock
        self._peer = transport
        self._source = _fresh_source(self.controller)  # a new host starts a new H4 stream
        self.hosts_served += 1

    @property
    def hosts_waiting(self) -> int:
        return len(self._waiting)

    def _detach(self) -> None:
        self._peer = None
        drop_host_state(self.controller)

    def _next_host(self) -> None:
        """The radio is free: the host that has waited longest gets it, with what it already sent."""
        if self._waiting:
            host = self._waiting.pop(0)
            self._attach(host.transport)
            if host.held:
                self._source.data_received(host.held)

    async def close(self) -> None:
        for host in self._waiting:
            host.transport.close()
        self._waiting.clear()
        if self._peer is not None:
            self._peer.close()
            self._detach()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await self._server.wait_closed()
            self._server = None
        if self.controller.link is not None:
            with contextlib.suppress(KeyError):
                self.controller.link.remove_controller(self.controller)
        self.door.close()


def _fresh_source(controller: Any) -> Any:
    from bumble.transport.common import StreamPacketSource

    source = StreamPacketSource()
    source.set_packet_sink(controller)
    return source


def drop_host_state(controller: Any) -> None:
    """What a controller loses with its host: its LE connections (the peer sees a connection timeout), its
    advertising, scanning and pending connection."""
    from bumble import hci, ll

    for connection in list(controller.le_connections.values()):
        connection.send_ll_control_pdu(ll.TerminateInd(hci.HCI_CONNECTION_TIMEOUT_ERROR))
        controller.on_le_disconnected(connection, hci.HCI_CONNECTION_TIMEOUT_ERROR)
    controller.le_legacy_advertiser.stop()
    for adv_set in controller.advertising_sets.values():
        adv_set.stop()
    controller.le_scan_enable = False
    controller.pending_le_connection = None


async def start_radio(
    link: WirelessLink,
    *,
    board_id: int = 1,
    hci: str | None = None,
    board: Any = None,
    on_data: Callable[[bytes], None] | None = None,
    on_disconnect: Callable[[bool], None] | None = None,
) -> BoardRadio:
    """The one call for ``fcb-sim serve``: put the board's radio on the air, wired to ``link``.

    For the board: ``radio = await start_radio(board.wireless, board=board, board_id=..., hci=args.ble_hci)``:
    the radio then calls ``board.ble_connected()``, ``board.ble_disconnected()``, ``board.ble_receive(data)``
    (from the event loop, between the board's ``advance`` calls) and sends the link's notifications itself.

    - ``hci=None``: a virtual radio on a fresh LocalLink (``radio.local_link``; in-process centrals attach
      their own ``Controller`` to it);
    - ``hci="tcp-server:HOST:PORT"`` (``--ble-hci``): the same, plus a second virtual controller on that link
      served as an HCI transport; ``radio.hci.client_spec`` is what to give ``term --ble ... --hci``
      (PORT 0 picks a free port);
    - any other bumble transport (``usb:0``, ``serial:...``): the board's radio is that real controller, so a
      phone can connect to the simulator.

    Without ``board``, the radio drives ``link`` itself: ``on_data(bytes)`` receives what the parser must read
    from BLE. ``on_disconnect(was_started)`` is called after a lost connection. Close with
    ``await radio.close()``.
    """
    radio = BoardRadio(link, board_id=board_id, board=board, on_data=on_data, on_disconnect=on_disconnect)
    if hci is not None and hci.startswith("tcp-server:"):
        parse_tcp_server(hci, "--ble-hci", "tcp-server:127.0.0.1:9000")  # a bad spec fails before anything starts
        await radio.start()
        try:
            await radio.expose_hci(hci)
        except BaseException:
            await radio.close()
            raise
    else:
        try:
            await radio.start(hci)
        except Exception as exc:
            from fcb_sim.errors import UsageError

            await radio.close()
            raise UsageError(f"cannot open the BLE radio {hci!r}: {exc}") from None
    return radio
