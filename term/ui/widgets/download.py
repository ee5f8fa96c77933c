"""Log download progress: a bar with the fraction, kB/s and where the CSV goes; the outcome's line for
``STATUS_LINE_S`` (the events list keeps it)."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.session.model import Model
from term.ui.widgets.bars import hbar
from term.ui.widgets.base import STATUS_LINE_S, ModelView


class DownloadPanel(ModelView):
    TIME_DEPENDENT = True

    def render_model(self, model: Model, now: float) -> RenderableType:
        d = model.download
        out = Text()
        said = model.download_note_at
        note = model.download_note if said is None or now - said < STATUS_LINE_S else ""  # the events list keeps it
        self.display = d is not None or bool(note)
        if d is None:
            out.append(note)
            return out
        width = max(10, (self.content_size.width or 60) - 40)
        out.append("log download ")
        out.append_text(hbar(d.fraction, 0, 1, width, "cyan"))
        total = f"{d.used / 1000:.1f} kB" if d.used is not None else "? kB"
        out.append(f" {100 * d.fraction:5.1f}% of {total}  {d.rate_kBps(now):5.2f} kB/s")
        return out
