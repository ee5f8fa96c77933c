"""The board's transmit side: a scheduler with a budget, the same rule on the UART and on the BLE queue.

Every packet the board sends goes through ``Transmitter.send(pkt, now)`` (telemetry through ``telemetry``, log
chunks after ``bulk_room()``). The rule (docs/board.md, "The transmit side"; docs/protocol.md):

1. Heartbeats first and on time, whatever else is queued. On the UART the frames wait here, by class, and the
   wire takes the next one at each frame boundary, a heartbeat before anything else: it waits at most for the
   frame on the wire (20 bytes, 1.7 ms). On BLE a heartbeat is never refused and flushes the queue at once.
2. Answers (Ack, Event, Hello, LogStatus, Profile) next, bounded: at most ``ANSWER_BUDGET`` bytes of them wait on
   a link. A command that finds no room for its Ack is not done and not answered (``CommandDesk.shed``): the
   terminal retries it. An answer set (the Profile packets, a LogStatus) asked for again while the previous one
   still waits is queued once; each request still gets its Ack.
3. Telemetry in what is left: a telemetry packet replaces one of its kind still waiting (latest wins) and is
   skipped while more than ``TX_BUFFER_BYTES`` wait; the log download's chunks only while the same holds.

Frames are encoded when they take the wire, so sequence numbers follow the wire order and a packet that never
left costs the receiver no gap. Sans-IO: the board's clock is passed in, ``transmit(now)`` is what has left the
UART by then.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from fcb_sim.board.timing import UART_US_PER_BYTE
from fcb_sim.board.uart import TX_BUFFER_BYTES, Uart
from fcb_sim.board.wireless import ANSWER_BUDGET, WirelessLink
from term.core.protocol import (
    MAX_FRAME,
    SPEC_OF,
    TELEMETRY,
    Ack,
    Compact,
    Compact2,
    Encoder,
    Heartbeat,
    LogChunk,
    Text,
)

__all__ = ["ANSWER_BUDGET", "Transmitter"]

HEARTBEAT, ANSWER, TELEMETRY_CLASS, BULK = range(4)
# debug lines (qb_log, Text) wait as the log's chunks do: behind heartbeats, answers and telemetry
_CLASS = {Heartbeat: HEARTBEAT, LogChunk: BULK, Text: BULK, Compact: TELEMETRY_CLASS, Compact2: TELEMETRY_CLASS,
          **{cls: TELEMETRY_CLASS for cls in TELEMETRY}}
ACK_BYTES = SPEC_OF[Ack].frame_size


def packet_class(pkt: Any) -> int:
    return _CLASS.get(type(pkt), ANSWER)


def frame_size(pkt: Any) -> int:
    return SPEC_OF[type(pkt)].frame_size


class UartQueue:
    """Packets waiting for the UART by class (FIFO within a class); ``pump(now)`` puts the next one on the wire at
    each frame boundary up to ``now``, the most urgent class first among those queued by then."""

    def __init__(self, uart: Uart) -> None:
        self.uart = uart
        self.encoder = Encoder()
        self.queues: list[deque[list[Any]]] = [deque() for _ in range(4)]  # entries [queued at, packet, tag]
        self.bytes = [0, 0, 0, 0]
        self.tags: dict[str, int] = {}  # answer sets still waiting, by tag
        self.hb_late_max_us = 0.0  # the longest a heartbeat waited from queued to on the wire

    def queue(self, pkt: Any, now: int, tag: str | None = None) -> None:
        self.pump(now)
        c = packet_class(pkt)
        if c == TELEMETRY_CLASS:
            for entry in self.queues[c]:
                if type(entry[1]) is type(pkt):
                    entry[1] = pkt  # latest wins, in the place the older one had
                    return
        self.queues[c].append([now, pkt, tag])
        self.bytes[c] += frame_size(pkt)
        if tag is not None:
            self.tags[tag] = self.tags.get(tag, 0) + 1

    def pending(self, now: int) -> int:
        """Bytes not yet sent: the frame on the wire and everything waiting."""
        self.pump(now)
        return len(self.uart.tx) + sum(self.bytes)

    def pump(self, now: int) -> None:
        u, qs = self.uart, self.queues
        while True:
            heads = [q[0][0] for q in qs if q]
            if not heads:
                return
            t = max(u.tx_clock + len(u.tx) * UART_US_PER_BYTE, min(heads))  # the next frame boundary
            if t > now:
                return
            c = next(i for i, q in enumerate(qs) if q and q[0][0] <= t)
            at, pkt, tag = qs[c].popleft()
            frame = self.encoder.encode(pkt)
            self.bytes[c] -= len(frame)
            if tag is not None:
                self.tags[tag] -= 1
            if c == HEARTBEAT:
                self.hb_late_max_us = max(self.hb_late_max_us, t - at)
            if not u.tx:
                u.tx_clock = max(u.tx_clock, t)
            u.tx += frame


class Transmitter:
    """The transmit side of both links (module docstring)."""

    def __init__(self, uart: Uart, wireless: WirelessLink) -> None:
        self.uart = uart
        self.wireless = wireless
        self.q = UartQueue(uart)
        self.tx_dropped = 0  # telemetry skipped for a full transmit side
        self.answers_dropped = 0  # events that found the answer budget spent
        self.answer_bytes_max = 0  # the most answer bytes ever waiting on the UART
        self._ble_tags: dict[str, int] = {}  # answer sets on BLE: the link's byte count once the set is queued

    @property
    def encoder(self) -> Encoder:
        return self.q.encoder

    @property
    def hb_late_max_us(self) -> float:
        return self.q.hb_late_max_us

    def send(self, pkt: Any, now: int, tag: str | None = None) -> None:
        link = self.wireless
        if link.send(pkt) and tag is not None:
            self._ble_tags[tag] = link.bytes_queued
        if not link.writes_uart:
            return
        if packet_class(pkt) == ANSWER and self.q.bytes[ANSWER] + frame_size(pkt) > ANSWER_BUDGET:
            self.answers_dropped += 1  # only events get here: commands are shed before they are done
            return
        self.q.queue(pkt, now, tag)
        self.answer_bytes_max = max(self.answer_bytes_max, self.q.bytes[ANSWER])

    def send_set(self, tag: str, pkts: list[Any], now: int) -> None:
        """An answer set (the Profile packets, ...): queued unless the previous set of this tag still waits."""
        if self.waiting(tag, now):
            return
        for pkt in pkts:
            self.send(pkt, now, tag)

    def waiting(self, tag: str, now: int) -> bool:
        """Whether an answer set with this tag still waits on the link that carries answers."""
        link = self.wireless
        if link.writes_ble:
            return link.bytes_taken < self._ble_tags.get(tag, 0)
        self.q.pump(now)
        return self.q.tags.get(tag, 0) > 0

    def answer_room(self, now: int, nbytes: int = ACK_BYTES) -> bool:
        """Whether an answer of ``nbytes`` fits the budget of the link that carries answers now."""
        link = self.wireless
        if link.writes_ble:
            return link.backlog_bytes + nbytes <= ANSWER_BUDGET
        self.q.pump(now)
        return self.q.bytes[ANSWER] + nbytes <= ANSWER_BUDGET

    def telemetry(self, pkt: Any, now: int) -> None:
        if self.q.pending(now) > TX_BUFFER_BYTES - MAX_FRAME:
            self.tx_dropped += 1
            return
        self.send(pkt, now)

    def bulk_room(self, now: int) -> bool:
        """Whether a log chunk may be queued now (the wire paces the download)."""
        return self.q.pending(now) < TX_BUFFER_BYTES - MAX_FRAME

    def pending_bytes(self, now: int) -> int:
        """Bytes not yet sent on the UART at ``now``."""
        return self.q.pending(now)

    def transmit(self, now: int) -> bytes:
        self.q.pump(now)
        return self.uart.transmit(now)

    def wire(self, now: int) -> tuple[float, int]:
        """(time the first unsent byte starts, bytes that leave back to back from then): the UART's transmit
        interrupts for the interference model."""
        return self.uart.tx_clock, self.q.pending(now)
