"""Ready to fly? The preflight checks a pilot reads in SAFE, each one green or the one thing to do about it.

``checks(model, now, keymap)`` gives the items in a fixed order (``ITEMS``): calibrated, lift at zero, sticks
neutral, link up, battery, crash acknowledged, wireless state, log space. Each ``Check`` is ``ok`` (green),
``todo`` (its ``text`` is the fix, with the keys of the pilot's own key map: "press z 13 times, or Z"), ``wait``
(nothing known yet: no board, or its status is stale) or ``info`` (worth knowing, nothing to do). ``next_step``
picks the first thing to do in the order a pilot must do them (the link before anything, the crash before
calibrating, ...): the first screen tells a new pilot to calibrate.

Every ``Nak`` reason maps to the item it is about (``NAK_ITEM``; None for the reasons no check can show: an
unknown command, a bad argument): a refusal by the board marks its item (``Check.refused``) until the condition
is fixed, so the board's "no" and the panel's fix are one thing. The same numbers as the board's guards
(``term.core.protocol``: LIFT_ZERO, STICK_NEUTRAL, the battery thresholds). Pure: no Textual, no clock reads.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from term.core.protocol import (
    LIFT_ZERO,
    STICK_MAX,
    STICK_NEUTRAL,
    Flag,
    LogState,
    Mode,
    Nak,
    Op,
    WirelessState,
    lift_trim_after,
)
from term.input.keymap import KeyBinding, pretty_key
from term.session.model import Model
from term.session.texts import BATTERY_PANIC_V, BATTERY_WARN_V, rtt_text

# The checks, in the order the panel lists them.
ITEMS = ("calibrated", "lift", "sticks", "link", "battery", "crash", "wireless", "log")
LABELS = {"calibrated": "calibrated", "lift": "lift at zero", "sticks": "sticks neutral", "link": "link up",
          "battery": "battery", "crash": "no crash", "wireless": "wireless", "log": "log space"}
# What the next-step line calls each check's fix.
STEP = {"calibrated": "calibrate", "lift": "lift to zero", "sticks": "centre the sticks", "link": "the link",
        "battery": "the battery", "crash": "the crash", "wireless": "wireless", "log": "the log"}
# The order a pilot fixes things in: nothing works without the link; a crash must be seen before flying again.
PRIORITY = ("link", "crash", "battery", "lift", "sticks", "calibrated", "log", "wireless")

# Every refusal reason -> the check it is about (None: nothing the panel can show; the events list says it).
NAK_ITEM: dict[Nak, str | None] = {
    Nak.OK: None,
    Nak.LIFT_NOT_ZERO: "lift",
    Nak.STICKS_NOT_NEUTRAL: "sticks",
    Nak.NOT_CALIBRATED: "calibrated",
    Nak.NOT_IN_SAFE: None,  # a SAFE-only command in flight: the mode banner says where the board is
    Nak.INVALID_TRANSITION: None,
    Nak.UNKNOWN_COMMAND: None,
    Nak.BAD_ARGUMENT: None,
    Nak.LOG_FULL: "log",
    Nak.LOG_EMPTY: None,  # nothing to download: no fault of the log space, nothing stops a flight
    Nak.LOG_BUSY: "log",
    Nak.BATTERY_LOW: "battery",
    Nak.NO_BLE_CONNECTION: "wireless",
    Nak.BUSY: "calibrated",  # the board is still averaging (CALIBRATION)
    Nak.PANIC_ACTIVE: None,
    Nak.NOT_IMPLEMENTED: None,
    Nak.CRASHED: "crash",
    Nak.OUT_OF_RANGE: None,  # a parameter's value: the parameter screen shows it beside the parameter
    Nak.UNKNOWN_PARAM: None,
    Nak.ONLY_SHORTER_IN_FLIGHT: None,  # a link timeout made longer in flight: the parameter screen says why
    Nak.PARAM_RULE: None,  # a rule between parameters: the parameter screen names it beside the parameter
}

REFUSAL_SHOWN_S = 30.0  # a refusal marks its item this long (or until the item is fixed)
LOG_LOW_PCT = 90  # log fill at which the log check asks for a download


@dataclass(frozen=True, slots=True)
class Check:
    item: str  # one of ITEMS
    state: str  # "ok", "todo", "wait", "info"
    text: str  # what is the case (ok, info, wait) or the one thing to do (todo)
    refused: str = ""  # the board's refusal that named this item, while it stands

    @property
    def label(self) -> str:
        return LABELS[self.item]

    @property
    def step(self) -> str:
        """The fix as the next step: "calibrate — press 3 (board level and still)"."""
        return f"{STEP[self.item]} — {self.text}"


def keys_for(keymap: Iterable[KeyBinding], name: str) -> str:
    """The first key of the key map's action ``name``, as the help screen writes it ("?" if unbound)."""
    for b in keymap:
        if b.action.name == name and b.keys:
            return pretty_key(b.keys[0])
    return "?"


def _key_for_op(keymap: Iterable[KeyBinding], op: Op, sign: int) -> str:
    for b in keymap:
        if b.action.op == op and b.action.arg * sign > 0 and b.keys:
            return pretty_key(b.keys[0])
    return "?"


def _presses(excess: float, step: int | None) -> int | None:
    return None if not step else max(1, math.ceil(excess / step))


def _lift_presses(stick: int, trim: int, step: int | None) -> int | None:
    """Presses of lift down that bring stick + trim to LIFT_ZERO, as the board steps them (finer near hover: the
    protocol's lift_trim_after); the fewest, by bisection (the rule is monotonic in the presses)."""
    if not step:
        return None
    lo, hi = 1, STICK_MAX
    while lo < hi:
        mid = (lo + hi) // 2
        if stick + lift_trim_after(trim, -mid, step, stick) <= LIFT_ZERO:
            hi = mid
        else:
            lo = mid + 1
    return lo


def _value(model: Model, name: str, now: float) -> float | None:
    r = model.reading(name, now)
    return float(r.value) if r.shown and r.value is not None and r.bound != "?" else None


def _status_known(model: Model, now: float) -> bool:
    return model.reading("flags", now).fresh


def _link(model: Model, now: float) -> Check:
    if model.version_mismatch is not None:
        return Check("link", "todo", "other protocol: update board or term")
    if model.control_lost:
        return Check("link", "todo", "LINK LOST: check cable and power")
    s = model.link
    if model.primary_ble and not model.heard:
        return Check("link", "todo", "BLE: 8 on the cable terminal")
    if s is None or s.since_last_frame_s is None:
        return Check("link", "wait", "waiting for the board…")
    rtt = rtt_text(model.radio if model.over_ble else s)  # the link that carries control
    return Check("link", "ok", f"{'BLE' if model.over_ble else 'cable'}{f' ({rtt})' if rtt else ''}")


def _calibrated(model: Model, now: float, keymap: tuple[KeyBinding, ...]) -> Check:
    if model.mode == Mode.CALIBRATION:
        return Check("calibrated", "wait", "calibrating: keep it level and still")
    if not _status_known(model, now):
        return Check("calibrated", "wait", "not known yet (no board status)")
    if model.flags & Flag.CALIBRATED:
        return Check("calibrated", "ok", "sensors zeroed")
    key = keys_for(keymap, "mode_calibration")
    return Check("calibrated", "todo", f"press {key} (board level and still)")


def _lift(model: Model, now: float, keymap: tuple[KeyBinding, ...], lift_step: int | None) -> Check:
    stick = model.stick.lift
    trim = _value(model, "trim_lift", now) or 0.0
    total = stick + trim
    pct = round(100 * total / STICK_MAX)
    if total <= LIFT_ZERO:
        return Check("lift", "ok", f"{pct} % (stick + trim)")
    if stick > LIFT_ZERO:
        return Check("lift", "todo", f"throttle fully down (now {round(100 * stick / STICK_MAX)} %)")
    down, zero = keys_for(keymap, "lift_down"), keys_for(keymap, "lift_zero")
    n = _lift_presses(int(stick), round(trim), lift_step)
    times = f"{n} time{'s' if n != 1 else ''}" if n is not None else "till 0 %"
    return Check("lift", "todo", f"trim {pct} %: press {down} {times}, or {zero}")


_AXES = (("roll", Op.TRIM_ROLL), ("pitch", Op.TRIM_PITCH), ("yaw", Op.TRIM_YAW))


def _sticks(model: Model, now: float, keymap: tuple[KeyBinding, ...], trim_step: int | None) -> Check:
    s = model.stick
    for axis, op in _AXES:
        stick = getattr(s, axis)
        trim = _value(model, f"trim_{axis}", now) or 0.0
        if abs(stick + trim) <= STICK_NEUTRAL:
            continue
        if abs(stick) > STICK_NEUTRAL:
            return Check("sticks", "todo", f"centre the {axis} stick (now {round(100 * stick / STICK_MAX):+d} %)")
        key = _key_for_op(keymap, op, -1 if trim > 0 else +1)
        n = _presses(abs(stick + trim) - STICK_NEUTRAL, trim_step)
        times = f" {n} time{'s' if n != 1 else ''}" if n is not None else " till 0"
        return Check("sticks", "todo", f"{axis} trim {trim:+.0f}: press {key}{times}")
    return Check("sticks", "ok", "centred (stick + trim)")


def _battery(model: Model, now: float) -> Check:
    r = model.reading("battery", now)
    if not r.shown or r.value is None:
        return Check("battery", "wait", "not known yet")
    v = float(r.value)
    if v < BATTERY_PANIC_V:
        return Check("battery", "todo", f"{v:.2f} V: charge or swap it")
    if v < BATTERY_WARN_V:
        return Check("battery", "info", f"{v:.2f} V: low, a short flight only")
    # a tenth of a volt when all is well: the hundredths are the ADC's noise, and redrew the panel every frame (the
    # battery gauge beside it has them)
    return Check("battery", "ok", f"{v:.1f} V")


def _crash(model: Model, now: float, keymap: tuple[KeyBinding, ...]) -> Check:
    crashed = getattr(Flag, "CRASHED", None)
    if crashed is None:
        return Check("crash", "ok", "—")
    if not _status_known(model, now):
        return Check("crash", "wait", "not known yet")
    if model.flags & crashed:
        key = keys_for(keymap, "ack_crash")
        return Check("crash", "todo", f"crashed: check the craft, press {key}")
    return Check("crash", "ok", "none")


def _wireless(model: Model, now: float) -> Check:
    try:
        state = WirelessState(model.wireless)
    except ValueError:
        return Check("wireless", "info", f"state {model.wireless}")
    if state == WirelessState.STARTED:
        return Check("wireless", "ok", "flying over BLE")
    if state == WirelessState.STARTING:
        return Check("wireless", "info", "handing over to BLE…")
    if model.primary_ble:
        return Check("wireless", "info", "BLE: waiting for the handover")
    if model.radio_name and not model.radio_up:
        return Check("wireless", "info", "cable; radio not connected")
    if model.radio_name:
        return Check("wireless", "ok", "cable; radio ready (8 hands over)")
    return Check("wireless", "ok", "cable")


def _log(model: Model, now: float, keymap: tuple[KeyBinding, ...]) -> Check:
    fill = _value(model, "log_fill", now)
    state = model.log_state
    if fill is None and not model.reading("log_fill", now).carried:  # nothing to wait for: BLE never sends it
        return Check("log", "info", "not over BLE (the cable's status carries it)")
    if fill is None:
        return Check("log", "wait", "not known yet")
    if state == LogState.FULL or fill >= 100:
        return Check("log", "todo", f"full: download ({keys_for(keymap, 'log_download')}), erase "
                     f"({keys_for(keymap, 'log_reset')})")
    if fill >= LOG_LOW_PCT:
        return Check("log", "info", f"{fill:.0f} % used: download, erase soon")
    return Check("log", "ok", f"{100 - fill:.0f} % free")


def checks(model: Model, now: float, keymap: tuple[KeyBinding, ...], *, lift_step: int | None = None,
           trim_step: int | None = None) -> list[Check]:
    """Every check, in ``ITEMS`` order. ``lift_step``/``trim_step``: stick units per key press (None: unknown,
    the fix says "until it reads 0")."""
    found = {
        "calibrated": _calibrated(model, now, keymap),
        "lift": _lift(model, now, keymap, lift_step),
        "sticks": _sticks(model, now, keymap, trim_step),
        "link": _link(model, now),
        "battery": _battery(model, now),
        "crash": _crash(model, now, keymap),
        "wireless": _wireless(model, now),
        "log": _log(model, now, keymap),
    }
    refusals: dict[str, tuple[str, float]] = {}  # item -> its latest refusal (text, when)
    for nak, (text, t) in model.refused.items():
        item = NAK_ITEM.get(Nak(nak)) if nak in Nak._value2member_map_ else None
        if item is not None and now - t <= REFUSAL_SHOWN_S and t >= refusals.get(item, ("", -math.inf))[1]:
            refusals[item] = (text, t)
    out = []
    for item in ITEMS:
        c = found[item]
        refusal = refusals.get(item)
        if refusal is not None and c.state != "ok":
            c = Check(c.item, "todo", c.text, refusal[0])
        out.append(c)
    return out


def next_step(found: list[Check]) -> Check | None:
    """The first thing to do, in the order a pilot does them (``PRIORITY``); None when nothing is to do."""
    by_item = {c.item: c for c in found}
    for item in PRIORITY:
        c = by_item.get(item)
        if c is not None and c.state == "todo":
            return c
    return None


def ready(found: list[Check]) -> bool:
    """Every check green or only informative: the board will let the pilot leave SAFE."""
    return all(c.state in ("ok", "info") for c in found)
