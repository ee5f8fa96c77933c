"""Body-rate gauges: p, q, r in °/s, bars centred on zero."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.session.model import Model
from term.ui.widgets.bars import cbar
from term.ui.widgets.base import STALE_STYLE, ModelView, figure

SPAN_DPS = 200.0


class RateGauges(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        width = max(9, ((self.content_size.width or 40) - 21) | 1)
        out = Text()
        readings = []
        for i, (name, field) in enumerate((("p roll ", "sp"), ("q pitch", "sq"), ("r yaw  ", "sr"))):
            r = self.read(model, field, now)
            readings.append(r)
            dps = r.value if r.shown and r.value is not None else 0.0
            out.append(f"{name} ")
            out.append_text(cbar(dps, SPAN_DPS, width, STALE_STYLE if r.stale else "cyan"))
            out.append(" ")
            out.append_text(figure(r, "+6.0f", "°/s"))
            if i < 2:
                out.append("\n")
        self.mark(*readings)
        return out
