"""What a lesson (and the autopilot) can see: the variables of lesson expressions, from the truth, the screen and
what happened.

``Observer`` is sans-IO. The front end hands it every station event (``event(ev, model, now)``: the same events
the model applies, term/core/events.py) and every truth sample (``truth(sample)``); ``namespace(model, now)`` gives
the variables below as a dict, the one thing lesson expressions read. ``reset(now)`` starts an attempt: counters
and touch-downs count from then. A figure that is not known yet (no truth sample, no battery reading) is None, which
every comparison reads as false.

``NAMES`` lists every variable with its meaning (the user guide's table is generated from it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from term.core.events import RADIO, FromLink, LinkDown, NotSent, Requested, StationEvent
from term.core.link import CommandFailed, PacketReceived
from term.core.protocol import ROOM_CEILING_M, ROOM_HALF_M, Event, EventCode, Flag, Mode, Op, WirelessState
from term.lessons.instructor import Truth
from term.session.model import Model
from term.session.texts import battery_level, mode_name

NAMES: dict[str, str] = {
    # the truth (only the simulator knows it)
    "h": "height above the floor (m)",
    "n": "north of the pad (m)",
    "e": "east of the pad (m)",
    "vz": "vertical speed, up positive (m/s)",
    "speed": "horizontal speed (m/s)",
    "tilt": "tilt from level (°)",
    "heading": "heading, 0 to 360°, 0 north, 90 east",
    "yaw_rate": "yaw rate, positive turning right (°/s)",
    "on_ground": "resting on its feet",
    "touchdown": "downward speed of the last touch-down (m/s)",
    "landings": "touch-downs in this attempt",
    "crashes": "crashes in this attempt (too fast or too tilted)",
    "crash_where": "what the last crash hit: \"the floor\", \"a wall\" or \"the ceiling\" (\"\" before one)",
    "crash_speed": "how fast the craft went into it (m/s, the truth just before; 0 before one)",
    "soc": "the pack's state of charge, 0 to 1",
    "cable_ok": "the cable carries bytes (the instructor may cut it)",
    "in_box": "inside the lesson's box",
    "box_out": "how far outside the lesson's box (m; 0 inside)",
    # the screen (the board's telemetry, as the model has it)
    "mode": "the board's mode by name: \"SAFE\", \"PANIC\", \"MANUAL\", \"CALIBRATION\", \"YAW\", \"FULL\", \"RAW\", "
            "\"HEIGHT\"",
    "flying": "the board is in a flight mode",
    "over_ble": "BLE carries control (after the handover)",
    "wireless": "the handover's state: \"DISCONNECTED\", \"STARTING\", \"STARTED\"",
    "battery": "the battery as shown (V)",
    "battery_level": "\"ok\", \"warn\" (time to land) or \"panic\" (the board's PANIC level)",
    "warn_time": "seconds since the battery shown went under the land level (0 while it is not)",
    "link_lost": "the link that carries control is silent",
    "link_loss": "frames lost on the link that carries control over the last 2 s (%), as the link panel shows",
    "calibrated": "the board says it is calibrated",
    "lift": "the lift stick, 0 to 32767",
    "log_saved": "a log download was saved",
    # what happened in this attempt
    "refusals": "commands refused (by the terminal or the board)",
    "calibrations": "calibrations done",
    "panics": "PANICs the pilot asked for",
    "board_panics": "PANICs the board took by itself (link, battery, tilt)",
    "link_timeouts": "link timeouts the board saw",
    "low_battery": "low-battery PANICs",
    "tilt_panics": "tilt-limit PANICs",
    "handovers": "handovers to BLE done (STARTED)",
    "radio_losses": "BLE connections lost",
    "commands": "commands sent",
    # time
    "time": "seconds since the attempt started",
    "step_time": "seconds in this step",
    "held": "seconds the step's goal has held without a break",
    "mode_time": "seconds in the current mode",
    "step_turn": "degrees turned (either way) in this step",
    "step_landings": "touch-downs in this step",
}

COUNTERS = ("refusals", "calibrations", "panics", "board_panics", "link_timeouts", "low_battery", "tilt_panics",
            "handovers", "radio_losses", "commands")
STEP_NAMES = ("step_time", "held", "step_turn", "step_landings")


@dataclass(frozen=True, slots=True)
class Box:
    """The lesson's box: centre (north, east, height) and its full extents (m)."""

    north: float = 0.0
    east: float = 0.0
    height: float = 1.0
    size: float = 1.0  # north and east extent
    tall: float = 1.0  # height extent

    def distance(self, n: float, e: float, h: float) -> float:
        """0 inside, else how far outside (m)."""
        dn = max(0.0, abs(n - self.north) - self.size / 2)
        de = max(0.0, abs(e - self.east) - self.size / 2)
        dh = max(0.0, abs(h - self.height) - self.tall / 2)
        return math.sqrt(dn * dn + de * de + dh * dh)

    @property
    def low(self) -> float:
        return self.height - self.tall / 2

    @property
    def high(self) -> float:
        return self.height + self.tall / 2


class Observer:
    """Counts what happens and builds the lesson variables (module docstring)."""

    def __init__(self, box: Box | None = None) -> None:
        self.box = box
        self.sample: Truth | None = None
        self.counts: dict[str, int] = dict.fromkeys(COUNTERS, 0)
        self.started = 0.0
        self._landings0: int | None = None
        self._crashes0: int | None = None
        self._warn_since: float | None = None
        self._ok_since: float | None = None
        self._mode: int | None = None
        self._mode_since = 0.0
        self.log: list[tuple[float, str]] = []  # (time, what) of the counted happenings, for the summary
        self.crash_where, self.crash_speed = "", 0.0

    def reset(self, now: float) -> None:
        """An attempt starts: counters, touch-downs and crashes count from now."""
        self.counts = dict.fromkeys(COUNTERS, 0)
        self.started = now
        self.log = []
        self.crash_where, self.crash_speed = "", 0.0
        s = self.sample
        self._landings0 = s.landings if s is not None else None
        self._crashes0 = s.crashes if s is not None else None

    def truth(self, sample: Truth) -> None:
        before = self.sample
        if before is not None and sample.crashes > before.crashes:  # what it hit, and how fast, from just before
            self.crash_where = crash_place(before)
            self.crash_speed = math.sqrt(before.vn ** 2 + before.ve ** 2 + before.vd ** 2)
        self.sample = sample
        if self._landings0 is None:
            self._landings0 = sample.landings
            self._crashes0 = sample.crashes

    def _count(self, name: str, now: float, what: str) -> None:
        self.counts[name] += 1
        self.log.append((now - self.started, what))

    def event(self, ev: StationEvent, model: Model, now: float) -> None:
        """One station event (after the model applied it)."""
        kind = type(ev)
        if kind is NotSent:
            if ev.title is not None:  # a refusal worth a toast; "not connected" is not the pilot's doing
                self._count("refusals", now, f"refused: {ev.what}: {ev.why}")
        elif kind is Requested:
            self.counts["commands"] += 1
            if ev.op == Op.MODE and ev.arg == Mode.PANIC:
                self._count("panics", now, "PANIC asked for")
        elif kind is LinkDown:
            if ev.link == RADIO:
                self._count("radio_losses", now, "BLE connection lost")
        elif kind is FromLink:
            inner = ev.event
            if type(inner) is CommandFailed and inner.nak is not None:
                self._count("refusals", now, f"the board refused: {inner.reason}")
            elif type(inner) is PacketReceived and type(inner.packet) is Event:
                self._board_event(inner.packet, model, now)

    def _board_event(self, pkt: Event, model: Model, now: float) -> None:
        code = pkt.code
        if code == EventCode.CALIBRATION_DONE:
            self._count("calibrations", now, "calibration done")
        elif code == EventCode.LOW_BATTERY:
            self._count("low_battery", now, "the board saw a low battery")
            self._count("board_panics", now, "the board PANICked: low battery")
        elif code == EventCode.LINK_TIMEOUT:
            self._count("link_timeouts", now, "the board saw the link time out")
            if model.flying:
                self._count("board_panics", now, "the board PANICked: link timeout")
        elif code == EventCode.TILT_LIMIT:
            self._count("tilt_panics", now, "the board PANICked: tilt limit")
            self._count("board_panics", now, "the board PANICked: tilt limit")
        elif code == EventCode.WIRELESS_STATE and pkt.arg == WirelessState.STARTED:
            self._count("handovers", now, "control handed over to BLE")

    # --- the variables ------------------------------------------------------------------------------------

    def namespace(self, model: Model, now: float, step: dict[str, float] | None = None) -> dict[str, Any]:
        """Every variable of ``NAMES`` (``step``: the step's own, from the engine or the autopilot)."""
        ns: dict[str, Any] = dict.fromkeys(NAMES)
        s = self.sample
        if s is not None:
            box_out = self.box.distance(s.n, s.e, s.h) if self.box is not None else None
            ns.update(h=s.h, n=s.n, e=s.e, vz=s.vz, speed=s.speed, tilt=s.tilt_deg, heading=s.heading_deg,
                      yaw_rate=s.yaw_rate_dps, on_ground=s.on_ground, touchdown=s.touchdown, soc=s.soc,
                      cable_ok=s.cable, in_box=box_out == 0.0 if box_out is not None else None, box_out=box_out,
                      landings=s.landings - (self._landings0 if self._landings0 is not None else s.landings),
                      crashes=s.crashes - (self._crashes0 if self._crashes0 is not None else s.crashes),
                      crash_where=self.crash_where, crash_speed=self.crash_speed)
        if model.mode != self._mode:
            self._mode, self._mode_since = model.mode, now
        volts = model.battery_v
        level = battery_level(volts) if volts is not None else None
        # The sagging pack crosses the land level back and forth for a moment: "ok" must last a second to count.
        if level in ("warn", "panic"):
            self._ok_since = None
            if self._warn_since is None:
                self._warn_since = now
        elif self._warn_since is not None:
            if self._ok_since is None:
                self._ok_since = now
            elif now - self._ok_since >= 1.0:
                self._warn_since = self._ok_since = None
        stats = model.radio if model.radio_name and model.over_ble else model.link
        try:
            wireless = WirelessState(model.wireless).name
        except ValueError:
            wireless = None
        ns.update(
            mode=mode_name(model.mode) if model.mode is not None else None, flying=model.flying,
            over_ble=model.over_ble, wireless=wireless, battery=volts, battery_level=level,
            warn_time=now - self._warn_since if self._warn_since is not None else 0.0,
            link_lost=model.control_lost, link_loss=stats.loss_pct if stats is not None else None,
            calibrated=bool(model.flags & Flag.CALIBRATED),
            lift=model.stick.lift, log_saved=model.download_note.startswith("log saved"),
            time=now - self.started, mode_time=now - self._mode_since,
        )
        ns.update(self.counts)
        for name in STEP_NAMES:
            ns[name] = (step or {}).get(name, 0.0)
        return ns


def crash_place(t: Truth) -> str:
    """What a crash at ``t`` hit: the room's walls and ceiling are the simulator's (term.core.protocol's ROOM_*)."""
    if max(abs(t.n), abs(t.e)) > ROOM_HALF_M - 0.4:
        return "a wall"
    if t.h > ROOM_CEILING_M - 0.4:
        return "the ceiling"
    return "the floor"


def names_markdown() -> str:
    """The variables as the Markdown table of docs/lessons.md (a test keeps the copy there equal to this)."""
    rows = ["| variable | meaning |", "|---|---|", *(f"| `{k}` | {v.replace('|', '/')} |" for k, v in NAMES.items())]
    return "\n".join(rows) + "\n"
