"""The board's UART as a wire model: the protocol's BAUD_RATE, 8N1, ten bits a byte, both directions paced on the
board clock.

Sans-IO, no clock of its own: the board passes its time in.

- Receive: bytes from the PC reach the UART as a burst and occupy the wire one after another, so a burst can be
  parsed once its last byte is in (``arrived(now)``); a pty or a test hands a burst over at once, the board's UART
  does not. The receive queue is bounded (``RX_QUEUE_BYTES``): a flood is dropped and counted
  (``rx_overflow``), it never stalls the loop. With ``discard_at_frames`` (the report's parser, Param.QUEUE_RULE
  "discard-20") the whole queue is thrown away once that many frames wait in it (``rx_discarded`` counts).
- Transmit: frames are queued in a bounded buffer (``TX_BUFFER_BYTES``) and leave at the baud rate;
  ``transmit(now)`` returns what has left the UART by then. What may be queued, and in what order, is the
  board's transmit scheduler's decision (docs/board.md, "The transmit side").

docs/board.md ("The UART") explains why a burst is parsed in one run even though the firmware takes its bytes
as they come.
"""

from __future__ import annotations

import math
from collections import deque

from fcb_sim.board.timing import UART_US_PER_BYTE

RX_QUEUE_BYTES = 1024  # bounded: a flood is dropped and counted, it never stalls the loop
TX_BUFFER_BYTES = 1024  # what the transmit side may have queued at once


class Uart:
    """One UART: a bounded receive queue fed by bursts on the wire, a transmit buffer drained at the baud rate."""

    def __init__(self) -> None:
        self.rx = bytearray()  # the receive queue: bytes in, and bytes still on the wire at its end
        self._wire: deque[tuple[float, int]] = deque()  # bursts still arriving: (last byte in, µs; bytes)
        self._wire_bytes = 0  # bytes at the end of rx that are still on the wire
        self._wire_free = 0.0  # when the receive line is free (bursts arrive one after another)
        self.tx = bytearray()  # the transmit buffer
        self.tx_clock = 0.0  # board time up to which the transmit wire has been busy
        self.rx_overflow = 0  # bytes dropped from a full receive queue
        self.discard_at_frames: int | None = None  # the report's rule: discard the queue when this many frames wait
        self.rx_discarded = 0  # bytes thrown away by that rule

    # --- receive ------------------------------------------------------------------------------------------

    def receive(self, data: bytes, at: int) -> int:
        """A burst reaching the UART at board time ``at``; returns how many bytes the queue took (the rest is
        dropped and counted)."""
        room = RX_QUEUE_BYTES - len(self.rx)
        if len(data) > room:
            self.rx_overflow += len(data) - max(room, 0)
            data = data[: max(room, 0)]
        if not data:
            return 0
        self.rx += data
        # The bytes take the wire at the baud rate, after any still arriving.
        start = max(float(at), self._wire_free)
        self._wire_free = end = start + len(data) * UART_US_PER_BYTE
        self._wire.append((end, len(data)))
        self._wire_bytes += len(data)
        if self.discard_at_frames is not None and self.rx.count(0) >= self.discard_at_frames:
            self.rx_discarded += self.discard_rx()  # "all the packets in the queue are discarded" (report 3.4)
        return len(data)

    def arrived(self, now: int) -> int:
        """How many bytes of the receive queue are in by ``now`` (the rest is still on the wire)."""
        wire = self._wire
        while wire and wire[0][0] <= now:
            self._wire_bytes -= wire.popleft()[1]
        return len(self.rx) - self._wire_bytes

    def next_arrival_us(self) -> int | None:
        """When the last byte of the oldest burst still on the wire is in, or None."""
        return math.ceil(self._wire[0][0]) if self._wire else None

    def take(self, limit: int) -> bytes:
        """Up to ``limit`` bytes from the head of the receive queue."""
        chunk = bytes(self.rx[:limit])
        del self.rx[: len(chunk)]
        return chunk

    def discard_rx(self) -> int:
        """Empty the receive queue (the parser reads another link); returns the bytes thrown away."""
        n = len(self.rx)
        self.rx.clear()
        self._wire.clear()
        self._wire_bytes = 0
        return n

    # --- transmit -----------------------------------------------------------------------------------------

    @property
    def tx_room(self) -> int:
        return TX_BUFFER_BYTES - len(self.tx)

    def write(self, frame: bytes, now: int) -> None:
        """Queue a frame; the wire starts on it at once if it was idle."""
        if not self.tx:
            self.tx_clock = max(self.tx_clock, float(now))
        self.tx += frame

    def transmit(self, now: int) -> bytes:
        """What has left the UART by ``now``: BAUD_RATE, 8N1."""
        if not self.tx:
            self.tx_clock = max(self.tx_clock, float(now))
            return b""
        start = max(self.tx_clock, 0.0)
        can = int((now - start) / UART_US_PER_BYTE)
        if can <= 0:
            return b""
        out = bytes(self.tx[:can])
        del self.tx[:can]
        self.tx_clock = start + len(out) * UART_US_PER_BYTE
        return out


class BleInbox:
    """What the phone wrote for the parser after the handover (``WirelessLink.ble_receive``), queued as the UART's
    receive side is: bounded by RX_QUEUE_BYTES, a full queue drops and counts."""

    def __init__(self) -> None:
        self.queue = bytearray()
        self.overflow = 0  # bytes dropped from a full queue

    def put(self, data: bytes) -> None:
        room = max(RX_QUEUE_BYTES - len(self.queue), 0)
        if len(data) > room:
            self.overflow += len(data) - room
            data = data[:room]
        self.queue += data

    def take(self, limit: int) -> bytes:
        chunk = bytes(self.queue[:limit])
        del self.queue[: len(chunk)]
        return chunk
