"""Motor bars ae1..ae4 (0..1000; about 400 hovers), in the plus frame's order: front, right, back, left."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.session.model import Model
from term.ui.widgets.bars import hbar
from term.ui.widgets.base import STALE_STYLE, ModelView, figure

NAMES = ("ae1 front", "ae2 right", "ae3 back ", "ae4 left ")


class MotorBars(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        readings = [self.read(model, f"ae{i}", now) for i in range(1, 5)]
        width = max(5, (self.content_size.width or 40) - 16)
        out = Text()
        for i, (name, r) in enumerate(zip(NAMES, readings, strict=True)):
            v = r.value if r.shown and r.value is not None else 0
            style = STALE_STYLE if r.stale else "red" if v >= 950 else "green" if v > 0 else "dim"
            out.append(f"{name} ")
            out.append_text(hbar(v, 0, 1000, width, style))
            out.append(" ")
            out.append_text(figure(r, "4d"))
            if i < 3:
                out.append("\n")
        self.mark(*readings)
        return out
