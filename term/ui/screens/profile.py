"""The profile screen: the board's task timings (F9 asks the board for them)."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.screen import Screen

from term.ui.screens.flight import panel
from term.ui.widgets.events import EventsList
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner
from term.ui.widgets.profile import ProfileTable


class ProfileScreen(Screen[None]):
    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        yield panel(ProfileTable(), "profile", "profile")
        yield panel(EventsList(), "events · errors", "events-small")
        yield KeyBar()
