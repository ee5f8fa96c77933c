"""The pressure indicator: pressure and temperature, estimated height and its set point, vertical speed."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.core.freshness import Reading
from term.core.protocol import Flag, Mode
from term.session.model import Model
from term.ui.widgets.bars import cbar, hbar
from term.ui.widgets.base import STALE_STYLE, ModelView, figure

HEIGHT_SPAN_M = 3.0
VZ_SPAN = 2.0


class PressureIndicator(ModelView):
    MAX_HZ = 5.0  # the barometer's figures are noisy; 5 Hz is readable, every frame is not

    def urgent(self, model: Model) -> object:
        return model.mode == Mode.HEIGHT

    def render_model(self, model: Model, now: float) -> RenderableType:
        hold = model.mode == Mode.HEIGHT or bool(model.flags & Flag.HEIGHT_HOLD)
        p, temp, hr, vzr = (self.read(model, n, now) for n in ("pressure", "temperature", "height", "vz"))
        spr = self.read(model, "setpoint", now, figure=hold)  # a figure only while it is in force
        self.mark(p, hr, vzr, temp, *((spr,) if hold else ()))
        out = Text()
        if not (p.known or hr.known):  # over BLE alone the height comes without the pressure (Compact2)
            out.append("pressure  —\nheight    —\nvz        —")
            return out
        width = max(8, (self.content_size.width or 40) - 20)

        def num(r: Reading) -> float:
            return r.value if r.shown and r.value is not None else 0.0

        bar = STALE_STYLE if hr.stale else "cyan"
        out.append("pressure ")
        out.append_text(figure(p, "7d", " Pa"))
        out.append("  ")
        out.append_text(figure(temp, "5.1f", " °C"))
        out.append("\nheight   ")
        out.append_text(hbar(max(0.0, num(hr)), 0.0, HEIGHT_SPAN_M, width, bar))
        out.append(" ")
        out.append_text(figure(hr, "+6.2f", " m"))
        if model.flags & Flag.HEIGHT_UNSURE:  # after a hard stop, until the barometer confirms it
            out.append(" unsure", style="yellow")
        out.append("\nset pt   ")
        if hold:
            sp_bar = STALE_STYLE if spr.stale else "magenta"
            out.append_text(hbar(max(0.0, num(spr)), 0.0, HEIGHT_SPAN_M, width, sp_bar))
            out.append(" ")
            out.append_text(figure(spr, "+6.2f", " m"))
        else:  # not in force: no figure (an old set point read as if it held the craft)
            out.append("— (HEIGHT mode only)".ljust(width + 9)[:width + 9], style="dim")
        vz = num(vzr)
        arrow = "↑" if vz > 0.05 else "↓" if vz < -0.05 else "·"
        out.append("\nvz       ")
        out.append_text(cbar(vz, VZ_SPAN, (width - 2) | 1, STALE_STYLE if vzr.stale else "cyan"))
        out.append(" ")
        out.append_text(figure(vzr, "+5.2f", "m/s"))
        out.append(arrow if vzr.shown else " ")
        return out
