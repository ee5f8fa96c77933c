"""What the pilot reads: the words and units for a mode, a command, a board's event, a refusal, a battery and a
round trip. Pure functions over the protocol's tables; the model (term/session/model.py) writes them into the
events list, the widgets show them."""

from __future__ import annotations

from term.core.link import (
    LinkStats,
)
from term.core.protocol import (
    BATTERY_FULL,
    BATTERY_LOW,
    BATTERY_WARN,
    EVENT_ARG_SCALE,
    HEIGHT_KEY_STEP_MM,
    PARAMS,
    ContactKind,
    EventCode,
    Height,
    Mode,
    MotorTestEnd,
    Nak,
    Op,
    WirelessState,
    field_scale,
    motor_test_split,
    param_split,
)
from term.input.keymap import ZERO_TRIM_STEPS

_VOLTS = field_scale(Height, "battery")
BATTERY_PANIC_V = BATTERY_LOW * _VOLTS  # the board's PANIC threshold while flying
BATTERY_WARN_V = BATTERY_WARN * _VOLTS  # a 3S LiPo at its nominal voltage: time to land
BATTERY_FULL_V = BATTERY_FULL * _VOLTS



def battery_level(volts: float) -> str:
    """"panic" under the board's PANIC threshold, "warn" under a 3S LiPo's nominal voltage (time to land), else
    "ok"."""
    if volts < BATTERY_PANIC_V:
        return "panic"
    if volts < BATTERY_WARN_V:
        return "warn"
    return "ok"


def mode_name(mode: int | None) -> str:
    if mode is None:
        return "—"
    try:
        return Mode(mode).name
    except ValueError:
        return f"MODE {mode}"


RTT_IDLE_S = 1.0  # a link that answered no heartbeat for this long is idle: it shows no round-trip time


def rtt_text(s: LinkStats | None) -> str:
    """The one round-trip time the screens show: the heartbeat's round trip (the board's own measurement and the
    commands' acknowledgements), the mean of the recent ones, as "RTT 27 ms"; "" for a link that is idle or has
    none measured (issue 22: three RTTs on one screen, and one for a silent cable)."""
    if s is None or s.rtt_mean_ms is None or s.since_last_heartbeat_s is None or s.since_last_heartbeat_s > RTT_IDLE_S:
        return ""
    return "RTT <1 ms" if s.rtt_mean_ms < 0.5 else f"RTT {s.rtt_mean_ms:.0f} ms"


def op_text(op: int, arg: int) -> str:
    """A command in words, for the events list."""
    try:
        o = Op(op)
    except ValueError:
        return f"op {op}"
    if o is Op.MODE:
        return f"mode {mode_name(arg)}"
    if o is Op.WIRELESS:
        return "wireless handover" if arg else "wireless hand-back"
    if o is Op.SET_PARAM:
        pid, raw = param_split(arg)
        spec = PARAMS.get(pid)  # type: ignore[call-overload]
        return f"set param {pid} = {raw}" if spec is None else f"set {spec.name} = {spec.text(spec.from_raw(raw))}"
    if o is Op.PARAM_GET:
        spec = PARAMS.get(arg)  # type: ignore[call-overload]
        return f"get param {arg}" if spec is None else f"get {spec.name}"
    if o is Op.PARAM_LIST:
        return "list the parameters"
    if o is Op.MOTOR_TEST:
        mask, level = motor_test_split(arg)
        return f"motor test: mask {mask:x} at {level}" if level and mask else "motor test: stop"
    name = o.name.lower().replace("_", " ")
    if o is Op.TRIM_LIFT and arg <= ZERO_TRIM_STEPS:
        return "lift trim to zero"
    if o.name.startswith(("TRIM_", "GAIN_")):
        return f"{name} {'+' if arg > 0 else ''}{arg}"
    return name


def event_text(code: int, arg: int, flying: bool = True, mode: int | None = None) -> tuple[str, str]:
    """(severity, text) for a board Event; ``flying``: the board was in a flight mode when it sent it (a link
    timeout PANICs only there); ``mode``: the mode it was in (a link timeout in PANIC: the descent goes on)."""
    try:
        c = EventCode(code)
    except ValueError:
        return "warning", f"board event {code} ({arg})"
    if c is EventCode.BOOT:
        return "info", f"board booted (protocol v{arg})"
    if c is EventCode.MODE_CHANGED:
        return "info", f"mode {mode_name(arg >> 8)} → {mode_name(arg & 0xFF)}"
    if c is EventCode.REFUSED:
        try:
            why = _nak_text(Nak(arg >> 8))
        except ValueError:
            why = f"reason {arg >> 8}"
        return "error", f"board refused {mode_name(arg & 0xFF)}: {why}"
    if c is EventCode.LOW_BATTERY:
        return "error", f"LOW BATTERY {_event_arg(c, arg):.2f} V"
    if c is EventCode.LINK_TIMEOUT:
        silent = f"board saw link timeout ({_event_arg(c, arg) * 1000:.0f} ms silent)"
        if mode == Mode.PANIC:
            return "error", f"{silent}: already in PANIC, the descent goes on"
        return ("error", f"{silent}: PANIC") if flying else ("warning", f"{silent}: not flying, no PANIC")
    if c is EventCode.LINK_LOST:
        return "error", f"LINK LOST: board holds level ({_event_arg(c, arg) * 1000:.0f} ms silent); PANIC if it stays"
    if c is EventCode.LINK_REGAINED:
        return "warning", f"board has the link back after {_event_arg(c, arg) * 1000:.0f} ms: no PANIC, fly on"
    if c is EventCode.HEIGHT_SETPOINT:
        return "info", f"HEIGHT set point {_event_arg(c, arg):.2f} m (lift keys: ±{HEIGHT_KEY_STEP_MM / 1000:.2f} m)"
    if c is EventCode.CRASH:
        return "error", f"crash at {_event_arg(c, arg):.2f} m/s: motors off (c acknowledges it)"
    if c is EventCode.SIM_LAG:
        return "warning", f"simulator {_event_arg(c, arg) * 1000:.0f} ms behind real time (its process was starved)"
    if c is EventCode.TILT_LIMIT:
        return "error", f"tilt limit {_event_arg(c, arg):.1f}°: PANIC"
    if c is EventCode.CONTACT:
        kind, mm_s = arg >> 16, arg & 0xFFFF
        if kind == ContactKind.WALL:
            return "warning", "hit something sideways (a wall?)"
        what = "touched down" if kind == ContactKind.GROUND else "hit the ceiling"
        return ("info" if kind == ContactKind.GROUND else "warning"), f"{what} at {mm_s / 1000:.2f} m/s"
    if c is EventCode.HEADING_DRIFT:
        return "info", f"heading drift {_event_arg(c, arg):+.1f}° since calibration, taken out (no compass)"
    if c is EventCode.PANIC_DONE:
        return "info", "panic done: motors off, SAFE"
    if c is EventCode.CALIBRATION_DONE:
        return "info", f"calibration done ({arg} samples)"
    if c is EventCode.LOG_FULL:
        return "warning", f"log flash full ({arg} bytes)"
    if c is EventCode.LOG_DONE:
        return "info", f"log download sent ({arg} chunks)"
    if c is EventCode.WIRELESS_STATE:
        try:
            return "info", f"wireless {WirelessState(arg).name}"
        except ValueError:
            return "info", f"wireless state {arg}"
    if c is EventCode.DEADLINE_MISS:
        return "warning", f"deadline miss (period {arg} µs)"
    if c is EventCode.SENSOR_FAULT:
        return "error", f"sensor fault (sensor {arg})"
    if c is EventCode.OVERFLOW:
        return "warning", f"board receive queue overflow ({arg} bytes dropped)"
    if c is EventCode.MOTOR_TEST:  # the bench test ended (docs/modes.md); the reasons by name
        try:
            return "info", f"motor test ended: {MotorTestEnd(arg).name.lower().replace('_', ' ')}"
        except ValueError:
            return "info", f"motor test ended ({arg})"
    if c is EventCode.PARAM_CHANGED:
        pid, raw = param_split(arg)
        spec = PARAMS.get(pid)  # type: ignore[call-overload]
        if spec is None:
            return "info", f"param {pid}: {raw} (not in this terminal's table)"
        value = spec.from_raw(raw)
        default = "" if raw == spec.to_raw(spec.default) else f" (default {spec.text(spec.default)})"
        return "info", f"param {spec.name}: {spec.text(value)}{(' ' + spec.unit) if spec.unit else ''}{default}"
    return "info", f"{c.name.lower()} ({arg})"


def _event_arg(code: EventCode, arg: int) -> float:
    """An Event's argument in its unit (V, s, °; EVENT_ARG_SCALE)."""
    return arg * EVENT_ARG_SCALE[code][0]


def _nak_text(nak: Nak) -> str:
    from term.core.protocol import nak_text

    return nak_text(nak)
