"""A line chart in braille dots, as plain data: series in, rows of (text, colour) runs out. No Textual, no clock.

A terminal cell holds 2 × 4 dots (Unicode braille, U+2800..U+28FF), so a chart of ``width`` × ``height`` cells is
a canvas of ``2 width`` × ``4 height`` dots. Each sample is placed by its time (x) and value (y) and joined to the
previous one by a straight run of dots: every sample is drawn, none decimated away, so a one-sample spike shows as
a line to its peak (a dot column holding many samples draws their whole span, as an oscilloscope does). Two samples
further apart in time than ``gap`` (the link was silent) are not joined: a hole shows a hole. Values that are no
finite number are holes too; values outside the y range are clipped at its edges.

Where the lines of two series share a cell the cell takes the colour of the later series (a cell has one colour).

``nice_range`` picks the y range and its tick step (1, 2, 2.5 or 5 times a power of ten, the finest that gives at
most ``ticks + 1`` steps) so the axis reads in round numbers and does not jitter with every new sample.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence

# The bit of each dot in a braille cell, by [dot row][dot column] (Unicode's numbering: 1-2-3-7 left, 4-5-6-8 right).
_BITS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))
BLANK = 0x2800


def nice_range(lo: float, hi: float, ticks: int = 4) -> tuple[float, float, float]:
    """(low, high, step): ``lo..hi`` widened to whole steps, at most ``ticks + 1`` of them. A flat or empty range
    gets a span around its value."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        lo, hi = -1.0, 1.0
    if hi - lo < 1e-9 * max(1.0, abs(lo), abs(hi)):
        pad = max(1.0, abs(hi) * 0.1) if hi else 1.0
        lo, hi = lo - pad, hi + pad
    ticks = max(1, ticks)
    mag = 10.0 ** math.floor(math.log10((hi - lo) / ticks))
    for step in (m * mag * k for k in (0.1, 1.0, 10.0, 100.0) for m in (1.0, 2.0, 2.5, 5.0)):
        a, b = math.floor(lo / step + 1e-9) * step, math.ceil(hi / step - 1e-9) * step
        if (b - a) / step <= ticks + 1 + 1e-9:  # the finest step that gives at most ticks + 1 of them
            return a, b, step
    return lo, hi, hi - lo


# _SPAN[column][first][last]: the bits of dot rows first..last (0..3) of one dot column of a cell.
_SPAN = tuple(tuple(tuple(sum(_BITS[r][c] for r in range(a, b + 1)) for b in range(4)) for a in range(4))
              for c in range(2))
_CHARS = tuple(" " if m == 0 else chr(BLANK + m) for m in range(256))
_RUN = re.compile(rb"(.)\1*", re.S)


class Canvas:
    """``width`` × ``height`` cells of braille dots, each cell with the colour (1, 2, ...) of the series that drew
    there last; 0 is blank."""

    def __init__(self, width: int, height: int) -> None:
        self.width = max(1, width)
        self.height = max(1, height)
        self.mask = bytearray(self.width * self.height)
        self.color = bytearray(self.width * self.height)

    def _span(self, x: int, y0: int, y1: int, color: int) -> None:
        """Dot column ``x`` from dot row ``y0`` to ``y1`` (inclusive, either order), a cell at a time."""
        if y0 > y1:
            y0, y1 = y1, y0
        mask, colors, span = self.mask, self.color, _SPAN[x & 1]
        cell = (y0 >> 2) * self.width + (x >> 1)
        for r in range(y0 >> 2, (y1 >> 2) + 1):
            a = y0 - 4 * r if y0 > 4 * r else 0
            b = y1 - 4 * r if y1 < 4 * r + 3 else 3
            mask[cell] |= span[a][b]
            colors[cell] = color
            cell += self.width

    def plot(self, ts: Iterable[float], vs: Iterable[float], color: int, x_range: tuple[float, float],
             y_range: tuple[float, float], gap: float = math.inf) -> None:
        """Draw one series (times ``ts``, increasing, and values ``vs``) in ``color`` (1..255). Samples outside
        ``x_range`` are drawn only as the line toward the first or from the last inside."""
        x0, x1 = x_range
        y0, y1 = y_range
        dots_w, dots_h = 2 * self.width, 4 * self.height
        if not x1 > x0 or not y1 > y0:
            return
        sx = (dots_w - 1) / (x1 - x0)
        sy = (dots_h - 1) / (y1 - y0)
        top = dots_h - 1
        span = self._span
        px = py = 0
        pt = -math.inf
        have = False
        for t, v in zip(ts, vs, strict=False):
            if not math.isfinite(v):
                have = False
                continue
            x = round((t - x0) * sx)
            y = round((y1 - v) * sy)
            y = 0 if y < 0 else top if y > top else y
            if not (have and t - pt <= gap):
                if 0 <= x < dots_w:
                    span(x, y, y, color)
            elif x == px:  # the same dot column: the span between the two (dense data, a spike)
                if 0 <= x < dots_w and y != py:
                    span(x, py, y, color)
            else:  # a line to the next column(s): each column gets the rows the line crosses in it
                dx, dy = x - px, y - py
                step = 1 if dx > 0 else -1
                prev = py
                for c in range(px + step, x + step, step):
                    yc = py + (dy * (c - px) * 2 + dx) // (2 * dx) if c != x else y  # rounded, exact at the end
                    if 0 <= c < dots_w:
                        span(c, yc if abs(yc - prev) <= 1 else prev + (1 if yc > prev else -1), yc, color)
                    prev = yc
            px, py, pt, have = x, y, t, True

    def rows(self) -> list[list[tuple[str, int]]]:
        """Each row of cells as runs of (text, colour); a blank cell is a space of colour 0."""
        out: list[list[tuple[str, int]]] = []
        w = self.width
        mask, colors = self.mask, bytes(self.color)
        for r in range(self.height):
            a = r * w
            text = "".join(map(_CHARS.__getitem__, mask[a:a + w]))
            out.append([(text[m.start() - a:m.end() - a], m.group()[0]) for m in _RUN.finditer(colors, a, a + w)])
        return out


def window_of(samples: Sequence[tuple[float, float]], lo: float, hi: float) -> tuple[list[float], list[float]]:
    """The samples (t, v) of a time-ordered sequence (a list or a deque) with lo <= t <= hi, plus the one just
    outside at each end (so the line runs to the chart's edges), as (times, values). Read from the newest end: a
    live chart reads only the tail of a long history."""
    ts: list[float] = []
    vs: list[float] = []
    after: tuple[float, float] | None = None
    for t, v in reversed(samples):
        if t > hi:
            after = (t, v)
            continue
        ts.append(t)
        vs.append(v)
        if t < lo:
            break  # the one before the window
    ts.reverse()
    vs.reverse()
    if after is not None:
        ts.append(after[0])
        vs.append(after[1])
    return ts, vs
