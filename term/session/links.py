"""The links a user names, opened one way for every command: ``open_link(spec)``.

A ``LinkSpec`` is what the command line and the config say about a board: a serial port (a device, a COM port, or
one of pyserial's URLs: ``socket://HOST:PORT``, ``rfc2217://HOST:PORT``) at a baud rate, and or a BLE address with
the HCI transport that reaches it (a bumble ``tcp-client:...``, or None for the platform's stack). Flying (the
cable and the radio beside it), ``term params`` and the simulated board's links all come through here, so a
transport is chosen in one place; ``term scan`` takes the same ``hci``.

``open_link`` returns the transport unopened: the connection or the link's own thread opens it on its loop.
"""

from __future__ import annotations

from dataclasses import dataclass

from term.core.errors import UsageError
from term.core.protocol import BAUD_RATE
from term.transports.base import Transport

BLE_TIMEOUT_S = 10.0  # s to find and connect to a board over BLE (term --ble-timeout)


@dataclass(frozen=True, slots=True)
class LinkSpec:
    port: str | None = None  # serial: a device, a COM port or a pyserial URL
    baud: int = BAUD_RATE
    ble: str | None = None  # a BLE address
    hci: str | None = None  # the HCI transport to reach it (bumble's), None for the platform's stack
    ble_timeout: float = BLE_TIMEOUT_S

    @property
    def cable(self) -> LinkSpec | None:
        """The serial link alone (None when no port is named)."""
        return LinkSpec(port=self.port, baud=self.baud) if self.port else None

    @property
    def radio(self) -> LinkSpec | None:
        """The BLE link alone (None when no address is named)."""
        return LinkSpec(ble=self.ble, hci=self.hci, ble_timeout=self.ble_timeout) if self.ble else None


def open_link(spec: LinkSpec) -> Transport:
    """The transport ``spec`` names, not yet opened: serial when it names a port, else BLE. A UsageError (one
    line) when it names neither, or BLE where the BLE stack cannot be imported."""
    if spec.port:
        from term.transports.serial import SerialTransport

        return SerialTransport(spec.port, spec.baud)
    if spec.ble:
        try:
            from term.transports.ble import BleTransport
        except ImportError as exc:
            raise UsageError(f"BLE transport not available ({exc})") from None
        return BleTransport(spec.ble, hci=spec.hci, timeout=spec.ble_timeout)
    raise UsageError("no board given: name a serial port (--serial) or a BLE address (--ble)")
