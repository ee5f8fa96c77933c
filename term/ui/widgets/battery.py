"""Battery gauge with its thresholds (term.core.protocol's): the board PANICs under the low threshold while flying;
under
the nominal voltage it is time to land."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.session.model import Model
from term.session.texts import BATTERY_FULL_V, BATTERY_PANIC_V, BATTERY_WARN_V, battery_level
from term.ui.widgets.bars import hbar
from term.ui.widgets.base import STALE_STYLE, ModelView, figure

LOW_END_V = 10.0


LEVEL_STYLE = {"panic": "bold red", "warn": "yellow", "ok": "green"}


def battery_style(volts: float) -> str:
    return LEVEL_STYLE[battery_level(volts)]


def threshold_ruler(width: int) -> Text:
    """Marks under the bar where the thresholds sit."""
    cells = [" "] * width
    for v, mark in ((BATTERY_PANIC_V, "▲"), (BATTERY_WARN_V, "△")):
        col = round((v - LOW_END_V) / (BATTERY_FULL_V - LOW_END_V) * width)
        if 0 <= col < width:
            cells[col] = mark
    return Text("".join(cells), style="dim")


class BatteryGauge(ModelView):
    MAX_HZ = 2.0  # a battery changes slowly; its noise would repaint the gauge every frame

    def urgent(self, model: Model) -> object:
        v = model.battery_v
        return None if v is None else battery_style(v)  # crossing a threshold shows at once

    def render_model(self, model: Model, now: float) -> RenderableType:
        r = self.read(model, "battery", now)
        self.mark(r)
        width = max(10, (self.content_size.width or 30) - 10)
        out = Text()
        if not r.shown or r.value is None:
            out.append("battery  —")
            return out
        v = r.value
        style = STALE_STYLE if r.stale else battery_style(v)
        out.append_text(hbar(v, LOW_END_V, BATTERY_FULL_V, width, style))
        out.append_text(figure(r, "5.2f", " V", style, pad=" "))
        out.append("\n")
        out.append_text(threshold_ruler(width))
        out.append("\n")
        if v < BATTERY_PANIC_V:
            out.append(f"BELOW {BATTERY_PANIC_V:g} V: land now", style="bold red")
        elif v < BATTERY_WARN_V:
            out.append(f"under {BATTERY_WARN_V:g} V: time to land", style="yellow")
        else:
            out.append(f"▲ {BATTERY_PANIC_V:g} V panic  △ {BATTERY_WARN_V:g} V land", style="dim")
        return out
