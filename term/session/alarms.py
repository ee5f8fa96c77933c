"""Alarms worth a sound: LINK LOST, PANIC, a low battery and a crash. ``Alarms.update(model, now)`` returns the
alarms that have just begun (each once, on its rising edge; it may ring again after it has ended), for the app to
ring the terminal's bell (``[alarms] bell`` in the config, ``--no-bell`` on the command line). Pure: no Textual.

- LINK LOST: the link that carries control went silent (``Model.control_lost``; the cable's silence while flying
  over BLE is not an alarm);
- PANIC: the board is in PANIC (whoever asked for it: the pilot, the fire button or the board's safety monitor);
- low battery: the board's LOW_BATTERY flag, or a battery under the board's PANIC threshold;
- crash: the board's CRASHED flag (an impact the pilot has not acknowledged);
- not recording: the session recording failed (a read-only folder, a full disk: ``Model.recording_error``), at
  once, not after quitting.
"""

from __future__ import annotations

from term.core.protocol import EventCode, Flag, Mode
from term.session.model import Model
from term.session.texts import BATTERY_PANIC_V

ALARMS = ("LINK LOST", "PANIC", "low battery", "crash", "not recording")
EVENT_ALARM_S = 5.0  # a board event (LOW_BATTERY, CRASH) holds its alarm this long (over BLE no Status says it)


def active(model: Model, now: float) -> set[str]:
    """The alarms that hold now."""
    out = set()
    if model.control_lost:
        out.add("LINK LOST")
    if model.mode == Mode.PANIC:
        out.add("PANIC")
    flags_fresh = model.reading("flags", now).fresh
    flags = model.flags if flags_fresh else Flag(0)
    battery = model.reading("battery", now)
    if (flags & Flag.LOW_BATTERY or _recent(model, "LOW_BATTERY", now)
            or (battery.fresh and battery.value is not None and battery.value < BATTERY_PANIC_V)):
        out.add("low battery")
    crashed = getattr(Flag, "CRASHED", None)
    if (crashed is not None and flags & crashed) or _recent(model, "CRASH", now):
        out.add("crash")
    if model.recording_error:
        out.add("not recording")
    return out


def _recent(model: Model, code: str, now: float) -> bool:
    c = getattr(EventCode, code, None)
    t = None if c is None else model.event_times.get(int(c))
    return t is not None and now - t <= EVENT_ALARM_S


class Alarms:
    """Rising edges of ``active``: each alarm is reported once when it begins."""

    def __init__(self) -> None:
        self.on: set[str] = set()

    def update(self, model: Model, now: float) -> list[str]:
        now_on = active(model, now)
        new = [a for a in ALARMS if a in now_on and a not in self.on]
        self.on = now_on
        return new
