"""Body-rate gauges: p, q, r in °/s, bars centred on zero."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.model import Model
from term.protocol import scaled
from term.widgets.bars import cbar
from term.widgets.base import ModelView

SPAN_DPS = 200.0


class RateGauges(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        a = model.attitude
        width = max(9, ((self.content_size.width or 40) - 21) | 1)
        out = Text()
        for i, (name, field) in enumerate((("p roll ", "sp"), ("q pitch", "sq"), ("r yaw  ", "sr"))):
            dps = scaled(a, field) if a else 0.0
            out.append(f"{name} ")
            out.append_text(cbar(dps, SPAN_DPS, width))
            out.append(f" {dps:+6.0f}°/s" if a else "     —   ")
            if i < 2:
                out.append("\n")
        return out
