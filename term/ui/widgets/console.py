"""The console: the board's text lines (printed between frames, and its Text packets), newest at the bottom, with
times, where each came from, the level's colour, and how many lines the rate limit dropped."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.core.console import ConsoleLine
from term.session.model import Model
from term.ui.widgets.base import ModelView

LEVEL_STYLE = {1: "dim", 2: "", 3: "yellow", 4: "bold red", 5: "bold white on red"}
LEVEL_MARK = {1: "D", 2: " ", 3: "W", 4: "E", 5: "F"}


def line_text(t: float, line: ConsoleLine) -> Text:
    """One console line: time, source, level mark, the text (never markup: a board's text is shown as it is)."""
    m, s = divmod(t, 60)
    out = Text(f"{int(m):02d}:{s:06.3f} ", style="dim")
    out.append(f"{line.source:<6}{LEVEL_MARK.get(line.level, ' ')} ", style="dim")
    if line.dropped:
        out.append(f"[{line.dropped} dropped] ", style="yellow")
    out.append(line.text, style=LEVEL_STYLE.get(line.level, ""))
    if line.cut:
        out.append(" …", style="dim")
    return out


class ConsoleView(ModelView):
    """The newest lines that fit, newest at the bottom; the first row counts lines and drops."""

    def render_model(self, model: Model, now: float) -> RenderableType:
        rows = max(1, (self.content_size.height or 12) - 1)
        lines = list(model.console)[-rows:]
        n = len(model.console)
        head = Text(f"{n} line{'' if n == 1 else 's'}", style="dim")
        if model.console_dropped:
            head.append(f" · {model.console_dropped} dropped by the rate limit", style="yellow")
        head.append(" · printf on the UART and qb_log lines; errors also go to the events list", style="dim")
        out = Text()
        out.append_text(head)
        if not lines:
            out.append("\nnothing from the board yet", style="dim")
        for t, line in lines:
            out.append("\n")
            out.append_text(line_text(t, line))
        return out
