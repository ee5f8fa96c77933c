"""What the pilot is commanding: the stick (or keyboard only), the board's trims and lift, gains and flags."""

from __future__ import annotations

import struct
from dataclasses import replace

from rich.console import RenderableType
from rich.text import Text

from term.core.freshness import Reading
from term.core.protocol import PARAMS, Button, Flag, LogState, Mode
from term.input.mapping import FULL, LIFT_ZERO
from term.session.model import Model
from term.ui.widgets.bars import cbar, hbar
from term.ui.widgets.base import STALE_STYLE, ModelView, figure

FLAG_NAMES = (
    (Flag.CALIBRATED, "CAL"),
    (Flag.ARMED, "ARMED"),
    (Flag.LOGGING, "LOG"),
    (Flag.BLE_CONNECTED, "BLE"),
    (Flag.WIRELESS_ACTIVE, "WIRELESS"),
    (Flag.RAW_SENSORS, "RAW"),
    (Flag.FIXED_POINT, "Q16.16"),
    (Flag.PRIORITY_SCHEDULER, "PRIO"),
    (Flag.HEIGHT_HOLD, "HOLD"),
    (Flag.LOW_BATTERY, "LOWBAT"),
    (Flag.LINK_TIMEOUT, "TIMEOUT"),
)


def _pct(v: int) -> str:
    return f"{100 * v / FULL:+4.0f}%"


def _as_pct(trim: Reading, stick: int) -> Reading:
    """The lift trim (shown, a number) plus ``stick`` as a percentage of full lift, with the trim's age."""
    assert trim.value is not None
    return replace(trim, value=100 * (stick + float(trim.value)) / FULL, unit="%", bound="", edge=None)


def _num(r: Reading) -> float:
    return r.value if r.shown and r.value is not None and r.bound != "?" else 0.0


def _marks(groups: tuple[tuple[str, list[Reading]], ...]) -> str:
    """The subtitle: each age mark once, with every group it applies to."""
    marks: dict[str, list[str]] = {}
    for what, rs in groups:
        for r in rs:
            if r.mark and what not in marks.setdefault(r.mark, []):
                marks[r.mark].append(what)
    return " · ".join(f"{', '.join(whats)}: {mark}" for mark, whats in marks.items())


def _stick_lines(out: Text, model: Model, trims: list[Reading], width: int) -> None:
    """The stick's name, then roll, pitch and yaw with their trims."""
    s = model.stick
    if model.joystick_name:
        out.append(f"stick: {model.joystick_name[:30]}", style="bold")
        out.append(f"  ({model.joystick_mapping})\n" if model.joystick_mapping else "\n", style="dim")
    else:
        out.append("stick: none, keyboard only\n", style="dim")
    for name, v, trim in (("roll ", s.roll, trims[0]), ("pitch", s.pitch, trims[1]), ("yaw  ", s.yaw, trims[2])):
        out.append(f"{name} ")
        out.append_text(cbar(v + _num(trim), FULL, width))
        out.append(f" {_pct(v)} trim ")
        out.append_text(figure(trim, "+6d"))
        out.append("\n")


def _lift_lines(out: Text, model: Model, lift_trim: Reading, width: int) -> None:
    """The lift the board flies, its two parts, and the warnings that go with the stick."""
    s = model.stick
    total = s.lift + _num(lift_trim)
    out.append("lift  ")
    out.append_text(hbar(total, 0, FULL, width - 10, "yellow" if total > LIFT_ZERO else "green"))
    # The lift the board flies is the stick plus the trim: one percentage, then its two parts. A tenth of a per cent:
    # near hover a press of a/z is a quarter of one (the protocol's lift_trim_after), and each must show.
    if lift_trim.shown and not lift_trim.bound:  # a bound ("<", ">", "?") is said as the trim itself, below
        out.append_text(figure(_as_pct(lift_trim, s.lift), "5.1f", "%", pad=" "))
        out.append(f" (stick {100 * s.lift / FULL:.0f} + trim", style="dim")
        out.append_text(figure(_as_pct(lift_trim, 0), ".1f", ")", style="dim", pad=" "))
    else:
        out.append(f" {100 * s.lift / FULL:4.0f}% (stick; trim ")
        out.append_text(figure(lift_trim, "+d", ")"))
    out.append("\n")
    if s.lift > LIFT_ZERO and model.mode in (None, Mode.SAFE):  # flying, lift is what it should be
        out.append("throttle up: SAFE cannot be left\n", style="yellow")
    if s.buttons & Button.FIRE:
        out.append("FIRE pressed: PANIC\n", style="bold red")


_GAIN_SPECS = {s.name.removeprefix("ctrl."): s for s in PARAMS.values()  # the gains as the parameter table has them
               if s.name in ("ctrl.yaw_p", "ctrl.p1", "ctrl.p2", "ctrl.height_p", "ctrl.height_d")}


def _shortest_half(value: float) -> float:
    """The shortest decimal that is the same half float (the Gains packet's "e" field: 0.4 arrives as 0.39990)."""
    try:
        want = struct.pack("<e", value)
    except (OverflowError, struct.error):
        return value
    for digits in range(1, 6):
        short = float(f"{value:.{digits}g}")
        try:
            same = struct.pack("<e", short) == want
        except OverflowError:  # 65504, the largest half, rounds to 7e+04 at one digit: not a half at all
            continue
        if same:
            return short
    return value


def _gains_line(out: Text, gains: list[Reading]) -> None:
    if gains[0].shown:
        out.append("gains ")
        for label, r in zip((" yaw P ", "  P1 ", "  P2 ", "  height P ", "  D "), gains, strict=True):
            out.append(label, style=STALE_STYLE if r.stale else "")
            spec = _GAIN_SPECS.get(r.name)
            if spec is not None and r.shown and r.value is not None and not r.bound:  # as the table rounds it
                out.append(spec.text(_shortest_half(r.value)), style=STALE_STYLE if r.stale else "")
            else:
                out.append_text(figure(r, ".4g"))
        out.append("\n")
    else:
        out.append("gains  —\n", style="dim")


def _flags_line(out: Text, flags_r: Reading) -> None:
    out.append("flags  ")
    if not flags_r.shown:
        out.append("—", style=STALE_STYLE)
        return
    flags = Flag(int(_num(flags_r)))
    for f, name in FLAG_NAMES:
        if flags & f:
            bad = f in (Flag.LOW_BATTERY, Flag.LINK_TIMEOUT)
            out.append(name + " ", style=STALE_STYLE if flags_r.stale else "bold red" if bad else "bold green")


def _status_line(out: Text, model: Model, cpu: Reading, log: Reading) -> None:
    """CPU load, log fill and the log's state, when the board has said them (a load of 0: "—", not measured)."""
    if not cpu.known:
        return
    out.append("\ncpu ")
    if cpu.value == 0:  # a running loop is never idle: 0 is a board that does not measure it (the C board's so far)
        out.append("  —", style="dim")
    else:
        out.append_text(figure(cpu, "3d", "%"))
    out.append("  log ")
    out.append_text(figure(log, "3d", "%"))
    ls = model.log_state
    if ls is not None and ls != LogState.IDLE:
        out.append(f" {ls.name}", style="yellow")


class ControlsPanel(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        trims = [self.read(model, n, now) for n in ("trim_roll", "trim_pitch", "trim_yaw", "trim_lift")]
        gains = [self.read(model, n, now) for n in ("yaw_p", "p1", "p2", "height_p", "height_d")]
        flags_r, cpu, log = (self.read(model, n, now) for n in ("flags", "cpu_load", "log_fill"))
        # the same age said once for every group it applies to, each named by what it is: over BLE the flags
        # come (Compact2), the CPU load and log fill do not
        self.subtitle(_marks((("trims", trims), ("gains", gains), ("flags", [flags_r]), ("cpu, log", [cpu, log]))))
        width = max(7, ((self.content_size.width or 44) - 26) | 1)
        out = Text()
        if 0 < self.content_size.height < 6:  # the compact layout: the lift first, it is what the pilot flies by
            _lift_lines(out, model, trims[3], width)
            _stick_lines(out, model, trims, width)
        else:
            _stick_lines(out, model, trims, width)
            _lift_lines(out, model, trims[3], width)
        _gains_line(out, gains)
        _flags_line(out, flags_r)
        _status_line(out, model, cpu, log)
        return out
