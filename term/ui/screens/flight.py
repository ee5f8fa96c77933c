"""The flight screen: everything a pilot needs at a glance; in SAFE, the readiness checks beside the events."""

from __future__ import annotations

from collections.abc import Sequence

from textual import events
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Static

from term.input.keymap import KeyBinding
from term.lessons.room import Room
from term.ui.widgets.base import ModelView
from term.ui.widgets.battery import BatteryGauge
from term.ui.widgets.controls import ControlsPanel
from term.ui.widgets.download import DownloadPanel
from term.ui.widgets.events import EventsList
from term.ui.widgets.horizon import HeadingTape, Horizon
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.lesson import LessonBar
from term.ui.widgets.link import LinkPanel
from term.ui.widgets.mode import ModeBanner
from term.ui.widgets.motors import MotorBars
from term.ui.widgets.pressure import PressureIndicator
from term.ui.widgets.rates import RateGauges
from term.ui.widgets.readiness import ReadinessPanel
from term.ui.widgets.room import RoomView

MIN_SIZE = (60, 18)  # the compact layout needs this many columns and rows; smaller: a notice instead
COMPACT_BELOW = (110, 35)  # narrower or lower: the compact layout (mode, attitude, battery, height, link, events)
WIDE_FROM = (200, 55)  # this wide and high: the horizon, the room view and the events grow into the space


def panel(widget: ModelView, title: str, wid: str) -> ModelView:
    widget.border_title = title
    widget.id = wid
    return widget


class FlightScreen(Screen[None]):
    """The main screen: everything a pilot needs at a glance; in SAFE, the readiness checks beside the events. Its
    layout follows the terminal (app.tcss): compact below ``COMPACT_BELOW`` (the rates, motors and room give way),
    wide from ``WIDE_FROM`` (the panels grow); in a terminal too small even for the compact layout, a notice says so
    instead of cut panels (the keys keep working)."""

    def __init__(self, keymap: Sequence[KeyBinding], room: Room | None = None, *, id: str | None = None) -> None:
        """``keymap``: the pilot's keys (the readiness checks name them); ``room``: the simulator's truth for the
        room view (term --sim), None with a real board."""
        super().__init__(id=id)
        self.keymap = keymap
        self.room = room

    def compose(self) -> ComposeResult:
        yield Static("", id="too-small")
        yield ModeBanner(id="mode")
        yield LessonBar(id="lesson-bar")  # term --sim: what the lesson or the autopilot does now
        with Horizontal(id="top"):
            with Vertical(id="attitude") as v:
                v.border_title = "attitude · heading"
                yield Horizon(id="horizon")
                yield HeadingTape(id="heading")
            with Vertical(id="gauges"):
                yield panel(RateGauges(), "rates", "rates")
                yield panel(MotorBars(), "motors", "motors")
            with Vertical(id="power"):
                yield panel(BatteryGauge(), "battery", "battery")
                yield panel(PressureIndicator(), "pressure · height", "pressure")
        with Horizontal(id="middle"):
            yield panel(ControlsPanel(), "sticks · trims · gains", "controls")
            yield panel(LinkPanel(), "link", "link")
            yield panel(RoomView(self.room), "room", "room")  # the truth: term --sim only
        yield DownloadPanel(id="download")
        with Horizontal(id="bottom"):
            yield panel(ReadinessPanel(self.keymap), "ready to fly? (SAFE)", "readiness")
            yield panel(EventsList(), "events · errors", "events")
        yield KeyBar()

    def on_resize(self, event: events.Resize) -> None:
        w, h = event.size
        small = w < MIN_SIZE[0] or h < MIN_SIZE[1]
        self.set_class(small, "too-small")
        self.set_class(not small and (w < COMPACT_BELOW[0] or h < COMPACT_BELOW[1]), "compact")
        self.set_class(w >= WIDE_FROM[0] and h >= WIDE_FROM[1], "wide")
        if small:
            self.query_one("#too-small", Static).update(
                f"This terminal is {w}×{h}: the flight screen needs at least {MIN_SIZE[0]}×{MIN_SIZE[1]}.\n"
                "Make the window larger (or the font smaller).\n\n"
                "The keys still work: 1 or ESC is PANIC, 0 is SAFE, F1 the help.")
