"""What the screen shows, as plain data, rendered by the widgets at a steady rate. No Textual here, no clock
reads: every update takes ``now`` (seconds, the app's monotonic clock).

The model changes in one place: ``apply(event, now)``, which dispatches through a table of handlers
(``_HANDLERS``), one per event type: a link session's events (``term.core.link``; the radio's wrapped in
``term.core.events.FromLink``), the station's (links up and down, retries, commands sent or refused, the stick) and the
front end's (notes, the joystick's name). ``Station.emit`` is its caller; tests may call the handlers' helpers
(``apply_packet``, ``radio_event``, ``set_link_stats``) directly. The two-link rules (which silence is an
alarm, STARTED left only for DISCONNECTED) live in the handlers and the derived properties.

Every telemetry figure knows the time of the packet behind it: ``reading(name, now)`` (term.core.freshness) gives its
value, age, staleness, whether the current link carries it and its bound at the field's limit.

``version`` increases on every change so the renderer can skip frames when nothing happened.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from term.core.console import ConsoleDropped, ConsoleLine
from term.core.events import (
    RADIO,
    EventsCleared,
    FromLink,
    JoystickNamed,
    LinkConnecting,
    LinkDown,
    LinkFailed,
    LinkUp,
    LinkWaiting,
    Note,
    NotSent,
    Requested,
    StatsSample,
    StickSet,
)
from term.core.freshness import Arrivals, Reading, read, spec_of
from term.core.link import (
    CommandAcked,
    CommandFailed,
    LinkLost,
    LinkRestored,
    LinkStats,
    PacketReceived,
    VersionMismatch,
)
from term.core.logfile import LogDownload
from term.core.protocol import (
    FLIGHT_MODES,
    LEVEL_ERROR,
    PARAMS,
    Attitude,
    Compact,
    Compact2,
    Event,
    EventCode,
    Flag,
    Gains,
    Height,
    Hello,
    Joystick,
    LogChunk,
    LogState,
    LogStatus,
    Motion,
    Nak,
    Op,
    Param,
    ParamValue,
    Profile,
    Status,
    WirelessState,
    broken_rules,
    param_split,
    scaled,
)
from term.session.eventlog import REFUSAL_PAIR_S, LogEntry, deadline_miss, note
from term.session.history import Series
from term.session.texts import (  # (the pilot's words: imported from here by the widgets too)
    event_text,
    mode_name,
    op_text,
)

HISTORY = 3000  # samples kept per plotted series (60 s at 50 Hz)


@dataclass
class Model:
    start: float = 0.0
    version: int = 0
    # board state
    mode: int | None = None
    attitude: Attitude | None = None
    motion: Motion | None = None
    height: Height | None = None
    status: Status | None = None
    gains: Gains | None = None
    hello: Hello | None = None
    board_ms: int | None = None
    profiles: dict[int, Profile] = field(default_factory=dict)
    log_status: LogStatus | None = None
    # terminal state
    stick: Joystick = field(default_factory=lambda: Joystick(0, 0, 0, 0, 0))
    joystick_name: str | None = None
    joystick_mapping: str = ""
    link: LinkStats | None = None
    link_lost: bool = False
    link_name: str = ""
    version_mismatch: VersionMismatch | None = None
    download: LogDownload | None = None
    live_url: str = ""  # the live Foxglove server's address while it serves (on screen: who can see the flight)
    recording_error: str = ""  # the session recording stopped (or never started): why; an alarm while set
    download_note: str = ""
    download_note_at: float | None = None  # when it was said (the panel shows it STATUS_LINE_S; None: always)
    events: deque[LogEntry] = field(default_factory=lambda: deque(maxlen=500))
    history: dict[str, Series] = field(default_factory=dict)  # preallocated rings (term/session/history.py)
    pending: int = 0  # commands sent and not yet answered
    own: set[int] = field(default_factory=set)  # cmd_ids the terminal sent on its own: no error if they fail
    wireless: int = 0  # WirelessState, as the board last said
    compact: Compact | None = None  # the phone's telemetry (over BLE): mode, attitude, battery
    compact2: Compact2 | None = None  # the rest of the flight screen over BLE: motors, height, vz, flags, lift trim
    flag_bits: int = 0  # the board's status bits from the latest of Status (cable) and Compact2 (BLE)
    # The radio: a second link over BLE beside the cable (term --sim, term --serial P --ble A). Empty name: none.
    # ``primary_ble``: the only link is BLE (term --ble), so it always carries control.
    radio_name: str = ""
    radio: LinkStats | None = None
    radio_up: bool = False  # the BLE connection is open
    radio_lost: bool = False  # STARTED, yet nothing from the board over BLE for the link timeout
    radio_note: str = ""  # why the radio is down and when it is tried again
    primary_ble: bool = False
    heard: bool = False  # a valid frame arrived from the board (on any link)
    arrivals: Arrivals = field(default_factory=Arrivals)  # when each telemetry packet came: term.core.freshness
    refused: dict[int, tuple[str, float]] = field(default_factory=dict)  # Nak -> (the refusal's text, when)
    params: dict[str, float | str | bool] = field(default_factory=dict)  # the board's parameters by name, as heard
    param_raw: dict[int, int] = field(default_factory=dict)  # Param -> raw value, as heard
    param_refused: dict[str, str] = field(default_factory=dict)  # name -> why the board refused the last set
    event_times: dict[int, float] = field(default_factory=dict)  # EventCode -> when the board last said it
    event_args: dict[int, int] = field(default_factory=dict)  # EventCode -> its arg the last time
    notes_written: int = 0  # lines written to the events list (merged repeats too): LogEntry.seq
    console: deque[tuple[float, ConsoleLine]] = field(default_factory=lambda: deque(maxlen=2000))  # (t, line)
    console_dropped: int = 0  # lines the link's rate limit dropped (term.core.console)
    _refusal_said: dict[tuple[int, int], float] = field(default_factory=dict)  # (mode, Nak) -> when said
    _misses: tuple[int, int, float, int] = (0, 0, 0.0, 0)  # deadline misses: count, longest period, first, seq
    _erasing: int | None = None  # records in the log when its erase was asked for
    _bad_noted: int = 0
    _link_noted: float = -1e9
    _lost_to_ble: bool = False  # the cable went quiet because the board flies over BLE (the handover)
    _loss_noted: float = -1e9

    # --- updates ------------------------------------------------------------------------------------------

    def note(self, now: float, severity: str, source: str, text: str) -> None:
        """A line in the events list, merged with a repeat of it (term/session/eventlog.py)."""
        note(self, now, severity, source, text)

    def _refusal(self, mode: int, nak: int, text: str, now: float) -> bool:
        """Note a refusal of ``mode`` for ``nak`` (its readiness item shows it); False if it was just said (the
        board answers a refused mode twice: the Ack's NAK and a REFUSED event)."""
        self.refused[nak] = (text, now)
        said = self._refusal_said.get((mode, nak))
        self._refusal_said[(mode, nak)] = now
        return said is None or now - said > REFUSAL_PAIR_S

    def apply(self, event: Any, now: float) -> None:
        """The one way the model changes: one event, from a link's session (the board's link; the radio's come
        wrapped in ``FromLink``), from the station (``term.core.events``) or from the front end."""
        handler = _HANDLERS.get(type(event))
        if handler is not None:
            handler(self, event, now)

    # --- the board's link's session events ------------------------------------------------------------------

    def _on_packet(self, event: PacketReceived, now: float) -> None:
        self.heard = True
        self.apply_packet(event.packet, now)

    def _on_acked(self, event: CommandAcked, now: float) -> None:
        self.version += 1
        self.own.discard(event.cmd_id)
        self.pending = max(0, self.pending - 1)
        self.arrivals.note_ack(event.op, event.value, now)  # a trim's Ack carries the new trim
        said = _LOG_ACKS.get(event.op)
        if said is not None:
            self.note(now, "info", "term", said(self, event.value))
        if event.op == Op.SET_PARAM:
            self._param(param_split(event.arg)[0], event.value)
        elif event.op == Op.PARAM_GET:
            self._param(event.arg, event.value)

    def _on_failed(self, event: CommandFailed, now: float) -> None:
        self.version += 1
        self.pending = max(0, self.pending - 1)
        what = op_text(event.op, event.arg)
        reason = event.reason
        if event.nak is not None and event.op == Op.SET_PARAM:
            pid, raw = param_split(event.arg)
            spec = PARAMS.get(pid)  # type: ignore[call-overload]
            if spec is not None:
                if event.nak == Nak.PARAM_RULE:
                    reason = self._rule_reason(spec.param, raw, reason)
                self.param_refused[spec.name] = reason
        elif event.nak == Nak.INVALID_TRANSITION and event.op == Op.MODE and self.mode is not None:
            reason = f"not allowed from {mode_name(self.mode)}"  # (the pilot reads which mode it was in)
        if event.cmd_id in self.own and event.op == Op.PARAM_LIST:
            self.own.discard(event.cmd_id)  # asked again at the board's next Hello (F11's r asks now)
            return
        if event.op == Op.PARAM_LIST and event.nak in (Nak.NOT_IMPLEMENTED, Nak.UNKNOWN_COMMAND):
            # the terminal asks every board it meets; one without parameters is no error
            self.note(now, "info", "params", f"this board has no parameter list ({event.reason})")
            return
        if event.nak is not None:
            text = f"NAK {what}: {reason}"
            mode = event.arg if event.op == Op.MODE else -1
            if self._refusal(mode, int(event.nak), text, now):
                self.note(now, "error", "nak", text)
        elif event.op in (Op.LOG_DOWNLOAD, Op.LOG_STATUS) and self.download is not None:
            # The log download retries its own requests until its deadline (term.session.download): not the end of it.
            self.note(now, "warning", "link", f"{what} failed: {event.reason}; the download tries again")
        else:
            self.note(now, "error", "link", f"{what} failed: {event.reason}")

    def _on_lost(self, event: LinkLost, now: float) -> None:
        self.version += 1
        self.link_lost = True
        self._lost_to_ble = bool(self.radio_name and self.over_ble)  # the handover's silence, not a fault
        if self._lost_to_ble:
            self.note(now, "info", "link", f"cable silent for {event.silent_s:.1f} s: flying over BLE")
        elif self.primary_ble and not self.heard:
            self.note(now, "info", "link", "nothing over BLE yet: the board talks here after the handover "
                      "(key 8 on the cable terminal, in SAFE)")
        elif event.never_heard:
            self.note(now, "error", "link", f"LINK LOST: no answer from the board in {event.silent_s:.1f} s since the "
                      "link opened (is it on, and on this port?)")
        else:
            self.note(now, "error", "link", f"LINK LOST: nothing from the board for {event.silent_s:.1f} s")

    def _on_restored(self, event: LinkRestored, now: float) -> None:
        self.version += 1
        self.link_lost = False
        if self._lost_to_ble:  # handed back: the cable was quiet by design, nothing was lost
            self._lost_to_ble = False
            self.note(now, "info", "link", f"the board talks on the cable again (handed back after "
                      f"{event.lost_for_s:.1f} s over BLE)")
            return
        self.note(now, "info", "link", f"link restored after {event.lost_for_s:.1f} s")

    def _on_mismatch(self, event: VersionMismatch, now: float) -> None:
        self.version += 1
        self.version_mismatch = event
        self.note(now, "error", "link", f"board speaks protocol v{event.board_version}, terminal "
                  f"v{event.our_version}: update one of them")

    # --- the station's events -------------------------------------------------------------------------------

    def _on_from_link(self, event: FromLink, now: float) -> None:
        if event.link == RADIO:
            self.radio_event(event.event, now)
        else:
            self.apply(event.event, now)

    def _on_link_up(self, event: LinkUp, now: float) -> None:
        if event.link == RADIO:
            self.radio_up = True
            self.radio_note = ""
            self.note(now, "info", "ble", f"radio connected: {event.name} (key 8 in SAFE hands control over to it)")
        else:
            self.note(now, "info", "link", f"{'re' if event.again else ''}connected to {event.name}")

    def _on_link_down(self, event: LinkDown, now: float) -> None:
        if event.link != RADIO:
            self.link_lost = True
            self.note(now, "error", "link", f"LINK LOST: {event.message}")
            if self.primary_ble and self.flying:
                self.note(now, "error", "link", "the board PANICs: it was flying over this BLE link")
            return
        was_flying_ble = self.over_ble
        self.radio_up = False
        self.radio_lost = False
        self.note(now, "error", "ble", f"BLE LOST: {event.message}")
        if self.wireless != WirelessState.DISCONNECTED:
            # The board drops the handover with the connection (report Figure 12): control is the cable's.
            self.wireless = int(WirelessState.DISCONNECTED)
            self.note(now, "error", "ble", "control back on the cable: the board goes DISCONNECTED"
                      + (" and PANICs (it was flying over BLE)" if was_flying_ble and self.flying else ""))

    def _on_link_waiting(self, event: LinkWaiting, now: float) -> None:
        if event.link == RADIO:
            self.radio_note = f"down: {event.why or 'lost'}; next try in {event.pause:.0f} s"
            self.version += 1

    def _on_link_connecting(self, event: LinkConnecting, now: float) -> None:
        if event.link == RADIO:
            self.radio_note = "connecting…"
            self.version += 1

    def _on_link_failed(self, event: LinkFailed, now: float) -> None:
        if event.repeated:
            return
        if event.link == RADIO:
            self.note(now, "warning", "ble", f"radio not connected: {event.message}")
        else:
            self.note(now, "warning", "link", f"reconnecting: {event.message}")

    def _on_stats(self, event: StatsSample, now: float) -> None:
        if event.link == RADIO:
            self.set_radio_stats(event.stats, now)
        else:
            self.set_link_stats(event.stats, now)

    def _on_requested(self, event: Requested, now: float) -> None:
        self.pending += 1
        if event.op == Op.LOG_RESET:
            self._erasing = self.log_status.records if self.log_status is not None else None
        elif event.op == Op.SET_PARAM:  # a new try: an older refusal is not its answer
            spec = PARAMS.get(param_split(event.arg)[0])  # type: ignore[call-overload]
            if spec is not None:
                self.param_refused.pop(spec.name, None)
        if event.op == Op.MODE:
            self.note(now, "info", "term", f"request {mode_name(event.arg)}"
                      + (" over BLE" if event.link == RADIO else ""))
        else:
            self.version += 1

    def _on_not_sent(self, event: NotSent, now: float) -> None:
        self.note(now, "error", "term", f"not sent: {event.what}: {event.why}")

    def _on_note(self, event: Note, now: float) -> None:
        self.note(now, event.severity, event.source, event.text)

    def _on_stick(self, event: StickSet, now: float) -> None:
        self.set_stick(event.stick)

    def _on_joystick(self, event: JoystickNamed, now: float) -> None:
        self.joystick_name, self.joystick_mapping = event.name, event.mapping
        self.version += 1

    def _on_cleared(self, event: EventsCleared, now: float) -> None:
        self.events.clear()
        self.version += 1

    def apply_packet(self, pkt: Any, now: float) -> None:
        """One packet from the board, whatever link brought it: each kind has its applier (``_PACKETS``)."""
        kind = type(pkt)
        if kind in _TIMED:
            self.arrivals.note(pkt, now)
        applier = _PACKETS.get(kind)
        if applier is None:
            return  # heartbeats and acks change nothing on screen (the link panel shows their stats)
        applier(self, pkt, now)
        self.version += 1

    def _rule_reason(self, param: Param, raw: int, said: str) -> str:
        """The board's PARAM_RULE refusal with the rule named: the one the refused value breaks with the values the
        board last said (``said`` if none is found: the board knows values the terminal has not heard yet)."""
        values = {s.param: self.params[s.name] for s in PARAMS.values() if s.name in self.params}
        values[param] = PARAMS[param].from_raw(raw)
        for rule in broken_rules(values):
            if param in (rule.big, rule.small):
                return f"breaks the rule {rule.text()} ({rule.now_text(values)})"
        return said

    def _param(self, pid: int, raw: int) -> None:
        """A parameter's value as the board has it (a listing, a change, an Ack)."""
        self.param_raw[pid] = raw
        spec = PARAMS.get(pid)  # type: ignore[call-overload]
        if spec is not None:
            self.params[spec.name] = spec.from_raw(raw)
            self.param_refused.pop(spec.name, None)
        self.version += 1

    def _set_wireless(self, state: int) -> None:
        # STARTED is left only for DISCONNECTED (report Figure 12). A STARTING that arrives after STARTED was sent
        # on the cable before the board went silent there, and the cable is slower than BLE: stale, not news.
        if self.wireless == WirelessState.STARTED and state == WirelessState.STARTING:
            return
        self.wireless = state

    def _set_mode(self, mode: int, now: float) -> None:
        self.mode = mode

    def _push_scaled(self, t: float, pkt: Any, names: tuple[str, ...]) -> None:
        self._push(t, **{name: getattr(pkt, name) * spec_of(type(pkt), name).scale for name in names})

    def _push(self, t: float, **values: float) -> None:
        h = self.history
        for name, v in values.items():
            d = h.get(name)
            if d is None:
                d = h[name] = Series(HISTORY)
            d.append((t, v))

    def set_link_stats(self, stats: LinkStats, now: float) -> None:
        """Called every render tick: only a change of state counts as a model change (the link panel redraws on
        its own, its figures age with time). Damaged frames and lost frames go to the events list too, summed
        over at most a second, so no link error goes unseen and none floods the list."""
        prev = self.link
        self.link = stats
        if prev is not None and now - self._link_noted >= 1.0:
            bad = stats.frames_bad - self._bad_noted
            if bad > 0:
                self.note(now, "warning", "link", f"{bad} damaged frame{'s' if bad > 1 else ''} dropped (CRC or "
                          "framing): noise on the line or a wrong baud rate?")
                self._bad_noted = stats.frames_bad
                self._link_noted = now
            if stats.loss_pct is not None and stats.loss_pct >= 5.0 and now - self._loss_noted >= 5.0:
                self.note(now, "warning", "link", f"{stats.loss_pct:.0f} % of the board's frames lost "
                          "(last 2 s)")
                self._loss_noted = now
        if stats.lost != self.link_lost:
            self.link_lost = stats.lost
            self.version += 1
        if stats.rtt_last_ms is not None and (prev is None or prev.commands_sent != stats.commands_sent
                                              or prev.rtt_last_ms != stats.rtt_last_ms):
            self._push(now - self.start, rtt=stats.rtt_last_ms)

    def set_radio_stats(self, stats: LinkStats, now: float) -> None:
        """The radio's statistics, every render tick. Its silence counts only while the board flies over BLE
        (STARTED): before, the board sends nothing there (STARTING: only heartbeats, and the cable still works)."""
        self.radio = stats
        lost = stats.lost and self.wireless == WirelessState.STARTED
        if lost != self.radio_lost:
            self.radio_lost = lost
            self.version += 1

    def radio_event(self, event: Any, now: float) -> None:
        """One LinkEvent from the radio's session: packets are the board's, whatever link brought them; the
        radio's own loss and restoration are its own."""
        kind = type(event)
        if kind is LinkLost:
            if self.wireless == WirelessState.STARTED:
                self.radio_lost = True
                self.note(now, "error", "ble", f"BLE LINK LOST: nothing from the board over BLE for "
                          f"{event.silent_s:.1f} s")
            return
        if kind is LinkRestored:
            if self.radio_lost:
                self.note(now, "info", "ble", f"BLE link restored after {event.lost_for_s:.1f} s")
            self.radio_lost = False
            self.version += 1
            return
        if kind is CommandAcked and event.op == Op.WIRELESS and event.arg == 0:
            # The board acks the hand-back over BLE and goes DISCONNECTED at once, writing only to the cable from
            # then on: its Ack is its word. Waiting for the cable to say so (damaged frames) let BLE's silence
            # become a BLE LINK LOST on the link in control (issue 36's soak).
            self.wireless = int(WirelessState.DISCONNECTED)
            self.radio_lost = False
        self.apply(event, now)

    def set_stick(self, stick: Joystick) -> None:
        if stick != self.stick:
            self.stick = stick
            self.version += 1

    # --- derived views ------------------------------------------------------------------------------------

    def trim_steps(self) -> tuple[int | None, int | None]:
        """Stick units per press of the lift and of the roll/pitch/yaw trim keys, as the board's parameters say
        (None until they are known)."""
        lift, trim = self.params.get("trim.lift_step"), self.params.get("trim.step")
        return (None if lift is None else int(lift)), (None if trim is None else int(trim))

    def reading(self, name: str, now: float) -> Reading:
        """A displayed figure with its age, staleness and bound (term.core.freshness)."""
        return read(self, name, now)

    @property
    def flags(self) -> Flag:
        return Flag(self.flag_bits)

    @property
    def flying(self) -> bool:
        return self.mode in FLIGHT_MODES

    @property
    def handed_over(self) -> bool:
        """The board was handing over to BLE: its silence on this link may be the handover, not a fault."""
        return self.wireless in (WirelessState.STARTING, WirelessState.STARTED)

    @property
    def over_ble(self) -> bool:
        """BLE carries control: the only link is BLE, or the radio is up and the board said STARTED."""
        return self.primary_ble or (self.radio_up and self.wireless == WirelessState.STARTED)

    @property
    def control_lost(self) -> bool:
        """The link that carries control is silent: the alarm. The cable's silence while flying over BLE is
        expected (the board writes only to BLE then), not an alarm."""
        if self.radio_name and self.over_ble:
            return self.radio_lost
        if self.primary_ble and not self.heard:
            return False  # over BLE alone, silence until the handover is the rule, not a fault
        return self.link_lost

    @property
    def battery_v(self) -> float | None:
        if self.over_ble and self.compact is not None:
            return scaled(self.compact, "battery")
        if self.height is not None:
            return scaled(self.height, "battery")
        return scaled(self.compact, "battery") if self.compact is not None else None

    @property
    def log_state(self) -> LogState | None:
        if self.log_status is None:
            return None
        try:
            return LogState(self.log_status.state)
        except ValueError:
            return None

    def series(self, name: str, window: float, now: float) -> tuple[list[float], list[float]]:
        """(t, values) of one plotted series over the last ``window`` seconds, t relative to now (<= 0)."""
        d = self.history.get(name)
        if not d:
            return [], []
        t_now = now - self.start
        lo = t_now - window
        xs, ys = [], []
        for t, v in d:
            if t >= lo:
                xs.append(t - t_now)
                ys.append(v)
        return xs, ys


def _log_started(m: Model, used: int) -> str:
    return f"log recording started ({used / 1000:.1f} kB of flash used)"


def _log_stopped(m: Model, used: int) -> str:
    return f"log recording stopped ({used / 1000:.1f} kB of flash used; F5 downloads it)"


def _log_erased(m: Model, value: int) -> str:
    n, m._erasing = m._erasing, None
    return "log erased" + (f": {n} records gone" if n is not None else "")


# The log keys say what they did, when the board has done it.
_LOG_ACKS: dict[int, Callable[[Model, int], str]] = {Op.LOG_START: _log_started, Op.LOG_STOP: _log_stopped,
                                                     Op.LOG_RESET: _log_erased}

_TIMED = frozenset((Attitude, Motion, Height, Status, Gains, Compact, Compact2))  # figures that can go stale


# --- the packet appliers: one per kind of packet (Model.apply_packet counts the change) ----------------------


def _on_attitude(m: Model, pkt: Attitude, now: float) -> None:
    m.attitude = pkt
    m._set_mode(pkt.mode, now)
    m._push_scaled(now - m.start, pkt, ("phi", "theta", "psi", "sp", "sq", "sr"))


def _on_motion(m: Model, pkt: Motion, now: float) -> None:
    m.motion = pkt
    m._push(now - m.start, ae1=pkt.ae1, ae2=pkt.ae2, ae3=pkt.ae3, ae4=pkt.ae4)


def _on_height(m: Model, pkt: Height, now: float) -> None:
    m.height = pkt
    m._push_scaled(now - m.start, pkt, ("height", "setpoint", "vz", "pressure", "battery"))


def _on_status(m: Model, pkt: Status, now: float) -> None:
    m.status = pkt
    m.flag_bits = pkt.flags
    m._set_wireless(pkt.wireless)


def _on_gains(m: Model, pkt: Gains, now: float) -> None:
    m.gains = pkt


def _on_compact(m: Model, pkt: Compact, now: float) -> None:
    m.compact = pkt
    m._set_mode(pkt.mode, now)
    m._set_wireless(pkt.wireless)
    m._push_scaled(now - m.start, pkt, ("phi", "theta", "psi", "battery"))


def _on_compact2(m: Model, pkt: Compact2, now: float) -> None:
    m.compact2 = pkt
    m.flag_bits = pkt.flags
    m._push_scaled(now - m.start, pkt, ("ae1", "ae2", "ae3", "ae4", "height", "setpoint", "vz"))


def _on_event(m: Model, pkt: Event, now: float) -> None:
    m.board_ms = pkt.board_ms
    m.event_times[pkt.code] = now
    m.event_args[pkt.code] = pkt.arg
    severity, text = event_text(pkt.code, pkt.arg, m.flying, m.mode)  # the mode it was sent in
    if pkt.code == EventCode.PARAM_CHANGED:
        m._param(*param_split(pkt.arg))
    if pkt.code == EventCode.DEADLINE_MISS:
        deadline_miss(m, now, pkt.arg)
    elif pkt.code != EventCode.REFUSED or m._refusal(pkt.arg & 0xFF, pkt.arg >> 8, text, now):
        m.note(now, severity, "board", f"[{scaled(pkt, 'board_ms'):.3f}] {text}")
    if pkt.code == EventCode.MODE_CHANGED:
        m._set_mode(pkt.arg & 0xFF, now)
    elif pkt.code == EventCode.WIRELESS_STATE:
        m._set_wireless(pkt.arg)


def _on_profile(m: Model, pkt: Profile, now: float) -> None:
    m.profiles[pkt.task] = pkt


def _on_hello(m: Model, pkt: Hello, now: float) -> None:
    m.hello = pkt


def _on_param_value(m: Model, pkt: ParamValue, now: float) -> None:
    m._param(pkt.param, pkt.value)


def _on_log_packet(m: Model, pkt: LogStatus | LogChunk, now: float) -> None:
    if type(pkt) is LogStatus:
        m.log_status = pkt
    if m.download is not None:
        m.download.feed(pkt, now)


def _on_console(m: Model, line: ConsoleLine, now: float) -> None:
    """A line of the board's text (term.core.console): in the console; an error's in the events list too."""
    m.console.append((now - m.start, line))
    if line.level >= LEVEL_ERROR:
        m.note(now, "error", "board", f"console: {line.text}")
    m.version += 1


def _on_console_dropped(m: Model, ev: ConsoleDropped, now: float) -> None:
    """Lines the link's rate limit dropped: counted as they go (the line after them may be long in coming)."""
    m.console_dropped += ev.count
    m.version += 1


_PACKETS: dict[type, Callable[[Model, Any, float], None]] = {
    Attitude: _on_attitude,
    Motion: _on_motion,
    Height: _on_height,
    Status: _on_status,
    Gains: _on_gains,
    Compact: _on_compact,
    Compact2: _on_compact2,
    Event: _on_event,
    Profile: _on_profile,
    Hello: _on_hello,
    ParamValue: _on_param_value,
    LogStatus: _on_log_packet,
    LogChunk: _on_log_packet,
}

_HANDLERS: dict[type, Callable[[Model, Any, float], None]] = {
    PacketReceived: Model._on_packet,
    CommandAcked: Model._on_acked,
    CommandFailed: Model._on_failed,
    LinkLost: Model._on_lost,
    LinkRestored: Model._on_restored,
    VersionMismatch: Model._on_mismatch,
    FromLink: Model._on_from_link,
    LinkUp: Model._on_link_up,
    LinkDown: Model._on_link_down,
    LinkWaiting: Model._on_link_waiting,
    LinkConnecting: Model._on_link_connecting,
    LinkFailed: Model._on_link_failed,
    StatsSample: Model._on_stats,
    Requested: Model._on_requested,
    NotSent: Model._on_not_sent,
    Note: Model._on_note,
    StickSet: Model._on_stick,
    JoystickNamed: Model._on_joystick,
    EventsCleared: Model._on_cleared,
    ConsoleLine: _on_console,
    ConsoleDropped: _on_console_dropped,
}
