"""A bleak backend built on bumble: bleak's scanner and client API over a bumble host on any HCI transport.

bleak has one client API and one backend class per platform, picked at run time; this is one more, picked by
passing ``backend=`` to ``BleakScanner`` / ``BleakClient`` together with the HCI transport::

    from bleak import BleakClient, BleakScanner
    from term.transports.bumble_backend import BumbleClient, BumbleScanner

    devices = await BleakScanner.discover(2.0, backend=BumbleScanner, hci="tcp-client:127.0.0.1:9000")
    async with BleakClient(devices[0], backend=BumbleClient, hci="tcp-client:127.0.0.1:9000") as client:
        await client.start_notify(TX_UUID, on_notification)
        await client.write_gatt_char(RX_UUID, b"...", response=False)

``hci`` is any bumble transport: ``tcp-client:HOST:PORT`` for the simulator's radio (``fcb-sim serve
--ble-hci tcp-server:...``), ``usb:0`` for a USB Bluetooth dongle, ``serial:...``, ``hci-socket:0``...
Scanners and clients on the same transport in one process share one bumble host (one controller has one host),
opened on first use and closed with the last user.

bleak's backend base classes are not its public API: this module is tested with bleak 1.0 to 3.x (pyproject.toml
allows ``>=1.0,<4``; 0.22's scanner base has other abstract methods) and bumble from 0.0.226 (older ones crash
or hang on connect and reconnect); ``make test-lowest`` runs it at those floors.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Any, Literal

from bleak.backends.characteristic import BleakGATTCharacteristic
from bleak.backends.client import BaseBleakClient, NotifyCallback
from bleak.backends.descriptor import BleakGATTDescriptor
from bleak.backends.device import BLEDevice
from bleak.backends.scanner import AdvertisementData, AdvertisementDataCallback, BaseBleakScanner
from bleak.backends.service import BleakGATTService, BleakGATTServiceCollection
from bleak.exc import BleakDeviceNotFoundError, BleakError
from bleak.uuids import normalize_uuid_str

log = logging.getLogger(__name__)

# bumble's characteristic property bits to bleak's property names
_PROPERTY_NAMES = (
    (0x01, "broadcast"),
    (0x02, "read"),
    (0x04, "write-without-response"),
    (0x08, "write"),
    (0x10, "notify"),
    (0x20, "indicate"),
    (0x40, "authenticated-signed-writes"),
    (0x80, "extended-properties"),
)


def _uuid(uuid: Any) -> str:
    return normalize_uuid_str(uuid.to_hex_str("-"))


def _address_key(address: str) -> str:
    """An address as users write it: upper case, without bumble's ``/P`` type suffix."""
    return address.split("/")[0].upper()


# --- the shared host ----------------------------------------------------------------------------------------


class BumbleHost:
    """One bumble host (a ``Device``) on one HCI transport, shared by the scanners and clients of this process
    that use that transport. Reference counted: ``acquire`` opens it, the last ``release`` closes it."""

    _open: dict[tuple[int, str], BumbleHost] = {}
    _lock: asyncio.Lock | None = None
    _lock_loop: asyncio.AbstractEventLoop | None = None

    def __init__(self, spec: str) -> None:
        self.spec = spec
        self.loop = asyncio.get_running_loop()
        self.users = 0
        self.transport: Any = None
        self.device: Any = None
        self.lost = False
        self._scan_listeners: dict[object, Callable[[Any], None]] = {}
        self._scanning_active: bool | None = None
        self._on_lost: dict[object, Callable[[], None]] = {}
        self._watch: asyncio.Task[None] | None = None

    @classmethod
    def _get_lock(cls) -> asyncio.Lock:
        loop = asyncio.get_running_loop()
        if cls._lock is None or cls._lock_loop is not loop:
            cls._lock = asyncio.Lock()
            cls._lock_loop = loop
        return cls._lock

    @classmethod
    async def acquire(cls, spec: str) -> BumbleHost:
        key = (id(asyncio.get_running_loop()), spec)
        async with cls._get_lock():
            host = cls._open.get(key)
            if host is None or host.lost or host.loop is not asyncio.get_running_loop():
                host = cls(spec)
                await host._open_transport()
                cls._open[key] = host
            host.users += 1
            return host

    async def release(self) -> None:
        self.users -= 1
        if self.users > 0:
            return
        key = (id(asyncio.get_running_loop()), self.spec)
        if BumbleHost._open.get(key) is self:
            del BumbleHost._open[key]
        await self._close()

    async def _open_transport(self) -> None:
        from bumble.device import Device
        from bumble.hci import Address
        from bumble.transport import open_transport

        try:
            self.transport = await open_transport(self.spec)
        except Exception as exc:
            if self.spec.startswith(("usb", "pyusb")):
                raise BleakError(
                    f"cannot open the Bluetooth adapter {self.spec}: no usable USB dongle ({_reason(exc)}); plug "
                    "one in, and on Linux detach it from the kernel's driver or give yourself access to it"
                ) from None
            raise BleakError(f"cannot open the Bluetooth adapter {self.spec}: {_reason(exc)}") from None
        self.device = Device.with_hci(
            "Quadrupel terminal", Address.generate_static_address(), self.transport.source, self.transport.sink
        )
        self.device.on("advertisement", self._on_advertisement)
        try:
            await asyncio.wait_for(self.device.power_on(), 10.0)
        except Exception as exc:
            await self.transport.close()
            raise BleakError(f"the Bluetooth adapter {self.spec} does not answer: {_reason(exc)}") from None
        terminated = getattr(self.transport.source, "terminated", None)
        if terminated is not None:
            self._watch = asyncio.create_task(self._watch_transport(terminated))

    async def _watch_transport(self, terminated: asyncio.Future[None]) -> None:
        await terminated
        self.lost = True
        log.info("HCI transport %s lost", self.spec)
        for callback in list(self._on_lost.values()):
            callback()

    async def _close(self) -> None:
        if self._watch is not None:
            self._watch.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._watch
        if self.device is not None and not self.lost:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self.device.power_off(), 2.0)
        if self.transport is not None:
            with contextlib.suppress(Exception):
                await self.transport.close()

    def on_lost(self, token: object, callback: Callable[[], None] | None) -> None:
        if callback is None:
            self._on_lost.pop(token, None)
        else:
            self._on_lost[token] = callback

    # scanning: one scan on the controller for any number of listeners
    def _on_advertisement(self, adv: Any) -> None:
        for listener in list(self._scan_listeners.values()):
            listener(adv)

    async def start_scan(self, token: object, listener: Callable[[Any], None], active: bool = True) -> None:
        self._scan_listeners[token] = listener
        if self._scanning_active is None or (active and not self._scanning_active):
            if self._scanning_active is not None:
                await self.device.stop_scanning()
            await self.device.start_scanning(active=active, filter_duplicates=False)
            self._scanning_active = active

    async def stop_scan(self, token: object) -> None:
        self._scan_listeners.pop(token, None)
        if not self._scan_listeners and self._scanning_active is not None:
            self._scanning_active = None
            if not self.lost:
                with contextlib.suppress(Exception):
                    await self.device.stop_scanning()

    async def find(self, address: str, timeout: float) -> Any:
        """The bumble ``Address`` (with its type) of the device advertising as ``address``, or None."""
        wanted = _address_key(address)
        found: asyncio.Future[Any] = asyncio.get_running_loop().create_future()

        def listener(adv: Any) -> None:
            if _address_key(str(adv.address)) == wanted and not found.done():
                found.set_result(adv.address)

        token = object()
        await self.start_scan(token, listener)
        try:
            return await asyncio.wait_for(found, timeout)
        except TimeoutError:
            return None
        finally:
            await self.stop_scan(token)


def _reason(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


def _hci_of(hci: str | None) -> str:
    if not hci:
        raise BleakError("the bumble backend needs an HCI transport: hci='tcp-client:HOST:PORT' or 'usb:0'")
    return hci


# --- advertisement data -------------------------------------------------------------------------------------


def advertisement_data(adv: Any) -> AdvertisementData:
    """bleak's ``AdvertisementData`` from a bumble ``Advertisement``."""
    from bumble.core import UUID, AdvertisingData

    data = adv.data
    name = data.get(AdvertisingData.COMPLETE_LOCAL_NAME) or data.get(AdvertisingData.SHORTENED_LOCAL_NAME)
    uuids: list[str] = []
    for kind, size in (
        (AdvertisingData.COMPLETE_LIST_OF_16_BIT_SERVICE_CLASS_UUIDS, 2),
        (AdvertisingData.INCOMPLETE_LIST_OF_16_BIT_SERVICE_CLASS_UUIDS, 2),
        (AdvertisingData.COMPLETE_LIST_OF_32_BIT_SERVICE_CLASS_UUIDS, 4),
        (AdvertisingData.INCOMPLETE_LIST_OF_32_BIT_SERVICE_CLASS_UUIDS, 4),
        (AdvertisingData.COMPLETE_LIST_OF_128_BIT_SERVICE_CLASS_UUIDS, 16),
        (AdvertisingData.INCOMPLETE_LIST_OF_128_BIT_SERVICE_CLASS_UUIDS, 16),
    ):
        for raw in data.get_all(kind, raw=True):
            uuids += [_uuid(UUID.from_bytes(raw[i : i + size])) for i in range(0, len(raw) - size + 1, size)]
    service_data: dict[str, bytes] = {}
    for kind, size in (
        (AdvertisingData.SERVICE_DATA_16_BIT_UUID, 2),
        (AdvertisingData.SERVICE_DATA_32_BIT_UUID, 4),
        (AdvertisingData.SERVICE_DATA_128_BIT_UUID, 16),
    ):
        for raw in data.get_all(kind, raw=True):
            if len(raw) >= size:
                service_data[_uuid(UUID.from_bytes(raw[:size]))] = bytes(raw[size:])
    manufacturer: dict[int, bytes] = {}
    for raw in data.get_all(AdvertisingData.MANUFACTURER_SPECIFIC_DATA, raw=True):
        if len(raw) >= 2:
            manufacturer[int.from_bytes(raw[:2], "little")] = bytes(raw[2:])
    tx_raw = data.get(AdvertisingData.TX_POWER_LEVEL, raw=True)
    tx_power = int.from_bytes(tx_raw[:1], "little", signed=True) if tx_raw else None
    return AdvertisementData(
        local_name=name if isinstance(name, str) else None,
        manufacturer_data=manufacturer,
        service_data=service_data,
        service_uuids=uuids,
        tx_power=tx_power,
        rssi=int(adv.rssi),
        platform_data=(adv,),
    )


# --- the scanner --------------------------------------------------------------------------------------------


class BumbleScanner(BaseBleakScanner):
    """bleak scanner backend over a bumble host. Extra keyword: ``hci`` (the bumble HCI transport)."""

    def __init__(
        self,
        detection_callback: AdvertisementDataCallback | None,
        service_uuids: list[str] | None,
        scanning_mode: Literal["active", "passive"] = "active",
        *,
        hci: str | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(detection_callback, service_uuids)
        self._hci = _hci_of(hci)
        self._active = scanning_mode != "passive"
        self._host: BumbleHost | None = None
        self._token = object()

    async def start(self) -> None:
        self.seen_devices = {}
        self._host = await BumbleHost.acquire(self._hci)
        try:
            await self._host.start_scan(self._token, self._on_advertisement, self._active)
        except Exception:
            await self._release()
            raise

    async def stop(self) -> None:
        if self._host is not None:
            await self._host.stop_scan(self._token)
            await self._release()

    async def _release(self) -> None:
        host, self._host = self._host, None
        if host is not None:
            await host.release()

    def _on_advertisement(self, adv: Any) -> None:
        data = advertisement_data(adv)
        if not self.is_allowed_uuid(data.service_uuids):
            return
        address = _address_key(str(adv.address))
        previous = self.seen_devices.get(address)
        name = data.local_name or (previous[0].name if previous else None)
        if previous is not None and data.local_name is None:
            data = data._replace(local_name=previous[1].local_name)
        device = self.create_or_update_device(address, address, name, adv.address, data)
        self.call_detection_callbacks(device, data)


# --- the client ---------------------------------------------------------------------------------------------


class BumbleClient(BaseBleakClient):
    """bleak client backend over a bumble host. Extra keyword: ``hci`` (the bumble HCI transport).

    Given a ``BLEDevice`` from ``BumbleScanner`` it connects at once; given an address string it first scans
    for it (up to ``timeout`` seconds), as bleak's other backends do."""

    def __init__(
        self,
        address_or_ble_device: BLEDevice | str,
        *,
        disconnected_callback: Callable[[], None] | None = None,
        timeout: float = 10.0,
        services: set[str] | None = None,
        hci: str | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(address_or_ble_device, disconnected_callback=disconnected_callback, timeout=timeout)
        self._hci = _hci_of(hci)
        self._services_filter = services
        self._device_name: str | None = None
        self._target: Any = None  # a bumble Address, when known
        if isinstance(address_or_ble_device, BLEDevice):
            self._device_name = address_or_ble_device.name
            from bumble.hci import Address

            if isinstance(address_or_ble_device.details, Address):  # found by BumbleScanner: has its type
                self._target = address_or_ble_device.details
        self.address = _address_key(self.address)
        self._host: BumbleHost | None = None
        self._connection: Any = None
        self._peer: Any = None
        self._subscriptions: dict[int, Callable[[bytes], None]] = {}
        self._token = object()

    @property
    def name(self) -> str:
        return self._device_name or self.address.replace(":", "-")

    @property
    def mtu_size(self) -> int:
        return self._connection.att_mtu if self._connection is not None else 23

    @property
    def is_connected(self) -> bool:
        return self._connection is not None and self._host is not None and not self._host.lost

    async def connect(self, pair: bool, **kwargs: Any) -> None:
        if self.is_connected:
            return
        self._host = await BumbleHost.acquire(self._hci)
        try:
            await self._connect(pair)
        except BaseException:
            await self._drop()
            raise

    async def _connect(self, pair: bool) -> None:
        from bumble.device import Peer

        host = self._host
        assert host is not None
        target = self._target
        if target is None:
            target = await host.find(self.address, self._timeout)
            if target is None:
                raise BleakDeviceNotFoundError(
                    self.address, f"no device with address {self.address} is advertising (searched for "
                    f"{self._timeout:g} s on {self._hci})"
                )
        try:
            connection = await host.device.connect(target, timeout=self._timeout)
        except Exception as exc:
            raise BleakError(f"cannot connect to {self.address}: {_reason(exc)}") from None
        self._connection = connection
        connection.on("disconnection", self._on_disconnection)
        host.on_lost(self._token, self._on_transport_lost)
        if pair:
            await connection.pair()
        self._peer = Peer(connection)
        self.services = await self._discover()

    async def _discover(self) -> BleakGATTServiceCollection:
        from bumble.core import UUID

        peer = self._peer
        wanted = [UUID(u) for u in self._services_filter] if self._services_filter else []
        await peer.discover_services(wanted)
        for service in peer.services:
            await peer.discover_characteristics(service=service)
            for characteristic in service.characteristics:
                await peer.discover_descriptors(characteristic)
        collection = BleakGATTServiceCollection()
        for service in peer.services:
            bleak_service = BleakGATTService(service, service.handle, _uuid(service.uuid))
            collection.add_service(bleak_service)
            for characteristic in service.characteristics:
                props = [name for bit, name in _PROPERTY_NAMES if characteristic.properties & bit]
                bleak_char = BleakGATTCharacteristic(
                    characteristic,
                    characteristic.handle,
                    _uuid(characteristic.uuid),
                    props,  # type: ignore[arg-type]
                    lambda: self.mtu_size - 3,
                    bleak_service,
                )
                collection.add_characteristic(bleak_char)
                for descriptor in characteristic.descriptors:
                    collection.add_descriptor(
                        BleakGATTDescriptor(descriptor, descriptor.handle, _uuid(descriptor.type), bleak_char)
                    )
        return collection

    def _on_disconnection(self, reason: int) -> None:
        log.info("%s disconnected (reason %#x)", self.address, reason)
        self._lost()

    def _on_transport_lost(self) -> None:
        log.info("%s: HCI transport %s lost", self.address, self._hci)
        self._lost()

    def _lost(self) -> None:
        was_connected = self._connection is not None
        self._connection = None
        self._peer = None
        self._subscriptions.clear()
        host, self._host = self._host, None
        if host is not None:
            host.on_lost(self._token, None)
            asyncio.ensure_future(host.release())
        if was_connected and self._disconnected_callback is not None:
            self._disconnected_callback()

    async def _drop(self) -> None:
        connection, self._connection = self._connection, None
        self._peer = None
        self._subscriptions.clear()
        host, self._host = self._host, None
        if host is None:
            return
        host.on_lost(self._token, None)
        if connection is not None and not host.lost:
            connection.remove_listener("disconnection", self._on_disconnection)
            with contextlib.suppress(Exception):
                await asyncio.wait_for(connection.disconnect(), 5.0)
        await host.release()

    async def disconnect(self) -> None:
        await self._drop()

    async def pair(self, *args: Any, **kwargs: Any) -> None:
        self._require()
        await self._connection.pair()

    async def unpair(self) -> None:
        raise BleakError("the bumble backend keeps no bonding keys: there is nothing to unpair")

    def _require(self) -> None:
        if not self.is_connected:
            raise BleakError(f"not connected to {self.address}")

    async def read_gatt_char(
        self, characteristic: BleakGATTCharacteristic, *, use_cached: bool = False, **kwargs: Any
    ) -> bytearray:
        self._require()
        return bytearray(await self._peer.read_value(characteristic.obj))

    async def read_gatt_descriptor(
        self, descriptor: BleakGATTDescriptor, *, use_cached: bool = False, **kwargs: Any
    ) -> bytearray:
        self._require()
        return bytearray(await self._peer.read_value(descriptor.obj))

    async def write_gatt_char(self, characteristic: BleakGATTCharacteristic, data: Any, response: bool) -> None:
        self._require()
        await self._peer.write_value(characteristic.obj, bytes(data), with_response=response)

    async def write_gatt_descriptor(self, descriptor: BleakGATTDescriptor, data: Any) -> None:
        self._require()
        await self._peer.write_value(descriptor.obj, bytes(data), with_response=True)

    async def start_notify(
        self, characteristic: BleakGATTCharacteristic, callback: NotifyCallback, **kwargs: Any
    ) -> None:
        self._require()

        def subscriber(value: bytes) -> None:
            callback(bytearray(value))

        self._subscriptions[characteristic.handle] = subscriber
        await self._peer.subscribe(characteristic.obj, subscriber, prefer_notify=True)

    async def stop_notify(self, characteristic: BleakGATTCharacteristic) -> None:
        self._require()
        subscriber = self._subscriptions.pop(characteristic.handle, None)
        await self._peer.unsubscribe(characteristic.obj, subscriber)
