"""Body-rate gauges: p, q, r in °/s, bars centred on zero."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.model import GYRO_LSB_PER_DPS, Model
from term.widgets.bars import cbar
from term.widgets.base import ModelView

SPAN_DPS = 200.0


class RateGauges(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        a = model.attitude
        width = max(9, ((self.content_size.width or 40) - 21) | 1)
        out = Text()
        for i, (name, raw) in enumerate((("p roll ", a.sp if a else 0), ("q pitch", a.sq if a else 0),
                                         ("r yaw  ", a.sr if a else 0))):
            dps = raw / GYRO_LSB_PER_DPS
            out.append(f"{name} ")
            out.append_text(cbar(dps, SPAN_DPS, width))
            out.append(f" {dps:+6.0f}°/s" if a else "     —   ")
            if i < 2:
                out.append("\n")
        return out
