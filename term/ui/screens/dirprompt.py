"""A small dialog asking where to write a downloaded log (the command palette's "download to…")."""

from __future__ import annotations

from pathlib import Path

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import Input, Label

from term.core.logfile import check_directory


class DirectoryPrompt(ModalScreen[Path | None]):
    """Enter accepts, Escape cancels (in SAFE; out of SAFE ESC is PANIC here too, term/ui/keygate.py)."""

    TYPING = True  # a text box: keys typed before its box has the focus are text too

    DEFAULT_CSS = """
    DirectoryPrompt { align: center middle; }
    DirectoryPrompt > Vertical { width: 80; height: auto; border: thick $accent; background: $surface;
                                 padding: 1 2; }
    """
    BINDINGS = [("escape", "cancel", "cancel")]

    title_text = "download the log to a directory"

    def __init__(self, current: Path, about: frozenset[int] | None = None) -> None:
        """``about``: the modes it is about (SAFE: a download and free text only there; the app closes it)."""
        super().__init__()
        self.current = current
        self.about = about

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Label("Download the board's log as CSV into this directory (Enter; Esc cancels):")
            yield Input(str(self.current), id="directory")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        text = event.value.strip()
        why = check_directory(Path(text)) if text else None
        if why:  # say why here and let the pilot fix it, rather than fail after the whole download
            self.query_one(Label).update(why)
            return
        self.dismiss(Path(text).expanduser() if text else None)

    def action_cancel(self) -> None:
        self.dismiss(None)
