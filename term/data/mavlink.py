"""`term --mavlink [udp:|tcp:]HOST:PORT`: the flight sent to a MAVLink ground station (QGroundControl, MAVProxy, a
pymavlink script) and its messages taken on the same socket (pymavlink, the ``mavlink`` extra). What maps to what:
docs/mavlink.md and term/data/mavlink_map.py.

Contract:

- ``MavlinkEndpoint(address, t0=, public=)`` opens the socket (term/data/mavlink_socket.py: UDP to HOST:PORT,
  reading only that peer, or TCP to a ground station listening there; loopback unless ``public``; QGroundControl
  listens on 14550). ``MavlinkError`` (one line) if the address is bad or the extra missing. ``start()`` starts
  the socket's thread (``term mavlink``), ``attach`` joins the display's side, ``close()`` ends it all.
- Out, on the link's thread (``link_packet``: the station's ``on_packet``, as the Foxglove server is fed): each
  board packet becomes its messages at once (ATTITUDE with every Attitude; height, pressure, motors at capped
  rates), written to the socket without a hop through another thread (its writes never block). The socket's
  thread sends HEARTBEAT, SYS_STATUS and BATTERY_STATUS once a second and reads the ground station's messages.
  Nothing here can stall the link: a slow or absent ground station costs messages (``dropped``), never the flight.
- In: parameter reads are answered on the endpoint's thread from the board's values as heard (``ParamValue``,
  ``PARAM_CHANGED``, the Acks). Everything that acts (PARAM_SET, COMMAND_LONG, SET_MODE, MANUAL_CONTROL, the log
  requests) is carried to the display's loop (``attach``'s ``post``) and goes through ``Station.send`` /
  ``Station.set_stick``: the station's guards and then the board's, as term's keys do. The answers (PARAM_VALUE,
  COMMAND_ACK with the board's Nak in ``result_param2`` and its text as STATUSTEXT) follow the board's Ack
  (``station_event``). Parameter sets need no handover; arming and modes other than SAFE and PANIC do.
- The handover (docs/mavlink.md, as the BLE one, docs/wireless.md): the pilot offers control from term
  (``handover``: in SAFE, with a ground station heard); the ground station's first MANUAL_CONTROL takes it; until
  then MANUAL_CONTROL moves nothing. While it flies, its silence (no MANUAL_CONTROL for ``MANUAL_TIMEOUT_S``)
  stops term's writes to the board (the links' gate), so the board sees a link loss and runs its own two-stage
  failsafe: hold level, then PANIC; MANUAL_CONTROL back in time gives control back, PANIC ends the handover. A
  pilot's own command in term (``pilot_command``) or ``handback`` takes control back at once.
- The log protocol: LOG_REQUEST_LIST asks the board's LogStatus and lists its flash log as log 1; LOG_REQUEST_DATA
  downloads it as F5 does (``start_download``: the app's download, its retries, its CSV) and serves the bytes
  in 90-byte LOG_DATA from the download once it is complete and matches the board's CRC-32.
- ``tick(now)`` (the render tick) gates new connections and serves a finished download. A flood from the ground
  station costs its own messages: at most ``DISPLAY_QUEUE_MAX`` of its requests wait on the display, MANUAL_CONTROL
  is latest-wins (one call waiting with the newest stick).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from term.core.events import FromLink, NotSent, StatsSample
from term.core.link import CommandAcked, CommandFailed, PacketReceived
from term.core.protocol import (
    FLIGHT_MODES,
    Event,
    EventCode,
    Joystick,
    LogStatus,
    Mode,
    Nak,
    Op,
    ParamValue,
    param_split,
)
from term.data.mavlink_log import LogService
from term.data.mavlink_map import (
    MavlinkMissing,
    Telemetry,
    codec,
    pack,
)
from term.data.mavlink_params import ParamService
from term.data.mavlink_socket import GroundSocket, MavlinkError, parse_address
from term.session.texts import mode_name

log = logging.getLogger("term.mavlink")
DEFAULT_ADDRESS = "udp:127.0.0.1:14550"  # QGroundControl's and MAVProxy's listening port
PERIOD_S = 1.0  # HEARTBEAT, SYS_STATUS, BATTERY_STATUS
HEARD_S = 3.0  # a ground station heard within this is there (MAVLink's GCS heartbeat is 1 Hz)
MANUAL_TIMEOUT_S = 0.5  # handed over and flying: no MANUAL_CONTROL this long is the ground station's link loss
PARAM_LIST_WAIT_S = 3.0  # a list asked of the board: sent as far as it came after this
STICK_FULL = 32767
FTP_NAK, FTP_UNKNOWN = 129, 7  # MAVLink FTP: opcode Nack, error UnknownCommand
DISPLAY_QUEUE_MAX = 64  # the ground station's requests waiting on the display's loop at once

TERM, OFFERED, GCS = "term", "offered", "ground station"  # who flies (the handover's states)


class MavlinkEndpoint:
    """One ground station's link (module docstring)."""

    thread_safe = True  # its link_packet never blocks: the link's thread calls it as packets are decoded

    def __init__(self, address: str = DEFAULT_ADDRESS, *, t0: float | None = None, public: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        kind, host, port = parse_address(address, public)
        try:
            self._mav = codec()
            self._rx = codec()
        except MavlinkMissing as exc:
            raise MavlinkError(str(exc)) from None
        self.clock = clock
        self.t0 = clock() if t0 is None else t0
        self._lock = threading.Lock()  # the codec's sequence and the telemetry's state, from any thread
        self._tele = Telemetry(self._mav)
        self.socket = GroundSocket(kind, host, port, clock)
        self._closed = False
        self._next_periodic = clock()
        # what the ground station did, and the board's parameters as heard (link thread and this one: dict ops)
        self.gcs: tuple[int, int] | None = None  # its (system, component)
        self.heard_at: float | None = None
        self.manual_at: float | None = None  # its last MANUAL_CONTROL
        self.params: dict[int, int] = {}  # Param -> raw
        self._list_asked: float | None = None  # a PARAM_REQUEST_LIST waits for the board's list since then
        # the display's side (attach)
        self.station: Any = None
        self._post: Callable[..., None] | None = None
        self.logs = LogService(self, None)  # the log protocol (term/data/mavlink_log.py)
        self.param_service = ParamService(self)  # the parameter protocol (term/data/mavlink_params.py)
        self.state = TERM
        self._pending: dict[int, tuple[str, Any]] = {}  # cmd_id -> (what, detail): the answer the Ack brings
        self._notsent: NotSent | None = None
        self._sending = False
        self._refused_manual_at = -1e9
        self._gated = False  # the ground station's silence held term's writes back in this handover
        self._handing_back = False  # the hand-back for its silence waits on the display
        self._queued = 0  # calls waiting on the display's loop
        self._stick: Joystick | None = None  # the ground station's latest MANUAL_CONTROL, as a stick
        self._stick_posted = False
        self.dropped_in = 0  # ground station's messages dropped: too many waiting on the display
        # figures
        self.sent: dict[str, int] = {}
        self.received: dict[str, int] = {}
        self.dropped = 0
        self.errors = 0

    @property
    def url(self) -> str:
        return self.socket.url

    @property
    def mav(self) -> Any:
        """The codec that builds the messages (``*_encode``)."""
        return self._mav

    def send(self, msgs: list[Any]) -> None:
        """Messages to the ground station, from any thread (never blocks)."""
        if not msgs or self._closed:
            return
        with self._lock:
            for msg in msgs:
                try:
                    ok = self.socket.write(pack(self._mav, msg))
                except Exception:  # a bad message costs itself
                    self.errors += 1
                    continue
                name = msg.get_type()
                if ok:
                    self.sent[name] = self.sent.get(name, 0) + 1
                else:
                    self.dropped += 1

    def text(self, severity: str, text: str) -> None:
        """A line of term's own to the ground station as STATUSTEXT (``severity``: "error", "warning", "info")."""
        d = self._tele.m
        sev = {"error": d.MAV_SEVERITY_ERROR, "warning": d.MAV_SEVERITY_WARNING}.get(severity, d.MAV_SEVERITY_INFO)
        with self._lock:
            msgs = self._tele.text(sev, text)
        self.send(msgs)

    # --- life cycle -------------------------------------------------------------------------------------------

    def start(self) -> None:
        self.socket.start(self._on_data, self._on_tick)

    def attach(self, station: Any, post: Callable[..., None], start_download: Callable[[], None] | None = None) -> None:
        """The display's side: the station (its guards, its model), ``post(fn, *args)`` running ``fn`` on the
        display's loop, and the app's log download (F5's)."""
        self.station = station
        self._post = post
        self.logs.start_download = start_download
        for link in station.links:
            self._gate(link)

    def close(self) -> None:
        self._closed = True
        self.socket.close()

    def _on_data(self, data: bytes) -> None:
        """Bytes from the ground station (the socket's thread): its messages, each handled alone. A datagram holds
        whole messages: what a damaged one left half-parsed is thrown away, never glued to the next datagram's."""
        if self.socket.kind == "udp" and len(self._rx.buf) > self._rx.buf_index:
            self._rx = codec()
        try:
            msgs = self._rx.parse_buffer(data) or []
        except Exception:  # garbage costs the buffer it came in
            self.errors += 1
            return
        for msg in msgs:
            try:
                self._on_message(msg)
            except Exception:  # one bad message costs itself, never the endpoint
                self.errors += 1
                log.exception("MAVLink: a %s from the ground station failed", msg.get_type())

    def _on_tick(self, now: float) -> None:
        if now >= self._next_periodic:
            self._next_periodic = max(self._next_periodic + PERIOD_S, now)
            self._periodic(now)
        self._timers(now)

    def _periodic(self, now: float) -> None:
        with self._lock:
            msgs = self._tele.periodic()
        self.send(msgs)

    def _timers(self, now: float) -> None:
        asked = self._list_asked
        if asked is not None and (self.param_service.complete() or now - asked > PARAM_LIST_WAIT_S):
            self._list_asked = None
            self.param_service.send_list()
        if self.state == GCS and self._post is not None and self.station is not None:
            mode = self.station.model.mode
            # In flight its silence is the board's failsafe's to handle (the gate); once that has landed it, or
            # when it is silent on the ground for HEARD_S, the handover is over (as a lost BLE phone's).
            gone = self._gated or self.heard_at is None or now - self.heard_at > HEARD_S
            if gone and mode is not None and mode not in FLIGHT_MODES and not self._handing_back:
                self._handing_back = True  # (before the post: the display may run it, and clear this, at once)
                self._handing_back = self._to_display(
                    self.handback, f"the ground station went silent ({mode_name(mode)}): control is term's pilot's "
                    "again; hand it over again from term") and self.state != TERM

    # --- out: the board's packets, on the link's thread -------------------------------------------------------

    def link_packet(self, link: str, pkt: Any) -> None:
        if self._closed:
            return
        kind = type(pkt)
        if kind is ParamValue:
            self.params[pkt.param] = pkt.value
            return
        if kind is Event and pkt.code == EventCode.PARAM_CHANGED:
            pid, raw = param_split(pkt.arg)
            self.param_service.changed(pid, raw)
        t = self.clock() - self.t0
        try:
            with self._lock:
                msgs = self._tele.packet(pkt, t)
        except Exception:  # one bad packet costs itself, never the link
            self.errors += 1
            return
        self.send(msgs)

    # --- in: the ground station's messages, on the endpoint's thread -----------------------------------------

    def _on_message(self, msg: Any) -> None:
        name = msg.get_type()
        if name == "BAD_DATA":
            return
        self.received[name] = self.received.get(name, 0) + 1
        now = self.clock()
        new = self.heard_at is None or now - self.heard_at > HEARD_S
        self.heard_at = now
        self.gcs = (msg.get_srcSystem(), msg.get_srcComponent())
        if new:  # a ground station names a quadrotor's custom modes from its own table (ArduCopter's): ours
            self.text("info", "Quadrupel: custom mode = the board's mode: " + ", ".join(
                f"{m.value} {m.name}" for m in Mode if m != Mode.WIRELESS) + f"; now {mode_name(self._tele.mode)}")
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self._mav.srcSystem):
            return  # for another vehicle
        if name == "PARAM_REQUEST_LIST":
            self._list_asked = now
            if not self.param_service.complete():
                self._to_display(self._ask_params)
        elif name == "PARAM_REQUEST_READ":
            self.param_service.read(msg)
        elif name == "PARAM_SET":
            self.param_service.set(msg)
        elif name == "MANUAL_CONTROL":
            self._manual(msg, now)
        elif name == "FILE_TRANSFER_PROTOCOL":
            self._ftp_nak(msg)
        elif name in ("COMMAND_LONG", "SET_MODE"):
            self._to_display(getattr(self, "_on_" + name.lower()), msg)
        elif name in ("LOG_REQUEST_LIST", "LOG_REQUEST_DATA", "LOG_REQUEST_END"):
            self._to_display(getattr(self.logs, name[4:].lower()), msg)

    def _to_display(self, fn: Callable[..., None], *args: Any) -> bool:
        """``fn(*args)`` on the display's loop; beyond DISPLAY_QUEUE_MAX waiting there, dropped (a flood from the
        ground station costs its own messages, never the screen)."""
        if self._post is None:
            return False
        with self._lock:
            if self._queued >= DISPLAY_QUEUE_MAX:
                self.dropped_in += 1
                return False
            self._queued += 1
        self._post(self._run_posted, fn, args)
        return True

    def _run_posted(self, fn: Callable[..., None], args: tuple[Any, ...]) -> None:
        with self._lock:
            self._queued -= 1
        try:
            fn(*args)
        except Exception:  # a hostile message's values (nan where an int goes) cost that message
            self.errors += 1
            log.exception("MAVLink: handling a ground station's message failed")

    def _ftp_nak(self, msg: Any) -> None:
        """No file server here: every MAVLink FTP request is answered NAK UnknownCommand at once, so a ground
        station that tries FTP first (MAVProxy's parameter fetch) falls back to the parameter protocol at once."""
        p = bytes(msg.payload)
        if len(p) < 12:
            return
        seq = (int.from_bytes(p[0:2], "little") + 1) & 0xFFFF
        reply = seq.to_bytes(2, "little") + bytes([p[2], FTP_NAK, 1, p[3], 0, 0]) + bytes(4) + bytes([FTP_UNKNOWN])
        self.send([self._mav.file_transfer_protocol_encode(0, *(self.gcs or (0, 0)), reply.ljust(251, b"\0"))])

    # the sticks

    def _manual(self, msg: Any, now: float) -> None:
        if self.state == TERM:
            if now - self._refused_manual_at > 1.0:  # said once a second, not for every message
                self._refused_manual_at = now
                self.text("warning", "MANUAL_CONTROL ignored: term's pilot has not handed control to this ground "
                          "station")
            return
        self.manual_at = now
        self._stick = Joystick(_axis(msg.y), _axis(-msg.x), _axis(msg.r), _axis(max(0, msg.z)), 0)
        if not self._stick_posted:  # latest wins: one call waits on the display at a time, with the newest stick
            self._stick_posted = True  # (before the post: the display may run it, and clear this, at once)
            if not self._to_display(self._fly):
                self._stick_posted = False

    # --- on the display's loop --------------------------------------------------------------------------------

    def _fly(self) -> None:
        self._stick_posted = False
        js = self._stick
        if self.state == TERM or self.station is None or js is None:
            return
        if self.state == OFFERED:
            self.state = GCS
            self.station.note("warning", "mavlink", f"the ground station at {self.url} flies now (its MANUAL_CONTROL); "
                              "any command of yours takes control back")
        self.station.set_stick(js)

    def _ask_params(self) -> None:
        self.send_command(Op.PARAM_LIST, 0, ("list", 0))

    def send_command(self, op: Op, arg: int, what: tuple[str, Any]) -> int | None:
        """``Station.send`` (its guards, then the board's), the answer kept for the Ack; a refusal answered now."""
        st = self.station
        if st is None:
            return None
        self._sending, self._notsent = True, None
        try:
            cmd = st.send(op, arg)
        finally:
            self._sending = False
        if cmd is None:
            self._answer(what, False, self._notsent.why if self._notsent else "not sent", None, None)
        else:
            if what[0] == "list":
                st.model.own.add(cmd)  # (term's own request: its failure is no error)
            self._pending[cmd] = what
        return cmd

    def station_event(self, ev: Any) -> None:
        """Every station event, on the display's loop: the Acks of our commands, refusals, the link statistics."""
        kind = type(ev)
        if kind is NotSent and self._sending:
            self._notsent = ev
        elif kind is StatsSample and ev.link == "cable":
            with self._lock:
                self._tele.stats(ev.stats.loss_pct, ev.stats.frames_bad)
        elif kind is FromLink:
            e = ev.event
            if type(e) is PacketReceived:
                if type(e.packet) is LogStatus:  # (the list's answer: it follows the Ack of LOG_STATUS)
                    self.logs.log_status(e.packet)
            elif type(e) is CommandAcked or type(e) is CommandFailed:
                what = self._pending.pop(e.cmd_id, None)
                if what is not None:
                    ok = type(e) is CommandAcked
                    self._answer(what, ok, "" if ok else e.reason, e.value if ok else None,
                                 None if ok else e.nak)

    def _answer(self, what: tuple[str, Any], ok: bool, why: str, value: int | None, nak: Nak | None) -> None:
        kind, detail = what
        if kind == "param":
            if ok and value is not None:
                self.params[detail] = value
                self.send([self.param_service.value(detail)])
            elif not ok:
                self.param_service.refused(detail, why)
        elif kind == "command":
            command, label = detail
            d = self._tele.m
            if not ok:
                self.text("error", f"{label} refused: {why}")
            result = d.MAV_RESULT_ACCEPTED if ok else (
                d.MAV_RESULT_TEMPORARILY_REJECTED if nak is not None else d.MAV_RESULT_DENIED)
            self.send([self._mav.command_ack_encode(command, result, 0, int(nak) if nak is not None else 0,
                                                    *(self.gcs or (0, 0)))])
        elif kind == "log":
            self.logs.status_answered(ok, why)

    # commands

    def _on_command_long(self, msg: Any) -> None:
        d = self._tele.m
        c = msg.command
        if c == d.MAV_CMD_COMPONENT_ARM_DISARM:
            arm = msg.param1 > 0.5
            self._command(c, Op.MODE, Mode.MANUAL if arm else Mode.SAFE, "arm (MANUAL)" if arm else "disarm (SAFE)")
        elif c == d.MAV_CMD_DO_SET_MODE:
            self._set_mode(c, int(msg.param2))
        elif c in (d.MAV_CMD_NAV_LAND, d.MAV_CMD_DO_FLIGHTTERMINATION):
            self._command(c, Op.MODE, Mode.PANIC, "PANIC")
        elif c in (d.MAV_CMD_REQUEST_MESSAGE, d.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
            self._autopilot_version(msg)
        else:
            self.send([self._mav.command_ack_encode(c, d.MAV_RESULT_UNSUPPORTED, 0, 0, *(self.gcs or (0, 0)))])

    def _on_set_mode(self, msg: Any) -> None:
        self._set_mode(self._tele.m.MAV_CMD_DO_SET_MODE, int(msg.custom_mode))

    def _set_mode(self, command: int, mode: int) -> None:
        try:
            m = Mode(mode)
        except ValueError:
            self.text("error", f"mode {mode}: the board's modes are 0..8 (docs/mavlink.md)")
            self.send([self._mav.command_ack_encode(command, self._tele.m.MAV_RESULT_DENIED, 0, 0,
                                                    *(self.gcs or (0, 0)))])
            return
        self._command(command, Op.MODE, m, f"mode {m.name}")

    def _command(self, command: int, op: Op, arg: int, label: str) -> None:
        """A flight command: SAFE and PANIC always (stopping is never refused here); the rest only when handed over."""
        d = self._tele.m
        if op == Op.MODE and arg not in (Mode.SAFE, Mode.PANIC) and self.state == TERM:
            why = "term's pilot has not handed control to the ground station (palette: MAVLink: hand control)"
            self.text("error", f"{label} refused: {why}")
            self.send([self._mav.command_ack_encode(command, d.MAV_RESULT_DENIED, 0, 0, *(self.gcs or (0, 0)))])
            return
        self.send_command(op, arg, ("command", (command, label)))

    def _autopilot_version(self, msg: Any) -> None:
        d = self._tele.m
        c = msg.command
        wanted = int(msg.param1) if c == d.MAV_CMD_REQUEST_MESSAGE else d.MAVLINK_MSG_ID_AUTOPILOT_VERSION
        if wanted != d.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self.send([self._mav.command_ack_encode(c, d.MAV_RESULT_UNSUPPORTED, 0, 0, *(self.gcs or (0, 0)))])
            return
        caps = d.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | d.MAV_PROTOCOL_CAPABILITY_MAVLINK2
        self.send([self._mav.command_ack_encode(c, d.MAV_RESULT_ACCEPTED, 0, 0, *(self.gcs or (0, 0))),
                   self._mav.autopilot_version_encode(caps, 0, 0, 0, 0, bytes(8), bytes(8), bytes(8), 0, 0, 0)])

    # the handover

    def handover(self) -> str | None:
        """The pilot offers control to the ground station; the reason it cannot be, or None."""
        st = self.station
        if st is None:
            return "not attached"
        if self.state != TERM:
            return f"already handed over ({self.state})"
        if st.model.mode not in (Mode.SAFE, None):
            return "only in SAFE, as the BLE handover"
        heard = self.heard_at
        if heard is None or self.clock() - heard > HEARD_S:
            return f"no ground station heard at {self.url}: start it (QGroundControl, mavproxy.py) first"
        self.state = OFFERED
        self.manual_at = None
        self._gated = self._handing_back = False
        st.note("info", "mavlink", f"control offered to the ground station at {self.url}: its MANUAL_CONTROL takes it")
        self.text("warning", "term's pilot handed control to this ground station: MANUAL_CONTROL flies")
        return None

    def handback(self, why: str = "term's pilot took control back") -> None:
        self._handing_back = False
        if self.state == TERM:
            return
        self.state = TERM
        self._gated = False
        if self.station is not None:
            self.station.note("warning", "mavlink", why)
        self.text("warning", why)

    def pilot_command(self) -> None:
        """A pilot's own command in term: control is term's again (before the command goes)."""
        if self.state != TERM:
            self.handback()

    def _silent(self, now: float) -> bool:
        """Handed over, flying, and no MANUAL_CONTROL for MANUAL_TIMEOUT_S: the ground station's link is lost."""
        if self.state != GCS:
            return False
        at = self.manual_at
        return at is None or now - at > MANUAL_TIMEOUT_S

    def _gate(self, link: Any) -> None:
        """Wrap ``link``'s connection gate (and each new one's: checked at every tick): while the ground station
        that flies is silent, nothing goes to the board, whose failsafe then acts as for any lost link."""
        conn = link.connection
        if conn is None or getattr(conn.gate, "mavlink", False):
            return
        inner = conn.gate

        def gate() -> bool:
            if self._silent(self.clock()) and self.station is not None and self.station.model.flying:
                self._gated = True
                return False
            return inner is None or inner()

        gate.mavlink = True  # type: ignore[attr-defined]
        conn.gate = gate

    def tick(self, now: float) -> None:
        """The render tick (the display's loop): new connections gated, a finished log download served."""
        st = self.station
        if st is None:
            return
        for link in st.links:
            self._gate(link)
        self.logs.tick()


def _axis(v: float) -> int:
    """MANUAL_CONTROL's -1000..1000 as the stick's -32767..32767."""
    return max(-STICK_FULL, min(STICK_FULL, round(float(v) * STICK_FULL / 1000)))
