"""The console screen (Ctrl+T): the board's text, as a firmware team's printf shows it (term.core.console)."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.screen import Screen

from term.ui.screens.flight import panel
from term.ui.widgets.console import ConsoleView
from term.ui.widgets.events import EventsList
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner


class ConsoleScreen(Screen[None]):
    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        yield panel(ConsoleView(), "console · the board's text", "console")
        yield panel(EventsList(), "events · errors", "events-small")
        yield KeyBar()
