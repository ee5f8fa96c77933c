"""A board over Bluetooth LE as a Transport, on bleak's API: the Nordic UART Service the board's nRF51 offers.

- writes go to RX (6E400002) as write-without-response commands of at most 20 bytes (ATT MTU 23);
- notifications from TX (6E400003) are the read chunks: the same stream decoder as the UART takes them, so a
  frame spanning two notifications is no problem;
- the platform's Bluetooth stack (BlueZ, CoreBluetooth, WinRT) by default; with ``hci`` our bleak backend on
  bumble (``term.transports.bumble_backend``): ``tcp-client:HOST:PORT`` reaches the simulator's radio
  (``fcb-sim serve --ble-hci tcp-server:HOST:PORT``), ``usb:0`` a USB dongle driven by bumble directly.

Every failure (no adapter, no such board, not a board, a dropped connection) is one TransportError line. A
transport that failed or was closed can be opened again: that is the reconnect path.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import sys
from dataclasses import dataclass
from typing import Any

from term.core.protocol import BOARD_NAME_PREFIX as NAME_PREFIX
from term.core.protocol import NUS_RX, NUS_SERVICE, NUS_TX  # we write RX; the board notifies TX
from term.transports.base import Transport, TransportClosed, TransportError

MAX_WRITE = 20  # ATT MTU 23 minus the 3-byte ATT header: what the nRF51 takes in one write


# What opening a link imports: bumble's host takes 0.3-0.7 s to import (bumble.hci alone builds its tables in
# 0.15 s) on a 2-core machine. Imported on the loop, that stalls every other link of the terminal for as long: the
# cable's heartbeats go unanswered and both ends call a LINK LOST at start-up. So they are imported on a thread.
_STACK = ("bleak",)
_BUMBLE_STACK = ("term.transports.bumble_backend", "bumble.device", "bumble.transport", "bumble.core", "bumble.hci")


def _import_all(names: tuple[str, ...]) -> None:
    for name in names:
        importlib.import_module(name)


async def import_stack(hci: str | None) -> None:
    """Import the BLE stack (bleak; with ``hci`` our bumble backend and bumble) on a worker thread, so the event
    loop, which answers the other links' heartbeats, keeps running meanwhile. Cheap once imported."""
    names = _STACK + (_BUMBLE_STACK if hci else ())
    if all(name in sys.modules for name in names):
        return
    await asyncio.to_thread(_import_all, names)


def _backend_kwargs(hci: str | None) -> dict[str, Any]:
    if not hci:
        return {}
    from term.transports.bumble_backend import BumbleClient, BumbleScanner

    return {"backend": (BumbleScanner, BumbleClient), "hci": hci}


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


def _adapter_error(exc: BaseException, hci: str | None) -> TransportError:
    """One line for a failure to reach the Bluetooth adapter at all."""
    try:
        from bleak.exc import BleakBluetoothNotAvailableError
        not_available: tuple[type[BaseException], ...] = (BleakBluetoothNotAvailableError,)
    except ImportError:  # bleak 1.x has no such class (new in 2.0): then no error is one
        not_available = ()

    if hci:
        text = _one_line(exc)
        if "plug one in" in text:  # the bumble backend already said what to do with the dongle
            return TransportError(text)
        return TransportError(f"{text}: check --hci (e.g. tcp-client:127.0.0.1:9000, usb:0)")
    if isinstance(exc, not_available):
        return TransportError(f"Bluetooth is not available: {_one_line(exc)}; switch it on, or use --hci usb:0")
    return TransportError(
        f"no Bluetooth adapter reachable ({_one_line(exc)}): is bluetoothd running? "
        "Or drive a USB dongle directly with --hci usb:0"
    )


class BleTransport(Transport):
    """``BleTransport("F0:5A:00:00:00:01")`` (platform stack) or ``BleTransport(addr, hci="tcp-client:...")``."""

    movable = True  # bleak's client is made in open(), on the loop that opens it

    def __init__(self, address: str, hci: str | None = None, *, timeout: float = 10.0) -> None:
        self.address = address
        self.hci = hci
        self.timeout = timeout
        self.name = f"BLE {address}" + (f" via {hci}" if hci else "")
        self._client: Any = None
        self._rx: Any = None
        self._queue: asyncio.Queue[bytes | BaseException] = asyncio.Queue()
        self._write_lock = asyncio.Lock()
        self._closed = True
        self._error: TransportError | None = None
        # counters for the pilot's link view and the benchmarks
        self.writes = 0
        self.bytes_written = 0
        self.notifications = 0
        self.bytes_read = 0

    @property
    def is_open(self) -> bool:
        return not self._closed and self._error is None

    async def open(self) -> None:
        if self.is_open:
            return
        try:
            await import_stack(self.hci)
        except ImportError as exc:
            raise TransportError(f"BLE not available: {_one_line(exc)}") from None
        from bleak import BleakClient
        from bleak.exc import BleakDeviceNotFoundError, BleakError

        self._queue = asyncio.Queue()
        self._error = None
        kwargs = _backend_kwargs(self.hci)
        if kwargs:
            kwargs["backend"] = kwargs["backend"][1]
        try:
            client = BleakClient(self.address, self._on_disconnect, timeout=self.timeout, **kwargs)
        except (BleakError, OSError, ValueError) as exc:
            raise _adapter_error(exc, self.hci) from None
        try:
            await client.connect()
        except BleakDeviceNotFoundError:
            raise TransportError(
                f"no board with address {self.address} found nearby: is it on and not connected to another "
                "phone? ('term scan' lists the boards in range)"
            ) from None
        except TimeoutError:
            raise TransportError(f"BLE connection to {self.address} timed out: is the board in range?") from None
        except BleakError as exc:
            if "adapter" in str(exc).lower() or "bluetooth" in str(exc).lower():
                raise _adapter_error(exc, self.hci) from None
            raise TransportError(f"cannot connect to {self.address} over BLE: {_one_line(exc)}") from None
        except Exception as exc:  # D-Bus missing, OS errors: the stack itself is not there
            raise _adapter_error(exc, self.hci) from None
        try:
            service = client.services.get_service(NUS_SERVICE)
            rx = service.get_characteristic(NUS_RX) if service else None
            tx = service.get_characteristic(NUS_TX) if service else None
            if rx is None or tx is None:
                raise TransportError(f"{self.address} is not a Quadrupel board: it has no Nordic UART Service")
            await client.start_notify(tx, self._on_notify)
        except BaseException as exc:
            with contextlib.suppress(Exception):
                await client.disconnect()
            if isinstance(exc, TransportError | asyncio.CancelledError):
                raise
            raise TransportError(f"BLE link to {self.address} failed while starting: {_one_line(exc)}") from None
        self._client = client
        self._rx = rx
        self._closed = False

    def _on_notify(self, _characteristic: Any, data: bytearray) -> None:
        if data:
            self.notifications += 1
            self.bytes_read += len(data)
            self._queue.put_nowait(bytes(data))

    def _on_disconnect(self, _client: Any) -> None:
        if self._closed:
            return
        self._error = TransportError(
            f"BLE connection to {self.address} lost: out of range or the board reset; reconnect to continue"
        )
        self._queue.put_nowait(self._error)

    async def close(self) -> None:
        if self._closed and self._client is None:
            return
        self._closed = True
        self._queue.put_nowait(TransportClosed(f"{self.name} closed"))
        client, self._client = self._client, None
        if client is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(client.disconnect(), 5.0)

    async def read(self) -> bytes:
        if self._closed and self._queue.empty():
            raise TransportClosed(f"{self.name} closed")
        item = await self._queue.get()
        if isinstance(item, BaseException):
            self._queue.put_nowait(item)  # every later read fails the same way
            raise item
        return item

    async def write(self, data: bytes) -> None:
        if self._closed:
            raise TransportClosed(f"{self.name} closed")
        if self._error is not None:
            raise self._error
        async with self._write_lock:  # chunks of two writes never interleave: frames stay whole
            for i in range(0, len(data), MAX_WRITE):
                chunk = data[i : i + MAX_WRITE]
                try:
                    await self._client.write_gatt_char(self._rx, chunk, response=False)
                except Exception as exc:
                    if self._error is not None:
                        raise self._error from None
                    raise TransportError(f"BLE write to {self.address} failed: {_one_line(exc)}") from None
                self.writes += 1
                self.bytes_written += len(chunk)


@dataclass(frozen=True, slots=True)
class BoardInfo:
    address: str
    name: str
    rssi: int

    def __str__(self) -> str:
        return f"{self.name:<16} {self.address}  {self.rssi} dBm"


async def scan(hci: str | None = None, timeout: float = 3.0) -> list[BoardInfo]:
    """The boards advertising nearby (name starting with ``BOARD_NAME_PREFIX``), strongest first."""
    await import_stack(hci)
    from bleak import BleakScanner
    from bleak.exc import BleakError

    kwargs = _backend_kwargs(hci)
    if kwargs:
        kwargs["backend"] = kwargs["backend"][0]
    try:
        found = await BleakScanner.discover(timeout, return_adv=True, **kwargs)
    except (BleakError, OSError, ValueError) as exc:
        raise _adapter_error(exc, hci) from None
    except Exception as exc:
        raise _adapter_error(exc, hci) from None
    boards = [
        BoardInfo(device.address, adv.local_name or device.name or "", adv.rssi)
        for device, adv in found.values()
        if (adv.local_name or device.name or "").startswith(NAME_PREFIX)
    ]
    return sorted(boards, key=lambda b: (-b.rssi, b.name))
