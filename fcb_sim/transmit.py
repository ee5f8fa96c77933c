"""The board's transmit side: every packet the board sends goes through here, to the UART and the BLE link.

``Transmitter.send(pkt, now)`` offers a packet to the wireless link (which decides whether it goes over BLE) and
queues it on the UART while the cable is in use; ``telemetry(pkt, now)`` does the same for telemetry, which is
skipped, not queued behind itself, when the UART cannot keep up; ``bulk_room()`` says whether a log chunk may be
queued. ``transmit(now)`` is what has left the UART by then. The rule the transmit side keeps is in
docs/board.md ("The transmit side").
"""

from __future__ import annotations

from typing import Any

from fcb_sim.uart import Uart
from fcb_sim.wireless import WirelessLink
from term.protocol import MAX_FRAME, Encoder


class Transmitter:
    """The transmit side of both links (module docstring)."""

    def __init__(self, uart: Uart, wireless: WirelessLink) -> None:
        self.uart = uart
        self.wireless = wireless
        self.encoder = Encoder()  # the UART's sequence numbers (BLE has its own)
        self.tx_dropped = 0  # telemetry frames skipped for a full transmit buffer

    def send(self, pkt: Any, now: int) -> None:
        link = self.wireless
        link.send(pkt)
        if link.writes_uart:
            self.uart.write(self.encoder.encode(pkt), now)

    def telemetry(self, pkt: Any, now: int) -> None:
        if self.uart.tx_room < MAX_FRAME:
            self.tx_dropped += 1
            return
        self.send(pkt, now)

    def bulk_room(self) -> bool:
        """Whether a log chunk may be queued now (the wire paces the download)."""
        return self.uart.tx_room > MAX_FRAME

    def transmit(self, now: int) -> bytes:
        return self.uart.transmit(now)

    def wire(self) -> tuple[float, int]:
        """(time the first unsent byte starts, bytes that will leave back to back from then): the UART's
        transmit interrupts for the interference model."""
        return self.uart.tx_clock, len(self.uart.tx)
