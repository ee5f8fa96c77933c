"""Motor bars ae1..ae4 (0..1000; about 400 hovers), in the plus frame's order: front, right, back, left."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.model import Model
from term.widgets.bars import hbar
from term.widgets.base import ModelView

NAMES = ("ae1 front", "ae2 right", "ae3 back ", "ae4 left ")


class MotorBars(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        m = model.motion
        values = (m.ae1, m.ae2, m.ae3, m.ae4) if m else (0, 0, 0, 0)
        width = max(5, (self.content_size.width or 40) - 16)
        out = Text()
        for i, (name, v) in enumerate(zip(NAMES, values, strict=True)):
            style = "red" if v >= 950 else "green" if v > 0 else "dim"
            out.append(f"{name} ")
            out.append_text(hbar(v, 0, 1000, width, style))
            out.append(f" {v:4d}" if m else "    —")
            if i < 3:
                out.append("\n")
        return out
