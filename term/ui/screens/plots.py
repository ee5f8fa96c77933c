"""The plots screen: live plots of the series the pilot chooses (F2), paused, zoomed and panned by keys."""

from __future__ import annotations

from collections.abc import Sequence

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widget import Widget
from textual.widgets import SelectionList, Static
from textual.widgets.selection_list import Selection

from term.session.config import PLOT_SERIES
from term.ui.widgets.events import EventsList
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner
from term.ui.widgets.plots import LivePlot, PlotView, group_by_unit


class SeriesChooser(SelectionList[str]):
    """Every series the plots can show; space or enter (or a click) turns one on or off."""

    CLAIMED_KEYS = frozenset({"up", "down"})  # with focus these move in the list (they trim pitch otherwise)


class PlotsScreen(Screen[None]):
    DEFAULT_CSS = """
    #plots-row { height: 1fr; }
    #plots { width: 1fr; height: 1fr; }
    #no-series { width: 1fr; height: 1fr; content-align: center middle; color: $text-muted; }
    SeriesChooser { width: 30; height: 1fr; display: none; border: round $accent; }
    SeriesChooser.open { display: block; }
    #events-small { height: 8; }
    """

    AUTO_FOCUS = None  # nothing takes the pilot's keys when the screen shows
    BINDINGS = [
        Binding("p", "pause", "pause/live"),
        Binding("right_square_bracket", "zoom(-1)", "zoom in", key_display="]"),
        Binding("left_square_bracket", "zoom(1)", "zoom out", key_display="["),
        Binding("comma", "pan(-1)", "back", key_display=","),
        Binding("full_stop", "pan(1)", "on", key_display="."),
        Binding("s", "choose", "series"),
    ]

    def __init__(self, series: tuple[str, ...], window: float) -> None:
        super().__init__()
        self.series = tuple(series)
        self.view = PlotView(window=window)

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        with Horizontal(id="plots-row"):
            with Vertical(id="plots"):
                yield from self._plots()
            chooser = SeriesChooser(*(Selection(f"{label} ({unit or '-'})", name, name in self.series)
                                      for name, (label, unit) in PLOT_SERIES.items()), id="chooser")
            chooser.border_title = "series (s closes)"
            chooser.can_focus = False  # until it is opened
            yield chooser
        events = EventsList(id="events-small")
        events.border_title = "events · errors"
        yield events
        yield KeyBar()

    def _plots(self) -> list[Widget]:
        if not self.series:
            return [Static("no series chosen: press s and pick some", id="no-series")]
        return [LivePlot(group, self.view, id=f"plot{i}", classes="plot")
                for i, group in enumerate(group_by_unit(self.series))]

    async def set_series(self, series: Sequence[str]) -> None:
        """Show ``series`` (in PLOT_SERIES order) instead: the plots are made again, the view kept."""
        chosen = tuple(s for s in PLOT_SERIES if s in series)
        if chosen == self.series:
            return
        self.series = chosen
        box = self.query_one("#plots", Vertical)
        await box.remove_children()
        await box.mount_all(self._plots())
        if self.view.model is not None:
            for p in self.query(LivePlot):
                p.show(self.view.model, self.view.now)

    @on(SelectionList.SelectedChanged, "#chooser")
    async def _chosen(self, event: SelectionList.SelectedChanged[str]) -> None:
        await self.set_series(event.selection_list.selected)

    @on(LivePlot.Zoom)
    def _wheel(self, event: LivePlot.Zoom) -> None:
        self.action_zoom(event.steps)

    def action_pause(self) -> None:
        self.view.toggle_pause()
        self._redraw()

    def action_zoom(self, steps: int) -> None:
        self.view.zoom(steps)
        self._redraw()

    def action_pan(self, direction: int) -> None:
        self.view.pan(direction)
        self._redraw()

    def action_choose(self) -> None:
        chooser = self.query_one(SeriesChooser)
        chooser.toggle_class("open")
        chooser.can_focus = chooser.has_class("open")
        if chooser.can_focus:
            chooser.focus()
        else:
            self.set_focus(None)

    def _redraw(self) -> None:
        if self.view.model is not None:
            for p in self.query(LivePlot):
                p.show(self.view.model, self.view.now)
