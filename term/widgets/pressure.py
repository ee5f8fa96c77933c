"""The pressure indicator: pressure and temperature, estimated height and its set point, vertical speed."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.model import Model
from term.protocol import Flag, Mode, scaled
from term.widgets.bars import cbar, hbar
from term.widgets.base import ModelView

HEIGHT_SPAN_M = 3.0
VZ_SPAN = 2.0


class PressureIndicator(ModelView):
    MAX_HZ = 5.0  # the barometer's figures are noisy; 5 Hz is readable, every frame is not

    def urgent(self, model: Model) -> object:
        return model.mode == Mode.HEIGHT

    def render_model(self, model: Model, now: float) -> RenderableType:
        h = model.height
        out = Text()
        if h is None:
            out.append("pressure  —\nheight    —\nvz        —")
            return out
        width = max(8, (self.content_size.width or 40) - 20)
        height_m, sp_m, vz = scaled(h, "height"), scaled(h, "setpoint"), scaled(h, "vz")
        out.append(f"pressure {h.pressure:7d} Pa  {scaled(h, 'temperature'):5.1f} °C\n")
        out.append("height   ")
        out.append_text(hbar(max(0.0, height_m), 0.0, HEIGHT_SPAN_M, width, "cyan"))
        out.append(f" {height_m:+6.2f} m\n")
        hold = model.mode == Mode.HEIGHT or bool(model.flags & Flag.HEIGHT_HOLD)
        out.append("set pt   ")
        if hold:
            out.append_text(hbar(max(0.0, sp_m), 0.0, HEIGHT_SPAN_M, width, "magenta"))
            out.append(f" {sp_m:+6.2f} m\n")
        else:
            out.append("(HEIGHT mode)".ljust(width)[:width], style="dim")
            out.append(f" {sp_m:+6.2f} m\n", style="dim")
        arrow = "↑" if vz > 0.05 else "↓" if vz < -0.05 else "·"
        out.append("vz       ")
        out.append_text(cbar(vz, VZ_SPAN, (width - 2) | 1, "cyan"))
        out.append(f" {vz:+5.2f}m/s{arrow}")
        return out
