"""What the pilot is commanding: the stick (or keyboard only), the board's trims and lift, gains and flags."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.input.mapping import FULL, LIFT_ZERO
from term.model import Model
from term.protocol import Button, Flag, LogState, Mode
from term.widgets.bars import cbar, hbar
from term.widgets.base import ModelView

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


class ControlsPanel(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        s = model.stick
        st = model.status
        width = max(7, ((self.content_size.width or 44) - 26) | 1)
        out = Text()
        if model.joystick_name:
            out.append(f"stick: {model.joystick_name[:30]}", style="bold")
            out.append(f"  ({model.joystick_mapping})\n" if model.joystick_mapping else "\n", style="dim")
        else:
            out.append("stick: none, keyboard only\n", style="dim")
        trims = (st.trim_roll, st.trim_pitch, st.trim_yaw) if st else (0, 0, 0)
        for name, v, trim in (("roll ", s.roll, trims[0]), ("pitch", s.pitch, trims[1]), ("yaw  ", s.yaw, trims[2])):
            out.append(f"{name} ")
            out.append_text(cbar(v + trim, FULL, width))
            out.append(f" {_pct(v)} trim {trim:+6d}\n")
        lift_trim = st.trim_lift if st else 0
        out.append("lift  ")
        out.append_text(hbar(s.lift + lift_trim, 0, FULL, width, "yellow" if s.lift > LIFT_ZERO else "green"))
        out.append(f" {100 * s.lift / FULL:4.0f}% trim {lift_trim:+6d}\n")
        if s.lift > LIFT_ZERO and model.mode in (None, Mode.SAFE):  # flying, lift is what it should be
            out.append("throttle up: SAFE cannot be left\n", style="yellow")
        if s.buttons & Button.FIRE:
            out.append("FIRE pressed: PANIC\n", style="bold red")
        g = model.gains
        if g:
            out.append(f"gains  yaw P {g.yaw_p:.4g}  P1 {g.p1:.4g}  P2 {g.p2:.4g}  "
                       f"height P {g.height_p:.4g}  D {g.height_d:.4g}\n")
        else:
            out.append("gains  —\n", style="dim")
        flags = model.flags
        out.append("flags  ")
        for f, name in FLAG_NAMES:
            if flags & f:
                bad = f in (Flag.LOW_BATTERY, Flag.LINK_TIMEOUT)
                out.append(name + " ", style="bold red" if bad else "bold green")
        if st:
            out.append(f"\ncpu {st.cpu_load:3d}%  log {st.log_fill:3d}%", style="")
            ls = model.log_state
            if ls is not None and ls != LogState.IDLE:
                out.append(f" {ls.name}", style="yellow")
        return out
