"""The plots screen (F8): live plots of telemetry series, drawn natively in braille dots (term/ui/widgets/braille.py).

Contract:
- ``LivePlot`` draws the series it is given (those of one unit share a plot) over the view's time window, from the
  model's histories (``Model.history``: time since the session's start, value in the shown unit). The app's render
  tick calls ``show(model, now)``; a plot redraws when the model changed or time moved by a dot column, at most
  ``MAX_HZ`` times a second, on the event loop. ``python -m bench.plots`` measures a redraw of the default screen's
  two plots (120 columns, 10 s at 50 Hz) at 1.2 to 1.7 ms of CPU, the textual-plotext widget it replaced at 10 to
  13 ms (which is why that one was held to 1 Hz on a worker thread); ``bench.ui`` in the app (``plot_redraw_ms``).
  The strips are built once per redraw and handed out line by line (Textual's line API).
- ``PlotView`` is the screen's state, shared by its plots: the window (zoomed in steps ``ZOOM_STEPS`` within the
  config's limits), paused or live. Pausing keeps a copy of every history (all series, so the chooser still works)
  and the moment of the pause; ``,``/``.`` pan a paused view by half a window; resuming shows live data again.
- ``PlotsScreen`` keys (screen bindings, under the pilot's keys): ``p`` pause/live, ``]`` zoom in, ``[`` zoom out
  (the mouse wheel on a plot too), ``,`` ``.`` back and on, ``s`` the series chooser: a list of every series
  (``term.session.config.PLOT_SERIES``); the chosen ones replace the plots at once. While the list has focus up and down
  move in it (it claims those keys: ``CLAIMED_KEYS``, which the app leaves to it; PANIC, SAFE and lift down are
  never claimed). Widgets here post messages up and never call the app.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from rich.segment import Segment
from rich.style import Style
from textual.events import MouseScrollDown, MouseScrollUp
from textual.message import Message
from textual.strip import Strip
from textual.widget import Widget

from term.session.config import PLOT_SERIES, PLOT_WINDOW
from term.session.model import Model
from term.ui.widgets.braille import Canvas, nice_range, window_of

ZOOM_STEPS = (1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0)  # s; the model keeps 60 s of each series at 50 Hz
MAX_HZ = 12.5  # redraws a second per plot at most: every render tick (12 Hz), a faster tick held to this
GAP_S = 0.5  # samples further apart are not joined (a silent link leaves a hole)
COLORS = ("bright_cyan", "bright_magenta", "bright_yellow", "bright_green", "bright_red", "bright_blue")
_STYLES = [Style()] + [Style(color=c) for c in COLORS]
_DIM = Style(dim=True)
_PAUSED = Style(bold=True, reverse=True)


def _clock(t: float) -> str:
    """Session time as the events list writes it (mm:ss)."""
    m, s = divmod(max(0.0, t), 60)
    return f"{int(m):02d}:{int(s):02d}"


@dataclass
class PlotView:
    """What the plots show: the window, and live or paused (a copy of the histories and the pause's moment)."""

    window: float = 10.0
    paused: bool = False
    end: float = 0.0  # paused: the right edge, s since the session's start
    paused_at: float = 0.0
    snapshot: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    generation: int = 0  # changes on every change of the view: the plots redraw
    model: Model | None = None  # the last model shown (the render tick's), and its time
    now: float = 0.0

    def zoom(self, steps: int) -> None:
        """``steps`` < 0 zooms in (a shorter window), > 0 out, through ZOOM_STEPS within the config's limits."""
        if steps < 0:
            w = max((s for s in ZOOM_STEPS if s < self.window - 1e-9), default=ZOOM_STEPS[0])
        else:
            w = min((s for s in ZOOM_STEPS if s > self.window + 1e-9), default=ZOOM_STEPS[-1])
        w = min(max(w, PLOT_WINDOW.lo), PLOT_WINDOW.hi)
        if w != self.window:
            self.window = w
            self._clamp()
            self.generation += 1

    def toggle_pause(self) -> None:
        if self.paused:
            self.paused, self.snapshot = False, {}
        elif self.model is not None:
            self.paused = True
            self.paused_at = self.end = self.now - self.model.start
            self.snapshot = {name: list(d) for name, d in self.model.history.items()}
        self.generation += 1

    def pan(self, direction: int) -> None:
        """Half a window back (-1) or on (+1); pauses a live view first."""
        if not self.paused:
            self.toggle_pause()
            if not self.paused:
                return  # nothing shown yet
        self.end += direction * self.window / 2
        self._clamp()
        self.generation += 1

    def _clamp(self) -> None:
        if not self.paused:
            return
        first = min((s[0][0] for s in self.snapshot.values() if s), default=self.paused_at)
        self.end = min(max(self.end, min(first + self.window, self.paused_at)), self.paused_at)

    def data(self, name: str) -> Sequence[tuple[float, float]]:
        if self.paused:
            return self.snapshot.get(name, ())
        if self.model is None:
            return ()
        return self.model.history.get(name, ())


class LivePlot(Widget):
    """One plot of the series that share a unit, drawn in braille from the view's data."""

    DEFAULT_CSS = "LivePlot { height: 1fr; }"

    class Zoom(Message):
        """The mouse wheel on a plot: zoom all plots by ``steps`` (< 0 in)."""

        def __init__(self, steps: int) -> None:
            super().__init__()
            self.steps = steps

    def __init__(self, series: tuple[str, ...], view: PlotView, *, id: str | None = None,  # noqa: A002
                 classes: str | None = None) -> None:
        super().__init__(id=id, classes=classes)
        self.series = series
        self.view = view
        self._strips: list[Strip] = []
        self._key: object = None
        self._painted = -1e9
        self.text = ""  # the last frame as plain text (tests and the bench read it)

    def show(self, model: Model, now: float) -> None:
        view = self.view
        view.model, view.now = model, now
        width, height = self.content_size
        if not width or not height:
            return
        if view.paused:
            key: object = (view.generation, width, height)
        else:
            wall = time.monotonic()  # a CPU budget: wall time, whatever clock the model runs on
            if wall - self._painted < 1.0 / MAX_HZ:
                return
            column = view.window / max(1, 2 * width)  # time moved by a dot column: the lines move
            key = (model.version, int((now - model.start) / column), view.generation, width, height)
        if key == self._key:
            return
        self._key = key
        self._painted = time.monotonic()
        end = view.end if view.paused else now - model.start
        self._strips = self.draw([(s, view.data(s)) for s in self.series], end, width, height)
        self.refresh()

    def draw(self, data: list[tuple[str, Sequence[tuple[float, float]]]], end: float, width: int,
             height: int) -> list[Strip]:
        """The plot of ``data`` (name, samples) over ``[end - window, end]`` as ``height`` strips of ``width``."""
        view = self.view
        lo_t = end - view.window
        windows = [(name, *window_of(samples, lo_t, end)) for name, samples in data]
        state = f"⏸ paused {_clock(view.paused_at)} " if view.paused else ""
        chart_h = height - 2
        shown = [v for _n, _ts, vs in windows for v in vs if math.isfinite(v)]
        y_lo, y_hi, step = nice_range(min(shown, default=-1.0), max(shown, default=1.0),
                                      max(1, min(4, chart_h // 2)))
        digits = _decimals(step)
        legend: list[tuple[str, Style]] = []
        for i, (name, _ts, vs) in enumerate(windows):
            label, unit = PLOT_SERIES[name]
            last = next((v for v in reversed(vs) if math.isfinite(v)), None)
            value = f" {last:+.{digits + 1}f}{unit}" if last is not None else " —"
            legend.append((f"━ {label}{value}  ", _STYLES[1 + i % len(COLORS)]))
        if height < 3 or width < 20:  # room for the legend only
            strips = [_strip(legend, width)] + [Strip.blank(width)] * (height - 1)
            self.text = "\n".join(s.text for s in strips)
            return strips
        ticks = [round(y_lo + k * step, 9) + 0.0 for k in range(round((y_hi - y_lo) / step) + 1)]  # no -0
        labels = [f"{t:.{digits}f}" for t in ticks]
        gutter = max(len(s) for s in labels) + 1
        canvas = Canvas(width - gutter, chart_h)
        for i, (_n, ts, vs) in enumerate(windows):
            canvas.plot(ts, vs, 1 + i % len(COLORS), (lo_t, end), (y_lo, y_hi), GAP_S)
        tick_rows: dict[int, str] = {}
        dots = 4 * chart_h - 1
        for t, s in zip(ticks, labels, strict=True):
            tick_rows.setdefault(round((y_hi - t) / (y_hi - y_lo) * dots) >> 2, s)
        strips = [_strip(legend + [(state, _PAUSED), (f"{view.window:g} s", _DIM)], width)]
        for r, runs in enumerate(canvas.rows()):
            mark = tick_rows.get(r)
            axis = (mark.rjust(gutter - 1) + "┤") if mark is not None else " " * (gutter - 1) + "│"
            strips.append(_strip([(axis, _DIM)] + [(text, _STYLES[c]) for text, c in runs], width))
        strips.append(_strip([(" " * gutter + _x_axis(view, end, canvas.width), _DIM)], width))
        self.text = "\n".join(s.text for s in strips)
        return strips

    def render_line(self, y: int) -> Strip:
        if y < len(self._strips):
            return self._strips[y]
        return Strip.blank(self.content_size.width)

    def on_resize(self) -> None:
        self._key = None  # draw again at the new size, at the next tick

    def _on_mouse_scroll_up(self, event: MouseScrollUp) -> None:
        event.stop()
        self.post_message(self.Zoom(-1))

    def _on_mouse_scroll_down(self, event: MouseScrollDown) -> None:
        event.stop()
        self.post_message(self.Zoom(+1))


def _decimals(x: float) -> int:
    """Decimals that show a step ``x`` (or a value of that size) without noise: 0 for 5, 1 for 2.5 or 0.5."""
    x = abs(x)
    if x == 0 or x >= 10:
        return 0
    for d in range(4):
        if abs(x * 10**d - round(x * 10**d)) < 1e-6 * 10**d:
            return d
    return 3 if x < 1 else 1


def _strip(runs: list[tuple[str, Style]], width: int) -> Strip:
    return Strip([Segment(text, style) for text, style in runs if text]).crop_extend(0, width, None)


def _x_axis(view: PlotView, end: float, width: int) -> str:
    """Time labels under the chart: seconds back from now when live, session time (mm:ss) when paused."""
    start, mid = end - view.window, end - view.window / 2
    if view.paused:
        left, middle, right = _clock(start), _clock(mid), _clock(end)
    else:
        left, middle, right = f"-{view.window:g} s", f"-{view.window / 2:g}", "now"
    line = [" "] * width
    for text, at in ((left, 0), (middle, (width - len(middle)) // 2), (right, width - len(right))):
        if 0 <= at and at + len(text) <= width and all(c == " " for c in line[max(0, at - 1):at + len(text) + 1]):
            line[at:at + len(text)] = text
    return "".join(line)


def group_by_unit(series: Sequence[str]) -> list[tuple[str, ...]]:
    """Series that share a unit share a plot, in the order first named."""
    by_unit: dict[str, list[str]] = {}
    for s in series:
        by_unit.setdefault(PLOT_SERIES[s][1], []).append(s)
    return [tuple(g) for g in by_unit.values()]
