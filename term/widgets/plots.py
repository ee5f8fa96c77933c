"""Live plots of chosen telemetry series (textual-plotext), the last ``window`` seconds.

Drawing a plot is the costliest thing on screen (plotext builds the whole canvas, then ANSI is parsed back into
styled text), so it happens at most ``max_rate`` times per second, on a worker thread, from a copy of the data:
the event loop, which answers heartbeats and forwards keys, never waits for a plot.
"""

from __future__ import annotations

import asyncio
import time

from rich.console import RenderableType
from rich.text import Text
from textual_plotext import PlotextPlot

from term.config import PLOT_SERIES
from term.model import Model


class LivePlot(PlotextPlot):
    """One plot of several series sharing a unit."""

    def __init__(self, series: tuple[str, ...], window: float = 10.0, max_rate: float = 1.0,
                 **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.series = series
        self.window = window
        self._interval = 1.0 / max_rate
        self._last = -1e9
        self._shown_version = -1
        self._text: Text = Text("")
        self._busy = False

    def on_resize(self) -> None:
        self._shown_version = -1  # draw again at the new size

    def show(self, model: Model, now: float) -> None:
        wall = time.monotonic()  # the rate limit is about CPU: wall time, whatever clock the model runs on
        if self._busy or not self.size.area or wall - self._last < self._interval:
            return
        if model.version == self._shown_version:
            return
        self._last = wall
        self._shown_version = model.version
        points = max(50, 2 * (self.size.width or 100))  # braille: 2 dots per column; more is invisible work
        data = []
        for name in self.series:
            xs, ys = model.series(name, self.window, now)
            if len(xs) > points:
                step = len(xs) / points
                idx = [int(i * step) for i in range(points)] + [len(xs) - 1]
                xs, ys = [xs[i] for i in idx], [ys[i] for i in idx]
            data.append((name, xs, ys))
        self._busy = True
        self.run_worker(self._draw(data, self.size.width, self.size.height), exclusive=True, group="plot")

    async def _draw(self, data: list[tuple[str, list[float], list[float]]], width: int, height: int) -> None:
        try:
            self._text = await asyncio.to_thread(self._build, data, width, height)
            self.refresh()
        finally:
            self._busy = False

    def _build(self, data: list[tuple[str, list[float], list[float]]], width: int, height: int) -> Text:
        plt = self.plt
        plt.clear_data()
        plt.clear_figure()
        plt.plotsize(width, height)
        plt._set_size(width, height)  # as PlotextPlot.render does (textual-plotext issue 5)
        plt.theme(self._get_plotext_theme_name(self.app.theme))
        units = {PLOT_SERIES[s][1] for s in self.series}
        plt.title(" · ".join(PLOT_SERIES[s][0] for s in self.series))
        plt.xlabel("s")
        if len(units) == 1:
            plt.ylabel(units.pop())
        plt.xlim(-self.window, 0)
        for name, xs, ys in data:
            if xs:
                plt.plot(xs, ys, label=PLOT_SERIES[name][0])
        return Text.from_ansi(plt.build())

    def render(self) -> RenderableType:
        return self._text
