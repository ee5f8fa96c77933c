"""Text bars for gauges, pure functions of numbers (testable without a screen)."""

from __future__ import annotations

from rich.text import Text

_EIGHTHS = " ▏▎▍▌▋▊▉█"


def hbar(value: float, lo: float, hi: float, width: int, style: str = "green") -> Text:
    """A left-anchored bar with eighth-cell resolution."""
    width = max(1, width)
    frac = 0.0 if hi <= lo else min(1.0, max(0.0, (value - lo) / (hi - lo)))
    eighths = round(frac * width * 8)
    full, part = divmod(eighths, 8)
    s = "█" * full + (_EIGHTHS[part] if part and full < width else "")
    return Text(s.ljust(width), style=style)


def cbar(value: float, span: float, width: int, style: str = "cyan") -> Text:
    """A bar centred on zero, ``span`` at either end; clipping is shown with an arrow at the end."""
    width = max(3, width | 1)
    half = width // 2
    frac = 0.0 if span <= 0 else max(-1.0, min(1.0, value / span))
    n = round(abs(frac) * half)
    cells = ["·"] * width
    cells[half] = "│"
    if value >= 0:
        for i in range(half + 1, half + 1 + n):
            cells[i] = "█"
    else:
        for i in range(half - n, half):
            cells[i] = "█"
    if span > 0 and abs(value) > span:
        cells[-1 if value > 0 else 0] = "▶" if value > 0 else "◀"
    # One span per run of a style, not per cell: Textual's cost of drawing a line grows with its spans.
    out = Text()
    run, run_style = "", ""
    for c in cells:
        cell_style = style if c in "█▶◀" else "dim"
        if cell_style != run_style and run:
            out.append(run, style=run_style)
            run = ""
        run, run_style = run + c, cell_style
    out.append(run, style=run_style)
    return out
