"""Live plots of chosen telemetry series (textual-plotext), the last ``window`` seconds."""

from __future__ import annotations

from textual_plotext import PlotextPlot

from term.config import PLOT_SERIES
from term.model import Model


class LivePlot(PlotextPlot):
    """One plot of several series sharing a unit; redrawn at most ``max_rate`` times per second (plotext is the
    costliest thing on screen)."""

    def __init__(self, series: tuple[str, ...], window: float = 10.0, max_rate: float = 5.0,
                 **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.series = series
        self.window = window
        self._interval = 1.0 / max_rate
        self._last = -1e9
        self._shown_version = -1

    def show(self, model: Model, now: float) -> None:
        if now - self._last < self._interval or model.version == self._shown_version:
            return
        self._last = now
        self._shown_version = model.version
        plt = self.plt
        plt.clear_data()
        plt.clear_figure()
        units = {PLOT_SERIES[s][1] for s in self.series}
        plt.title(" · ".join(PLOT_SERIES[s][0] for s in self.series))
        plt.xlabel("s")
        if len(units) == 1:
            plt.ylabel(units.pop())
        plt.xlim(-self.window, 0)
        for name in self.series:
            xs, ys = model.series(name, self.window, now)
            if xs:
                plt.plot(xs, ys, label=PLOT_SERIES[name][0])
        self.refresh()
