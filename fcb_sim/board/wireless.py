"""The board's wireless link (report section 3.9): the handover states and 20-byte notification batching
(the radio that carries them is a host's: fcb_sim/hosts/radio.py).

Two layers, so the rules can be tested at full speed without a radio:

- ``WirelessLink`` is sans-IO: connection events, received bytes and outgoing frames in; bytes for the parser,
  notifications and state out. It keeps the report's Figure 12:

  ``DISCONNECTED`` --wireless key in SAFE, with a connection--> ``STARTING`` --data over BLE--> ``STARTED``,
  and from either, a lost connection --> ``DISCONNECTED`` (the board PANICs if it was flying over BLE).

  A connection alone changes nothing. In STARTING the board keeps talking over the UART and also sends its
  heartbeats over BLE; the phone answers them, and that first data moves the link to STARTED: from then the
  parser reads only BLE and every reply goes to BLE. Over BLE the telemetry is reduced to the phone's
  ``Compact`` packet and, once per heartbeat, ``Compact2`` (the rest of the flight screen).

  Transmit batching: frames wait in the BLE tx queue until 20 bytes are ready, then leave as full 20-byte
  notifications (a frame may span two: the decoder is a stream decoder); a heartbeat flushes the queue at once.

- ``BoardRadio`` (fcb_sim/hosts/radio.py, the async edge) puts a ``WirelessLink`` on the air.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from term.core.protocol import (
    BOARD_NAME_PREFIX,
    SPEC_OF,
    TELEMETRY,
    Compact,
    Compact2,
    Encoder,
    Heartbeat,
    Nak,
    WirelessState,
)

log = logging.getLogger(__name__)

# The Nordic UART Service (NUS_SERVICE, NUS_RX written by the phone, NUS_TX notified by the board) and the
# advertised name are protocol facts; the names stay importable from here.
NAME_PREFIX = BOARD_NAME_PREFIX
ANSWER_BUDGET = 640  # bytes of answers (Ack, Event, Profile, ...) that may wait on a link: fcb_sim/board/transmit.py
ATT_MTU = 23  # the nRF51's S110 SoftDevice never negotiates more
NOTIFY_PAYLOAD = ATT_MTU - 3  # 20 bytes of value per notification


def compacts_per_heartbeat(compact: int, heartbeat: int, payload: int = NOTIFY_PAYLOAD, least: int = 3) -> int:
    """How many Compact frames to send per heartbeat period so that the bytes between two heartbeat flushes
    fill their notifications best: a heartbeat goes at once and takes the queue with it, so n Compacts and one
    heartbeat make ``n * compact + heartbeat`` bytes, the last notification of them partly empty. Of the counts
    from ``least`` (the phone's attitude at 30 Hz or more) to ``least + 3``, the first that reaches 95 % fill,
    else the best."""

    def fill(n: int) -> float:
        total = n * compact + heartbeat
        return total / (-(-total // payload) * payload)

    candidates = range(least, least + 4)
    return next((n for n in candidates if fill(n) >= 0.95), max(candidates, key=fill))


# Compact2 (motors, height, vz, set point, flags, lift trim: the rest of the flight screen) goes once per heartbeat
# period, 10 Hz: the pilot reads those figures, the phone's attitude moves faster.
COMPACT2_PER_HEARTBEAT = 1
# Derived from the frame sizes, so a change to any of the packets keeps the notifications full: with the 16-byte
# Compact, the 20-byte Compact2 and the 14-byte Heartbeat, four Compacts, a Compact2 and a heartbeat are 98 bytes,
# five notifications 98 % full (without Compact2: 78 bytes, four notifications, 97.5 %).
COMPACT_PER_HEARTBEAT = compacts_per_heartbeat(
    SPEC_OF[Compact].frame_size,
    SPEC_OF[Heartbeat].frame_size + COMPACT2_PER_HEARTBEAT * SPEC_OF[Compact2].frame_size)


def board_name(board_id: int) -> str:
    return f"{NAME_PREFIX} {board_id}"


# --- the sans-IO link ---------------------------------------------------------------------------------------


@dataclass
class WirelessStats:
    notifications: int = 0  # notifications handed to the radio
    payload_bytes: int = 0  # bytes in them
    largest: int = 0  # the largest notification (never above NOTIFY_PAYLOAD)
    urgent_flushes: int = 0  # flushes forced by a heartbeat
    frames_queued: int = 0
    tx_dropped: int = 0  # bytes queued while no phone was connected, or thrown away at a disconnection
    rx_bytes: int = 0  # bytes the phone wrote
    rx_ignored: int = 0  # bytes written before the handover (DISCONNECTED): the board does not read them
    compacts: int = 0  # Compact frames queued
    compact_skipped: int = 0  # Compact frames beyond COMPACT_PER_HEARTBEAT in one heartbeat period
    compact2s: int = 0  # Compact2 frames queued
    heartbeats_queued: int = 0
    answers_dropped: int = 0  # answers refused for a backlog over ANSWER_BUDGET (the phone's radio stalls)
    payload: int = NOTIFY_PAYLOAD

    @property
    def fill_pct(self) -> float:
        """Mean notification fill: payload bytes per notification over the 20 a notification can carry."""
        if not self.notifications:
            return 0.0
        return 100.0 * self.payload_bytes / (self.notifications * self.payload)


class WirelessLink:
    """The board's side of the BLE handover and its transmit queue. Sans-IO: no clock, no radio.

    The board calls:

    - ``connected()`` / ``disconnected()`` when the radio reports them (``disconnected()`` returns True if the
      board was being flown over BLE: it must PANIC if it is flying);
    - ``request_start()`` for ``Command(op=Op.WIRELESS, arg=1)`` once its own mode check (SAFE) passed, and
      ``request_stop()`` for ``arg=0`` after the Ack went out;
    - ``ble_receive(data)`` with what the phone wrote: the bytes for the parser, or ``b''`` while the board
      does not read BLE;
    - ``send(pkt)`` for every packet it sends (heartbeats, acks, events, Compact): the link decides whether it
      goes over BLE; ``reads_uart`` / ``writes_uart`` say whether the cable is still in use;
    - ``notifications()`` for what the radio must send now (the radio does this itself, woken by ``on_ready``).
    """

    def __init__(self, payload: int = NOTIFY_PAYLOAD, on_ready: Callable[[], None] | None = None,
                 compact2_per_heartbeat: int = COMPACT2_PER_HEARTBEAT) -> None:
        if payload < 1:
            raise ValueError("payload must be at least one byte")
        self.payload = payload
        self.compact2_per_heartbeat = compact2_per_heartbeat  # 0: Compact only (bench.ble compares)
        self.on_ready = on_ready  # called when notifications are waiting (the radio's wake-up)
        self.encoder = Encoder()  # BLE has its own sequence numbers: the phone sees no gaps from UART frames
        self.stats = WirelessStats(payload=payload)
        self._state = WirelessState.DISCONNECTED
        self._connected = False
        self._tx = bytearray()  # the ble_tx_queue
        self._ready: list[bytes] = []  # whole notifications waiting for the radio
        self._compacts = 0  # Compact frames queued since the last heartbeat
        self._compact2s = 0  # Compact2 frames queued since the last heartbeat
        self.bytes_queued = 0  # frame bytes ever queued, and ever handed to the radio: what still waits
        self.bytes_taken = 0
        self.transitions: list[tuple[WirelessState, WirelessState]] = []  # drained by the board (events)

    # --- state ----------------------------------------------------------------------------------------------

    @property
    def state(self) -> WirelessState:
        return self._state

    @property
    def is_connected(self) -> bool:
        """A phone holds a BLE connection (the firmware's valid m_conn_handle)."""
        return self._connected

    @property
    def reads_uart(self) -> bool:
        """The parser reads the UART; once STARTED it reads only BLE."""
        return self._state is not WirelessState.STARTED

    @property
    def writes_uart(self) -> bool:
        """Replies and telemetry go to the UART; once STARTED they go only to BLE."""
        return self._state is not WirelessState.STARTED

    @property
    def writes_ble(self) -> bool:
        """Replies go to BLE (STARTED). In STARTING only heartbeats do (see ``send``)."""
        return self._state is WirelessState.STARTED

    def _set(self, new: WirelessState) -> None:
        if new is not self._state:
            self.transitions.append((self._state, new))
            self._state = new

    def take_transitions(self) -> list[tuple[WirelessState, WirelessState]]:
        """State changes since the last call, oldest first (for the board's WIRELESS_STATE events)."""
        out, self.transitions = self.transitions, []
        return out

    # --- events from the radio ------------------------------------------------------------------------------

    def connected(self) -> None:
        """A phone connected. Nothing else changes: the pilot still has to press the wireless key."""
        self._connected = True

    def disconnected(self) -> bool:
        """The connection is gone: back to DISCONNECTED, the UART resumes, the tx queue is dropped. Returns True
        if the board was reading its commands from BLE (STARTED): a flying board must PANIC."""
        was_started = self._state is WirelessState.STARTED
        self._connected = False
        self.stats.tx_dropped += len(self._tx) + sum(len(n) for n in self._ready)
        self._tx.clear()
        self._ready.clear()
        self.bytes_taken = self.bytes_queued
        self._set(WirelessState.DISCONNECTED)
        return was_started

    def ble_receive(self, data: bytes) -> bytes:
        """Bytes the phone wrote. Returns what the parser must read (all of it once STARTING or STARTED; the
        first data in STARTING moves to STARTED), or ``b''`` before the handover."""
        self.stats.rx_bytes += len(data)
        if not data:
            return b""
        if not self._connected or self._state is WirelessState.DISCONNECTED:
            self.stats.rx_ignored += len(data)
            return b""
        if self._state is WirelessState.STARTING:
            self._set(WirelessState.STARTED)
        return bytes(data)

    # --- commands -------------------------------------------------------------------------------------------

    def request_start(self) -> Nak:
        """The wireless key (``Op.WIRELESS`` arg 1), after the board checked it is in SAFE. Needs a connection;
        moves DISCONNECTED to STARTING (already STARTING or STARTED: accepted, nothing changes)."""
        if not self._connected:
            return Nak.NO_BLE_CONNECTION
        if self._state is WirelessState.DISCONNECTED:
            self._set(WirelessState.STARTING)
        return Nak.OK

    def request_stop(self) -> Nak:
        """Hand control back to the cable (``Op.WIRELESS`` arg 0). The connection stays; the handover can be
        repeated. Call it after the Ack was sent, so that the Ack still goes where the command came from."""
        self.flush()
        self._set(WirelessState.DISCONNECTED)
        return Nak.OK

    # --- transmit -------------------------------------------------------------------------------------------

    def ble_wants(self, pkt: Any) -> bool:
        """Whether ``pkt`` goes over BLE now: heartbeats from STARTING on; in STARTED everything except the full
        UART telemetry (the phone shows only the Compact packet)."""
        if not self._connected:
            return False
        kind = type(pkt)
        if kind is Heartbeat:
            return self._state is not WirelessState.DISCONNECTED
        return self._state is WirelessState.STARTED and kind not in TELEMETRY

    def compact_due(self) -> bool:
        """Whether a Compact frame is wanted now: over BLE (STARTED) and fewer than ``COMPACT_PER_HEARTBEAT``
        since the last heartbeat. Ask at every telemetry tick (any rate of 30 Hz or more): the notifications
        then stay full whatever the phases of the board's telemetry and heartbeat timers."""
        return (
            self._connected
            and self._state is WirelessState.STARTED
            and self._compacts < COMPACT_PER_HEARTBEAT
        )

    def compact2_due(self) -> bool:
        """Whether a Compact2 frame is wanted now: over BLE (STARTED) and fewer than ``compact2_per_heartbeat``
        since the last heartbeat (ask at every telemetry tick, as for ``compact_due``)."""
        return (
            self._connected
            and self._state is WirelessState.STARTED
            and self._compact2s < self.compact2_per_heartbeat
        )

    @property
    def backlog_bytes(self) -> int:
        """Bytes queued for BLE that the radio has not taken yet."""
        return self.bytes_queued - self.bytes_taken

    def send(self, pkt: Any) -> bool:
        """Encode ``pkt`` with the BLE encoder and queue it if it goes over BLE (``ble_wants``); heartbeats are
        never refused and flush the queue at once. The transmit rule (fcb_sim/board/transmit.py): answers wait only
        while the backlog stays within ``ANSWER_BUDGET``; a Compact beyond ``COMPACT_PER_HEARTBEAT`` per
        heartbeat period, or over a full backlog, is skipped (the phone shows the latest anyway), and so is a Compact2
        beyond ``compact2_per_heartbeat``. Returns True if it was queued."""
        if not self.ble_wants(pkt):
            return False
        kind = type(pkt)
        size = SPEC_OF[kind].frame_size
        if kind is Compact:
            if self._compacts >= COMPACT_PER_HEARTBEAT or self.backlog_bytes + size > ANSWER_BUDGET:
                self.stats.compact_skipped += 1
                return False
            self._compacts += 1
            self.stats.compacts += 1
        elif kind is Compact2:
            if self._compact2s >= self.compact2_per_heartbeat or self.backlog_bytes + size > ANSWER_BUDGET:
                self.stats.compact_skipped += 1
                return False
            self._compact2s += 1
            self.stats.compact2s += 1
        elif kind is Heartbeat:
            self._compacts = self._compact2s = 0
            self.stats.heartbeats_queued += 1
        elif self.backlog_bytes + size > ANSWER_BUDGET:
            self.stats.answers_dropped += 1
            return False
        self.queue(self.encoder.encode(pkt), urgent=kind is Heartbeat)
        return True

    def queue(self, frame: bytes, urgent: bool = False) -> None:
        """Queue an encoded frame for BLE. Full 20-byte notifications are cut as soon as they are ready; the rest
        waits, unless ``urgent`` (a heartbeat), which sends everything queued at once."""
        if not self._connected:
            self.stats.tx_dropped += len(frame)
            return
        self.stats.frames_queued += 1
        self.bytes_queued += len(frame)
        self._tx += frame
        n = self.payload
        cut = len(self._tx) - len(self._tx) % n
        if urgent and len(self._tx) > cut:
            cut = len(self._tx)
            self.stats.urgent_flushes += 1
        if cut:
            self._emit(cut)

    def flush(self) -> None:
        """Send whatever is queued now, even a partial notification."""
        if self._tx:
            self._emit(len(self._tx))

    def _emit(self, cut: int) -> None:
        n = self.payload
        data = bytes(self._tx[:cut])
        del self._tx[:cut]
        chunks = [data[i : i + n] for i in range(0, len(data), n)]
        st = self.stats
        st.notifications += len(chunks)
        st.payload_bytes += len(data)
        st.largest = max(st.largest, max(len(c) for c in chunks))
        self._ready.extend(chunks)
        if self.on_ready is not None:
            self.on_ready()

    @property
    def pending(self) -> int:
        """Bytes waiting in the tx queue for a full notification."""
        return len(self._tx)

    def notifications(self) -> list[bytes]:
        """The notifications to send now, in order; each at most ``payload`` (20) bytes."""
        out, self._ready = self._ready, []
        self.bytes_taken += sum(len(n) for n in out)
        return out
