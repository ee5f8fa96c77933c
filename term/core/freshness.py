"""How old each figure on the screen is, where it came from, and whether it can be trusted: the model's freshness.

Every telemetry packet's arrival is noted (``Arrivals.note``) with the model's clock; each packet kind learns its
own period from its arrivals (a gap longer than the staleness limit is a gap, not a period). A displayed figure is
a ``Reading`` (``read(model, name, now)``):

- its **value** in the shown unit (through the packet table's scales), from the freshest of its sources: phi,
  theta, psi and the battery come from the cable's Attitude and Height or the radio's Compact; the motors, height,
  set point, vz, flags and lift trim from the cable's Motion, Height and Status or the radio's Compact2 (motors in
  steps of 4 there), whichever arrived last; a trim also from the board's Ack of a trim command (the Ack carries
  the new trim, over either link);
- its **age** (seconds since the packet behind it arrived) and its **limit**: ``STALE_PERIODS`` of its packet's
  periods, never less than ``STALE_FLOOR_S``; older is **stale** (drawn dimmed, with its age);
- whether the link that carries control **carries** it now: over BLE the board sends Compact, Compact2, events
  and acks, not the full telemetry (``term.core.protocol.TELEMETRY``: rates, accelerations, pressure, temperature, the
  roll/pitch/yaw trims' Status, CPU load, log fill, gains); a figure that is stale and not carried is not shown as
  a number at all: the panel says "not over BLE";
- its **bound**: a value at its field's encoding limit (the board clips there) is ">" or "<" that limit, never a
  plain number; "?" for a value that is not a number.

No Textual, no clock reads. Tests: tests/core/test_freshness.py (property test over every field's range) and the
handover test in tests/ui/test_app_wireless.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any, Protocol

from term.core.protocol import SPEC_OF, TELEMETRY, Compact, Compact2, Op, field_spec

spec_of = cache(field_spec)  # the table's entry of (packet class, field): looked up for every figure drawn

STALE_PERIODS = 4  # a figure older than this many of its packet's periods is stale
STALE_FLOOR_S = 0.5  # ... and never younger than this (render ticks, BLE batching, a busy machine)
FIRST_PERIOD_S = 0.25  # the period assumed until a packet kind has arrived twice
PERIOD_GAIN = 0.2  # smoothing of the period estimate

# Displayed figure -> the packet kinds that carry it (the field has the same name in each): every field of the
# cable's telemetry packets and of the phone's two, read from the packet table, the cable's kinds first. A new
# field in one of these packets is a figure the model can read, with no list to extend here.
CARRIERS: tuple[type, ...] = (*TELEMETRY, Compact, Compact2)


def _sources() -> dict[str, tuple[type, ...]]:
    out: dict[str, tuple[type, ...]] = {}
    for kind in CARRIERS:
        for spec in SPEC_OF[kind].fields:
            out[spec.name] = (*out.get(spec.name, ()), kind)
    return out


SOURCES = _sources()
# A trim command's Ack carries the trim's new value (stick units): a second source of the trim, on either link.
TRIM_OPS: dict[int, str] = {Op.TRIM_ROLL: "trim_roll", Op.TRIM_PITCH: "trim_pitch", Op.TRIM_YAW: "trim_yaw",
                            Op.TRIM_LIFT: "trim_lift"}
ACK = "Ack"
# Fields that name a state or a set of bits, not a quantity: nothing is clipped at the end of their encoding.
_NOT_QUANTITIES = frozenset({"Mode", "WirelessState", "Flag", "LogState", "bits"})


@dataclass(slots=True)
class Arrival:
    pkt: Any
    t: float  # model clock, s
    period: float | None = None


class Arrivals:
    """The last packet of each kind, when it came and how often that kind comes."""

    def __init__(self) -> None:
        self.last: dict[type, Arrival] = {}
        self.acks: dict[str, tuple[int, float]] = {}  # trim name -> (value, when its Ack came)

    def note(self, pkt: Any, now: float) -> None:
        kind = type(pkt)
        a = self.last.get(kind)
        if a is None:
            self.last[kind] = Arrival(pkt, now)
            return
        interval = now - a.t
        if interval <= self.limit(kind):  # longer is a gap (a handover, a lost link), not the packet's period
            a.period = interval if a.period is None else a.period + PERIOD_GAIN * (interval - a.period)
        a.pkt, a.t = pkt, now

    def note_ack(self, op: int, value: int, now: float) -> None:
        name = TRIM_OPS.get(op)
        if name is not None:
            self.acks[name] = (value, now)

    def limit(self, kind: type) -> float:
        """Seconds after which a figure from ``kind`` is stale."""
        a = self.last.get(kind)
        period = FIRST_PERIOD_S if a is None or a.period is None else a.period
        return max(STALE_FLOOR_S, STALE_PERIODS * period)


@dataclass(frozen=True, slots=True)
class Reading:
    """One displayed figure: value (shown unit), age and staleness limit (s), whether the current link carries
    it, and its bound (">" / "<" at the field's limit, "?" not a number)."""

    name: str
    value: float | None  # None: never received
    unit: str = ""
    age: float = math.inf
    limit: float = STALE_FLOOR_S
    carried: bool = True
    bound: str = ""
    source: str = ""
    edge: float | None = None  # the field's limit in the shown unit, when ``bound`` is ">" or "<"

    @property
    def known(self) -> bool:
        return self.value is not None

    @property
    def stale(self) -> bool:
        return self.known and self.age > self.limit

    @property
    def fresh(self) -> bool:
        return self.known and self.age <= self.limit

    @property
    def shown(self) -> bool:
        """Whether the value is drawn as a number: known, and fresh or still carried by the current link."""
        return self.known and (self.fresh or self.carried)

    @property
    def mark(self) -> str:
        """What the screen adds to a figure that is not fresh ("" if it is)."""
        if not self.known or self.fresh:
            return ""
        if not self.carried:
            return f"not over BLE (last {age_text(self.age)} ago)"
        return f"{age_text(self.age)} old"


_AGE_UNITS = ((100.0, 1.0, "s"), (6000.0, 60.0, "min"), (math.inf, 3600.0, "h"))  # (below, step, unit)


def age_text(age: float) -> str:
    """An age in whole seconds (minutes from 100 s, hours from 100 min), rounded down: it changes only at whole
    steps, so a panel redraws it then (``next_age_change``) and never shows an age that is already past."""
    if age < 1.0:
        return "<1 s"
    for below, step, unit in _AGE_UNITS:
        if age < below:
            return f"{int(age // step)} {unit}"
    return "long"


def next_age_change(age: float) -> float:
    """Seconds until ``age_text(age)`` changes."""
    for below, step, _ in _AGE_UNITS:
        if age < below:
            return max(1e-3, (age // step + 1) * step - age)
    return 3600.0


class Source(Protocol):
    """What a reading needs of the model (term.session.model.Model is one): the arrivals and the link in use."""

    arrivals: Arrivals

    @property
    def over_ble(self) -> bool: ...


def carried(model: Source, kind: type | str) -> bool:
    """Whether the link that carries control brings ``kind`` now: over BLE the board sends Compact, Compact2,
    events and acks but not the full telemetry; the cable sends neither Compact."""
    if kind == ACK:
        return True
    if model.over_ble:
        return kind not in TELEMETRY
    return kind not in (Compact, Compact2)


def bound(kind: type, name: str, raw: Any) -> str:
    """">" or "<" if ``raw`` sits at an end of its encoding (the board clipped it), "?" if not a number."""
    if isinstance(raw, float) and math.isnan(raw):
        return "?"
    spec = spec_of(kind, name)
    if spec.unit in _NOT_QUANTITIES or not spec.saturated(raw):
        return ""
    lim = spec.limits
    return ">" if lim is not None and raw >= lim[1] else "<"


def read(model: Source, name: str, now: float) -> Reading:
    """The figure ``name`` (a key of ``SOURCES``) as the model knows it at ``now``."""
    arrivals = model.arrivals
    best: tuple[float, Any, str, float] | None = None  # (t, raw, source, limit)
    kinds = SOURCES[name]
    for kind in kinds:
        a = arrivals.last.get(kind)
        if a is not None and (best is None or a.t > best[0]):
            best = (a.t, getattr(a.pkt, name), kind.__name__, arrivals.limit(kind))
    ack = arrivals.acks.get(name)
    if ack is not None and (best is None or ack[1] > best[0]):
        best = (ack[1], ack[0], ACK, arrivals.limit(kinds[0]))
    is_carried = any(carried(model, k) for k in kinds)
    if best is None:
        return Reading(name, None, spec_of(kinds[0], name).scaled_unit, carried=is_carried)
    t, raw, source, limit = best
    is_carried = is_carried or source == ACK  # an Ack came over the link that carries control
    kind = next((k for k in kinds if k.__name__ == source), kinds[0])  # an Ack's trim: in Status's terms
    spec = spec_of(kind, name)
    value = raw * spec.scale if isinstance(raw, int | float) else raw
    b = bound(kind, name, raw)
    lim = spec.limits
    edge = None if b not in (">", "<") or lim is None else (lim[1] if b == ">" else lim[0]) * spec.scale
    return Reading(name, value, spec.scaled_unit, now - t, limit, is_carried, b, source, edge)
