"""The errors and events list: every NAK with its reason, every board event, every link error, with times."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.session.eventlog import LogEntry
from term.session.model import Model
from term.ui.widgets.base import ModelView

STYLE = {"error": "bold red", "warning": "yellow", "info": ""}


def entry_text(e: LogEntry) -> Text:
    m, s = divmod(e.t, 60)
    t = Text(f"{int(m):02d}:{s:06.3f} ", style="dim")
    t.append(f"{e.source:<8}", style="dim")
    t.append(e.text, style=STYLE.get(e.severity, ""))
    if e.count > 1:
        t.append(f"  ×{e.count}", style="bold")
    return t


class EventsList(ModelView):
    """The newest entries that fit, newest at the bottom (the order they happened)."""

    def render_model(self, model: Model, now: float) -> RenderableType:
        rows = max(1, self.content_size.height or 8)
        width = self.content_size.width
        entries: list[LogEntry] = []
        used = 0
        for e in reversed(model.events):  # newest first, until the wrapped lines fill the panel
            lines = len(entry_text(e).wrap(self.app.console, width)) if width > 0 else 1
            if entries and used + lines > rows:
                break
            entries.append(e)
            used += lines
            if used >= rows:
                break
        entries.reverse()
        out = Text()
        if not entries:
            out.append("no events yet", style="dim")
        for i, e in enumerate(entries):
            if i:
                out.append("\n")
            out.append_text(entry_text(e))
        return out
