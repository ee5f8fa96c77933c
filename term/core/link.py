"""The PC side of a link to the board, sans-IO (in the style of h11): bytes and time in, bytes and events out.

A ``LinkSession`` knows the protocol's rules for talking to a board and nothing about how bytes travel:

- it answers every ``Heartbeat`` with a ``HeartbeatAck`` at once (queued ahead of everything else);
- it sends keyboard ``Command``s one at a time, in order (the next leaves when the previous one is answered or
  given up), retries one that is not acknowledged within ``command_timeout`` up to ``command_retries`` times,
  then reports ``CommandFailed`` with the reason; a NAK reports the board's reason. One in flight keeps the
  order of mode requests and lets the board spot a retry by remembering only its last command (it must answer
  a repeat of its last (cmd_id, op, arg) with the same Ack without doing it again). A PANIC request jumps the
  queue and cancels what waits before it; presses of a stepping op (``STEP_OPS``) not sent yet add up in one
  command (docs/link.md);
- it sends the joystick latest-wins (a new value replaces an unsent one, never queues behind it), at most
  ``joystick_rate`` times per second, and with ``change_only`` (BLE, and the serial ``stream`` policy) only when
  the value changed, plus a keep-alive every ``keepalive`` seconds, which never delays the next change;
- it keeps the statistics a pilot needs to trust the link (``stats_at(now)`` / ``stats``), declares the link
  lost after ``link_timeout`` seconds without a valid frame and restored at the next one (before the board's first
  frame the link is still being made: the start-up grace ``connect_timeout`` applies); time the caller says
  it could not run (``starved``: its process got no CPU) is not the board's silence, so a starved terminal does
  not call a loss for frames that waited in the OS;
- it sends a ``Hello`` at connect and reports a board that speaks another protocol version;
- it gives the board's text as ``ConsoleLine`` events (``term.core.console``): what the board prints between frames
  (printf on the UART) and its ``Text`` packets (``qb_log``), as lines, rate-limited (``console``); what the limit
  drops, as ``ConsoleDropped``.

Nothing here reads a clock: every call takes ``now`` (seconds, any monotonic origin). The caller (an asyncio
pump in ``term.session.connection``, a test with a fake clock, a benchmark) owns time and I/O.

What the figures mean (RTT from heartbeats and command round trips, Karn's rule, the heartbeat delay, loss from
sequence numbers): docs/link.md.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

from term.core.console import Console, ConsoleDropped, ConsoleLine
from term.core.protocol import (
    LINK_TIMEOUT_S,
    NAK_TEXT,
    PROTOCOL_VERSION,
    STEP_OPS,
    Ack,
    Command,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Hello,
    Joystick,
    Mode,
    Nak,
    Op,
    Role,
    Text,
    scaled,
)

RTT_SAMPLES = 200  # RTT mean and p95 are over the last this many samples
_EPS = 1e-9  # s: float slack for schedules computed by repeated addition
HB_DELAY_WINDOW = 10.0  # s: the baseline (smallest) heartbeat delay is taken over this window
# s a board may take to say its first word: a Hello is answered in milliseconds, but a board the port's open resets
# boots for a second or two, and a simulator on a busy laptop was seen without CPU for 0.8 s at start-up (issue 21)
CONNECT_TIMEOUT_S = 3.0


# --- events -------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class PacketReceived:
    """Any valid packet from the board (heartbeats and acks included, so a recorder sees everything)."""

    packet: Any


@dataclass(frozen=True, slots=True)
class CommandAcked:
    cmd_id: int
    op: Op
    arg: int
    value: int


@dataclass(frozen=True, slots=True)
class CommandFailed:
    """A command the board refused (``nak`` is its reason) or that could not be delivered (``nak`` is None)."""

    cmd_id: int
    op: Op
    arg: int
    reason: str
    nak: Nak | None


@dataclass(frozen=True, slots=True)
class LinkLost:
    silent_s: float = 0.0  # how long nothing valid arrived when the loss was declared
    never_heard: bool = False  # not one frame since the link opened (the start-up grace ran out)


@dataclass(frozen=True, slots=True)
class LinkRestored:
    lost_for_s: float = 0.0


@dataclass(frozen=True, slots=True)
class VersionMismatch:
    board_version: int
    our_version: int


LinkEvent = (PacketReceived | CommandAcked | CommandFailed | LinkLost | LinkRestored | VersionMismatch | ConsoleLine
             | ConsoleDropped)


# --- statistics ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LinkStats:
    """A snapshot of the link's health at one instant. Figures that have no sample yet are None."""

    rtt_last_ms: float | None
    rtt_mean_ms: float | None
    rtt_p95_ms: float | None
    loss_pct: float | None  # board-to-PC, over the last stats_window seconds; None if nothing was due
    loss_pct_total: float  # board-to-PC since the start
    rx_bytes_per_s: float
    tx_bytes_per_s: float
    frames_ok: int
    frames_bad: int  # CRC failures and malformed frames
    since_last_frame_s: float | None  # None: nothing valid received yet
    since_last_heartbeat_s: float | None
    heartbeat_delay_ms: float | None
    lost: bool
    rx_bytes: int
    tx_bytes: int
    commands_sent: int  # distinct commands, retries not counted
    command_retries: int
    commands_failed: int  # not delivered or cancelled (timeouts, lost link, PANIC, full queue); not NAKs
    heartbeats: int
    board_version: int | None  # from the board's Hello


def _p95(samples: list[float]) -> float:
    ordered = sorted(samples)
    return ordered[max(0, math.ceil(0.95 * len(ordered)) - 1)]  # nearest rank


class _Window:
    """Sums of a quantity over a sliding time window."""

    def __init__(self, span: float) -> None:
        self.span = span
        self._items: deque[tuple[float, int, int]] = deque()
        self.a = 0
        self.b = 0

    def add(self, t: float, a: int, b: int = 0) -> None:
        self._items.append((t, a, b))
        self.a += a
        self.b += b

    def prune(self, now: float) -> None:
        items = self._items
        while items and items[0][0] <= now - self.span:
            _, a, b = items.popleft()
            self.a -= a
            self.b -= b


@dataclass
class _Pending:
    cmd_id: int
    op: Op
    arg: int
    attempts: int = 0
    first_sent: float = 0.0
    last_sent: float = 0.0


def _as_op(op: int) -> Op | int:
    try:
        return Op(op)
    except ValueError:
        return op


# --- the session --------------------------------------------------------------------------------------------


class LinkSession:
    """The PC side of one link to a board. See the module docstring for the rules it keeps."""

    def __init__(
        self,
        now: float,
        *,
        link_timeout: float = LINK_TIMEOUT_S,
        connect_timeout: float = CONNECT_TIMEOUT_S,
        command_timeout: float = 0.25,
        command_retries: int = 3,
        joystick_rate: float = 100.0,
        change_only: bool = False,
        keepalive: float = 0.5,
        stats_window: float = 2.0,
        max_queued: int = 32,
    ) -> None:
        for name, value in (("link_timeout", link_timeout), ("connect_timeout", connect_timeout),
                            ("command_timeout", command_timeout),
                            ("joystick_rate", joystick_rate), ("keepalive", keepalive), ("stats_window", stats_window)):
            # (a nan passes a "<= 0" test and a timer that never fires spins the terminal; inf never fires at all)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
                raise ValueError(f"{name} must be a finite number above 0, got {value!r}")
        if isinstance(command_retries, bool) or not isinstance(command_retries, int) or command_retries < 0:
            raise ValueError(f"command_retries must be a whole number >= 0, got {command_retries!r}")
        if not 0 < max_queued < 255:
            raise ValueError("max_queued must be in 1..254 (command ids are 8-bit)")
        self.link_timeout = link_timeout
        self.connect_timeout = connect_timeout
        self.command_timeout = command_timeout
        self.command_retries = command_retries
        self.joystick_interval = 1.0 / joystick_rate
        self.change_only = change_only
        self.keepalive = keepalive
        self.max_queued = max_queued

        self.encoder = Encoder()
        self.decoder = Decoder(keep_text=True)
        self.console = Console()
        self._start = now
        self._now = now
        self._init_queues()
        self._init_stats(stats_window)

    def _init_queues(self) -> None:
        """What waits to go out (frames, commands, the joystick) and what the board last told us."""
        self._urgent: list[bytes] = []  # heartbeat ACKs and Hellos: out before anything else
        self._events: list[LinkEvent] = []  # produced outside receive/poll, delivered by the next of them
        self._new: deque[_Pending] = deque()  # commands not sent yet, in order
        self._inflight: dict[int, _Pending] = {}  # sent, waiting for its Ack: at most one
        self._next_id = 0

        self._js: Joystick | None = None
        self._js_sent: Joystick | None = None
        self._js_last = -math.inf  # when the joystick was last sent
        self._js_next = -math.inf  # the earliest time the next one may go (the rate limit)

        self._last_frame: float | None = None
        self._deaf: list[tuple[float, float]] = []  # when the caller could not run (``starved``): not silence
        self._last_hb: float | None = None
        self._lost = False
        self._lost_since = 0.0
        self._mismatch: VersionMismatch | None = None
        self.board_hello: Hello | None = None

    def _init_stats(self, stats_window: float) -> None:
        """The counters and windows behind ``stats_at``."""
        self._rtt: deque[float] = deque(maxlen=RTT_SAMPLES)
        self._hb_delays: deque[tuple[float, float]] = deque()
        self._hb_delay_ms: float | None = None
        self._rx = _Window(stats_window)
        self._tx = _Window(stats_window)
        self._seq = _Window(stats_window)  # a: frames ok, b: frames missing
        self._missing_total = 0
        self._rx_bytes = 0
        self._tx_bytes = 0
        self._commands_sent = 0
        self._retries = 0
        self._failed = 0
        self._heartbeats = 0

    # --- input ----------------------------------------------------------------------------------------------

    def hello(self) -> bytes:
        """Our Hello frame: write it when the transport opens. The board answers with its own."""
        frame = self._encode_hello()
        self._count_tx(frame, self._now)
        return frame

    def receive(self, data: bytes, now: float) -> list[LinkEvent]:
        """Feed bytes from the transport; returns the events they cause. Heartbeat ACKs are queued at the head
        of the output: call ``data_to_send(now)`` right after this to send them."""
        self._now = now
        events = self._take_events()
        self._check_timers(now, events)
        if data:
            self._rx_bytes += len(data)
            self._rx.add(now, len(data))
        stats = self.decoder.stats
        gaps_before = stats.seq_gaps
        packets = self.decoder.feed(data)
        text = self.decoder.take_text()
        if text:
            events += self.console.feed_bytes(text, now)
        missing = stats.seq_gaps - gaps_before
        if not packets:
            if missing:
                self._count_seq(now, 0, missing)
            return events
        if any(type(p) is Hello for p in packets):
            missing = 0  # a Hello means the board (re)started: its sequence jump is not loss
        self._count_seq(now, len(packets), missing)
        if self._lost:
            self._lost = False
            events.append(LinkRestored(now - self._lost_since))
            self._urgent.append(self._encode_hello())  # the board may have restarted: handshake again
        self._last_frame = now
        for pkt in packets:
            kind = type(pkt)
            if kind is Heartbeat:
                self._urgent.append(self.encoder.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))
                self._on_heartbeat(pkt, now)
            elif kind is Ack:
                self._on_ack(pkt, now, events)
            elif kind is Hello:
                self._on_hello(pkt, events)
            elif kind is Text:
                events += self.console.feed_packet(pkt, now)
            events.append(PacketReceived(pkt))
        return events

    def send_command(self, op: Op, arg: int = 0, now: float | None = None) -> int:
        """Queue a keyboard command; returns its cmd_id. The outcome arrives as CommandAcked or CommandFailed.
        To a lost link or a mismatched board it fails at once (delivered by the next ``poll``)."""
        if now is not None:
            self._now = now
        panic = op == Op.MODE and arg == Mode.PANIC
        if panic:  # safety first: nothing queued or unanswered may hold a PANIC back
            self._cancel_all("cancelled: PANIC requested", self._events)
        reason = self._refusal()
        last = self._new[-1] if self._new else None
        if reason is None and op in STEP_OPS and last is not None and last.op == op:
            last.arg += int(arg)  # one command for the burst: its Ack settles every press merged into it
            return last.cmd_id
        cmd_id = self._alloc_id()
        if len(self._new) >= self.max_queued:
            reason = "too many commands waiting for the board: wait for its answers"
        pending = _Pending(cmd_id, _as_op(op), int(arg))  # type: ignore[arg-type]
        self._commands_sent += 1
        if reason is not None:
            self._failed += 1
            self._events.append(CommandFailed(cmd_id, pending.op, pending.arg, reason, None))
        else:
            self._new.append(pending)
        return cmd_id

    def set_joystick(self, js: Joystick) -> None:
        """The latest stick position; replaces any value not sent yet."""
        self._js = js

    # --- output and timers ----------------------------------------------------------------------------------

    def data_to_send(self, now: float) -> bytes:
        """Everything due now, in order: heartbeat ACKs (and Hellos), a changed stick before a new command, new
        commands and retries, the joystick."""
        self._now = now
        parts = self._urgent
        self._urgent = []
        enc = self.encoder
        if self._new and not self._inflight and self._js is not None and self._js != self._js_sent \
                and self._mismatch is None:
            # A changed stick goes ahead of a command, whatever the rate: the board must read the stick the pilot
            # set before the key (lift to zero, then SAFE), not the one before it.
            parts.append(enc.encode(self._js))
            self._js_sent, self._js_last, self._js_next = self._js, now, now + self.joystick_interval
        while self._new and not self._inflight:  # one in flight: the next leaves when this one is settled
            p = self._new.popleft()
            p.attempts = 1
            p.first_sent = p.last_sent = now
            self._inflight[p.cmd_id] = p
            parts.append(enc.encode(Command(p.cmd_id, p.op, p.arg)))
        for p in self._inflight.values():
            if p.attempts <= self.command_retries and now >= p.last_sent + self.command_timeout:
                p.attempts += 1
                p.last_sent = now
                self._retries += 1
                parts.append(enc.encode(Command(p.cmd_id, p.op, p.arg)))
        if self._joystick_due(now):
            js = self._js
            parts.append(enc.encode(js))
            keepalive = self.change_only and js == self._js_sent
            self._js_sent = js
            self._js_last = now
            # A keep-alive (change_only: the same value again) does not hold back the next change: a change just
            # after it goes at once, not one rate interval later. At most one keep-alive per ``keepalive`` s
            # rides on top of the rate.
            if not keepalive:
                # Keep a steady grid when a send is a little late (a timer wakes up late), so the rate stays at
                # joystick_rate instead of drifting down; after a longer pause start a new grid. Either way two
                # sends are at least half an interval apart.
                late = now - self._js_next
                self._js_next = self._js_next + self.joystick_interval if late < self.joystick_interval / 2 else (
                    now + self.joystick_interval
                )
        if not parts:
            return b""
        out = b"".join(parts)
        self._count_tx(out, now)
        return out

    def starved(self, since: float, until: float) -> None:
        """The caller could not run from ``since`` to ``until`` (its process got no CPU: a timer that fired that
        late). The board's frames of that time waited in the OS, so that time is not the board's silence."""
        if until > since:
            self._deaf.append((since, until))

    def poll(self, now: float) -> list[LinkEvent]:
        """Run the timers: commands that ran out of retries, the link-lost timeout."""
        self._now = now
        events = self._take_events()
        self._check_timers(now, events)
        return events

    def next_deadline(self) -> float:
        """The time at which ``poll``/``data_to_send`` have something to do (``-inf`` if already due, ``inf``
        if nothing is scheduled)."""
        if self._events or self._urgent or (self._new and not self._inflight):
            return -math.inf
        deadlines = [p.last_sent + self.command_timeout for p in self._inflight.values()]
        if not self._lost:
            start = self._silence_start()
            deadlines.append(start + self._loss_timeout() + self._deaf_since(start, None))
        js = self._joystick_deadline()
        if js is not None:
            deadlines.append(js)
        return min(deadlines, default=math.inf)

    # --- statistics -----------------------------------------------------------------------------------------

    @property
    def lost(self) -> bool:
        return self._lost

    @property
    def stats(self) -> LinkStats:
        """Statistics as of the last time passed in (any call); ``stats_at(now)`` for a fresh instant."""
        return self.stats_at(self._now)

    def stats_at(self, now: float) -> LinkStats:
        for w in (self._rx, self._tx, self._seq):
            w.prune(now)
        span = min(self._rx.span, now - self._start)
        rtts = list(self._rtt)
        expected = self._seq.a + self._seq.b
        ok_total = self.decoder.stats.frames_ok
        expected_total = ok_total + self._missing_total
        return LinkStats(
            rtt_last_ms=rtts[-1] * 1e3 if rtts else None,
            rtt_mean_ms=sum(rtts) / len(rtts) * 1e3 if rtts else None,
            rtt_p95_ms=_p95(rtts) * 1e3 if rtts else None,
            loss_pct=100.0 * self._seq.b / expected if expected else None,
            loss_pct_total=100.0 * self._missing_total / expected_total if expected_total else 0.0,
            rx_bytes_per_s=self._rx.a / span if span > 0 else 0.0,
            tx_bytes_per_s=self._tx.a / span if span > 0 else 0.0,
            frames_ok=ok_total,
            frames_bad=self.decoder.stats.frames_bad,
            since_last_frame_s=None if self._last_frame is None else now - self._last_frame,
            since_last_heartbeat_s=None if self._last_hb is None else now - self._last_hb,
            heartbeat_delay_ms=self._hb_delay_ms,
            lost=self._lost,
            rx_bytes=self._rx_bytes,
            tx_bytes=self._tx_bytes,
            commands_sent=self._commands_sent,
            command_retries=self._retries,
            commands_failed=self._failed,
            heartbeats=self._heartbeats,
            board_version=None if self.board_hello is None else self.board_hello.protocol,
        )

    # --- internals ------------------------------------------------------------------------------------------

    def _take_events(self) -> list[LinkEvent]:
        events = self._events
        self._events = []
        return events

    def _encode_hello(self) -> bytes:
        return self.encoder.encode(Hello(PROTOCOL_VERSION, Role.TERMINAL, 0, 1, 0))

    def _count_tx(self, data: bytes, now: float) -> None:
        self._tx_bytes += len(data)
        self._tx.add(now, len(data))

    def _count_seq(self, now: float, ok: int, missing: int) -> None:
        self._seq.add(now, ok, missing)
        self._missing_total += missing

    def _loss_timeout(self) -> float:
        """The silence that is a lost link: the link timeout once the board has spoken, the start-up grace before."""
        if self._last_frame is None:
            return max(self.link_timeout, self.connect_timeout)
        return self.link_timeout

    def _silence_start(self) -> float:
        return self._start if self._last_frame is None else self._last_frame

    def _deaf_since(self, start: float, now: float | None) -> float:
        """How long, since ``start`` (until ``now``; None: all of it), the caller could not listen."""
        if not self._deaf:
            return 0.0  # (the common case, at every poll: no list built)
        self._deaf = [(a, b) for a, b in self._deaf if b > start]
        end = math.inf if now is None else now
        return sum(max(0.0, min(b, end) - max(a, start)) for a, b in self._deaf)

    def _silent(self, now: float) -> float:
        """The board's silence: since its last frame, less the time the caller could not listen."""
        start = self._silence_start()
        return now - start - self._deaf_since(start, now)

    def _alloc_id(self) -> int:
        # Consecutive ids (mod 256); at most 1 + max_queued (< 256) are alive, so an id is never reused while
        # its command still waits.
        cmd_id = self._next_id
        self._next_id = (cmd_id + 1) & 0xFF
        return cmd_id

    def _cancel_all(self, reason: str, events: list[LinkEvent]) -> None:
        for p in [*self._inflight.values(), *self._new]:
            self._failed += 1
            events.append(CommandFailed(p.cmd_id, p.op, p.arg, reason, None))
        self._inflight.clear()
        self._new.clear()

    def _refusal(self) -> str | None:
        if self._mismatch is not None:
            m = self._mismatch
            return f"board speaks protocol v{m.board_version}, terminal v{m.our_version}: update one of them"
        if self._lost:
            return f"link lost: nothing from the board for {self._now - self._silence_start():.1f} s"
        return None

    def _check_timers(self, now: float, events: list[LinkEvent]) -> None:
        silent = self._silent(now)
        if not self._lost and silent >= self._loss_timeout():
            self._lost = True
            self._lost_since = self._silence_start()
            self.decoder.reset_sequence()  # frames missed while silent are not countable modulo 256
            events.append(LinkLost(silent, never_heard=self._last_frame is None))
            self._cancel_all(f"link lost: nothing from the board for {silent:.1f} s", events)
            return
        if not self._inflight:
            return
        expired = [
            p
            for p in self._inflight.values()
            if p.attempts > self.command_retries and now >= p.last_sent + self.command_timeout
        ]
        for p in expired:
            del self._inflight[p.cmd_id]
            self._failed += 1
            waited = now - p.first_sent
            reason = f"no answer from the board after {p.attempts} tries ({waited:.2f} s)"
            events.append(CommandFailed(p.cmd_id, p.op, p.arg, reason, None))

    def _on_heartbeat(self, hb: Heartbeat, now: float) -> None:
        self._heartbeats += 1
        self._last_hb = now
        delay = now - scaled(hb, "board_ms")  # offset + one-way delay; the offset cancels against the minimum
        delays = self._hb_delays
        while delays and delays[0][0] <= now - HB_DELAY_WINDOW:
            delays.popleft()
        delays.append((now, delay))
        self._hb_delay_ms = (delay - min(d for _, d in delays)) * 1e3
        if hb.rtt:  # the board's own measurement of the previous heartbeat's round trip
            self._rtt.append(hb.rtt * 1e-4)

    def _on_ack(self, ack: Ack, now: float, events: list[LinkEvent]) -> None:
        p = self._inflight.get(ack.cmd_id)
        if p is None or int(p.op) != ack.op:
            return  # a duplicate Ack for a retried command, or one from before a restart: nothing waits for it
        del self._inflight[ack.cmd_id]
        if p.attempts == 1:
            self._rtt.append(now - p.first_sent)
        if ack.status == Nak.OK:
            events.append(CommandAcked(p.cmd_id, p.op, p.arg, ack.value))
            return
        try:
            nak: Nak | None = Nak(ack.status)
            reason = NAK_TEXT[nak]
        except (ValueError, KeyError):
            nak, reason = None, f"refused by the board (reason code {ack.status})"
        events.append(CommandFailed(p.cmd_id, p.op, p.arg, reason, nak))

    def _on_hello(self, hello: Hello, events: list[LinkEvent]) -> None:
        self.board_hello = hello
        if hello.protocol != PROTOCOL_VERSION:
            self._mismatch = VersionMismatch(hello.protocol, PROTOCOL_VERSION)
            events.append(self._mismatch)
            # Commands and sticks in a format the board may misread are not sent (safety); fail what waits.
            self._cancel_all(self._refusal() or "", events)
        else:
            self._mismatch = None

    def _joystick_due(self, now: float) -> bool:
        if self._js is None or self._mismatch is not None:
            return False
        if now < self._js_next - _EPS:
            return False
        if self.change_only and self._js == self._js_sent:
            return now >= self._js_last + self.keepalive - _EPS
        return True

    def _joystick_deadline(self) -> float | None:
        if self._js is None or self._mismatch is not None:
            return None
        if self.change_only and self._js == self._js_sent:
            return max(self._js_next, self._js_last + self.keepalive)
        return self._js_next
