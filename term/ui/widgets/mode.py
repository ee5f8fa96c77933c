"""The mode banner: the board's mode written out, large; PANIC unmistakable; SAFE-only states spelled out."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.core.protocol import MODE_TABLE, EventCode, Flag, Mode
from term.session.model import Model
from term.session.texts import mode_name
from term.ui.widgets.base import ModelView

STYLE = {mode: spec.style for mode, spec in MODE_TABLE.items()}  # the mode table's colours


SIM_LAG_SHOWN_S = 3.0  # the simulator says it is behind at most once a second while it is: shown this long


def sim_lag_text(model: Model, now: float) -> str:
    """How far the simulated board runs behind real time, while it says so ("" when it keeps up, or a real board)."""
    said = model.event_times.get(EventCode.SIM_LAG)
    if said is None or now - said > SIM_LAG_SHOWN_S:
        return ""
    return f"simulator {model.event_args.get(EventCode.SIM_LAG, 0)} ms behind real time (its process is starved)"


def spaced(word: str) -> str:
    return " ".join(word)


class ModeBanner(ModelView):
    """Three rows: blank, the spaced-out mode name (with the link state when it matters), blank; in the compact
    layout the name's row alone."""

    TIME_DEPENDENT = False

    def render_model(self, model: Model, now: float) -> RenderableType:
        mode = model.mode
        mode_r = self.read(model, "mode", now)
        flags_r = self.read(model, "flags", now, figure=False)
        flags = model.flags if flags_r.fresh else Flag(0)  # ARMED, LOW BATTERY: only while the board says so
        if model.version_mismatch is not None:
            text, style = "WRONG PROTOCOL VERSION", "bold white on red"
        elif mode is None:
            text, style = "NO BOARD", "bold white on grey37"
        else:
            name = mode_name(mode)
            text = f"!!!  {spaced(name)}  !!!" if mode == Mode.PANIC else spaced(name)
            style = STYLE.get(mode, "bold")  # type: ignore[call-overload]
            extra = []
            if mode != Mode.PANIC and flags & Flag.ARMED and mode == Mode.SAFE:
                extra.append("ARMED")
            if flags & Flag.LOW_BATTERY:
                extra.append("LOW BATTERY")
            if extra:
                text += "   " + " · ".join(extra)
        lost = model.control_lost
        if lost and model.radio_name and model.over_ble:
            text += "   ·   BLE LINK LOST"
        elif lost:
            text += "   ·   LINK LOST" + (" (handed over to BLE?)" if model.handed_over and not model.radio_name
                                          else "")
        elif model.radio_name and model.over_ble:
            text += "   ·   over BLE"
        if mode is not None and mode_r.stale:
            text += f"   ·   mode {mode_r.mark}"
        if model.recording_error:  # (the events list says why)
            text += "   ·   NOT RECORDING"
        if lost:
            style = "bold blink white on red" if mode is not None else style
        self.set_class(mode == Mode.PANIC or lost, "alarm")
        lag = sim_lag_text(model, now)
        if lag:  # gone again SIM_LAG_SHOWN_S after the simulator last said it
            self._expires = min(self._expires, model.event_times[EventCode.SIM_LAG] + SIM_LAG_SHOWN_S + 0.01)
        if not lag and model.live_url:  # who can see the flight, while they can
            lag = f"serving live to Foxglove: {model.live_url}"
        width = max(self.size.width, len(text) + 4, len(lag) + 4)
        blank = Text(" " * width, style=style)
        line = Text(text.center(width), style=style)
        if 0 < self.size.height < 3:  # the compact layout: the mode's own row (the lag note would hide it)
            return line
        out = Text()
        out.append_text(blank)
        out.append("\n")
        out.append_text(line)
        out.append("\n")
        out.append_text(Text(lag.center(width), style=style) if lag else blank)
        return out
