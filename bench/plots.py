"""Redraw cost of the live plots: the native braille widget (term/ui/widgets/plots.py) beside the textual-plotext one
it replaced. Prints one JSON line.

Both widgets sit on a real plots screen (TermApp headless, 120 × 44 cells; the screen's default series: roll,
pitch, yaw on one plot, height on another) over a model holding 60 s of each series at 50 Hz, window 10 s. One
redraw is what each widget does per new frame: from the model's data to the lines Textual composes (the native
widget: ``LivePlot.draw`` to strips; textual-plotext: plotext's canvas, its ANSI text parsed back by Rich, and
Textual's rendering of that text into lines). Figures per redraw of the whole screen (both plots), over
``--redraws`` redraws:

- ``ms_p50``, ``ms_p99``: CPU time of the drawing thread per redraw on this machine (CPU, not wall time: other
  processes on the machine do not count);
- ``cpu_pct_at_10hz``: the share of one core at 10 redraws a second (the native widget's rate; textual-plotext was
  held to one redraw a second on a worker thread because of its cost).

textual-plotext is measured only when it is installed (it is no dependency any more: ``pip install
textual-plotext``); its widget is kept below as it was in term/ui/widgets/plots.py.

    python -m bench.plots [--redraws 200]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import sys
import time
from typing import Any

from textual.geometry import Region

SIZE = (120, 44)
RATE_HZ = 50.0
HISTORY_S = 60.0


def _fill(model: Any) -> None:
    """60 s of every plotted series at 50 Hz: smooth motion with sensor-like noise."""
    import random

    rnd = random.Random(1)
    n = int(HISTORY_S * RATE_HZ)
    for i in range(n):
        t = i / RATE_HZ
        model._push(t, phi=15 * math.sin(0.7 * t) + rnd.gauss(0, 0.3), theta=8 * math.sin(1.3 * t) + rnd.gauss(0, 0.3),
                    psi=(20 * t) % 360 - 180, height=1.5 + 0.3 * math.sin(0.2 * t) + rnd.gauss(0, 0.02))
    model.version += 1


def _plotext_class() -> Any:
    """The textual-plotext widget as term/ui/widgets/plots.py had it (drawing part), or None when not installed."""
    try:
        from textual_plotext import PlotextPlot
    except ImportError:
        return None
    from rich.text import Text

    from term.session.config import PLOT_SERIES

    class PlotextLivePlot(PlotextPlot):  # type: ignore[misc]
        def __init__(self, series: tuple[str, ...], window: float) -> None:
            super().__init__()
            self.series = series
            self.window = window
            self._text = Text("")

        def build(self, model: Any, now: float) -> None:
            width, height = self.size.width, self.size.height
            points = max(50, 2 * width)
            data = []
            for name in self.series:
                xs, ys = model.series(name, self.window, now)
                if len(xs) > points:
                    step = len(xs) / points
                    idx = [int(i * step) for i in range(points)] + [len(xs) - 1]
                    xs, ys = [xs[i] for i in idx], [ys[i] for i in idx]
                data.append((name, xs, ys))
            plt = self.plt
            plt.clear_data()
            plt.clear_figure()
            plt.plotsize(width, height)
            plt._set_size(width, height)
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
            self._text = Text.from_ansi(plt.build())

        def render(self) -> Any:
            return self._text

    return PlotextLivePlot


def _figures(times: list[float]) -> dict[str, float]:
    s = sorted(times)
    p = lambda q: s[min(len(s) - 1, round(q / 100 * (len(s) - 1)))]  # noqa: E731
    return {"ms_p50": round(1e3 * p(50), 3), "ms_p99": round(1e3 * p(99), 3),
            "cpu_pct_at_10hz": round(100 * 10 * sum(s) / len(s), 1)}


async def run(redraws: int) -> dict[str, Any]:
    from textual.containers import Vertical

    from term.ui.app import TermApp
    from term.ui.widgets.plots import LivePlot

    clock = [0.0]
    app = TermApp(joystick=False, clock=lambda: clock[0])
    out: dict[str, Any] = {}
    async with app.run_test(size=SIZE, headless=True) as pilot:
        model = app.model
        _fill(model)
        clock[0] = model.start + HISTORY_S
        await pilot.press("f8")
        await pilot.pause(0.2)
        plots = list(app.screen.query(LivePlot))
        times = []
        for i in range(redraws):
            now = clock[0] + i * 0.1  # time moves on a dot column or more: every redraw is a full one
            t0 = time.thread_time()
            for p in plots:
                w, h = p.content_size
                p._strips = p.draw([(s, p.view.data(s)) for s in p.series], now - model.start, w, h)
                p.refresh()
                p.render_lines(Region(0, 0, w, h))
            times.append(time.thread_time() - t0)
        out["native"] = {**_figures(times), "plots": len(plots), "size": [p.content_size.width for p in plots]}
        cls = _plotext_class()
        if cls is None:
            out["plotext"] = None
        else:
            box = app.screen.query_one("#plots", Vertical)
            await box.remove_children()
            old = [cls(p.series, 10.0) for p in plots]
            await box.mount_all(old)
            await pilot.pause(0.2)
            times = []
            for i in range(redraws):
                now = clock[0] + i * 0.1
                t0 = time.thread_time()
                for p in old:
                    p.build(model, now)
                    p.refresh()
                    p.render_lines(Region(0, 0, p.size.width, p.size.height))
                times.append(time.thread_time() - t0)
            out["plotext"] = {**_figures(times), "plots": len(old), "size": [p.size.width for p in old]}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.plots", description=__doc__.splitlines()[0])
    ap.add_argument("--redraws", type=int, default=200, help="redraws measured per widget (default 200)")
    args = ap.parse_args(argv)
    res = asyncio.run(run(max(1, args.redraws)))
    native, plotext = res["native"], res["plotext"]
    print(json.dumps({
        "native_ms_p50": native["ms_p50"], "native_ms_p99": native["ms_p99"],
        "plotext_ms_p50": plotext["ms_p50"] if plotext else None,
        "plotext_ms_p99": plotext["ms_p99"] if plotext else None,
        "speedup_p50": round(plotext["ms_p50"] / native["ms_p50"], 1) if plotext else None,
        "chosen": "native", "native": native, "plotext": plotext, "screen": list(SIZE),
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
