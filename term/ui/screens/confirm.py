"""A question before something that cannot be undone (erasing the flash log, quitting while the motors run).

Two buttons; the safe one ("no") has the focus, so Enter alone never does the harm; Tab moves to the other, a click
works too, and ``n`` answers no (Esc too, in SAFE: the app closes any dialog on it there). The pilot's keys stay
live underneath (they are priority bindings): PANIC always works, a question never blocks it. ``message`` may be a
callable, re-read four times a second (the log's record count arrives after the question is shown). Dismissed with
True (yes) or False (no); None when the app closed it. ``about``: the modes the question is about (the erase: SAFE;
quitting while the motors run: the flight modes and PANIC): the app closes it, with a line, once the board is in
another (``Dialogs.close_stale``, term/ui/controllers/dialogs.py).
"""

from __future__ import annotations

from collections.abc import Callable

from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Static


class ConfirmScreen(ModalScreen[bool]):
    DEFAULT_CSS = """
    ConfirmScreen { align: center middle; }
    ConfirmScreen > Vertical { width: 72; height: auto; border: thick $warning; background: $surface; padding: 1 2; }
    ConfirmScreen #confirm-text { margin: 0 0 1 0; }
    ConfirmScreen Horizontal { height: auto; }
    ConfirmScreen Button { margin: 0 2 0 0; }
    """
    BINDINGS = [("n", "answer(False)", "no")]
    CANCEL = False  # what Esc answers (in SAFE, term/ui/app.py)

    def __init__(self, message: str | Callable[[], str], yes: str, no: str, *, title: str = "",
                 about: frozenset[int] | None = None) -> None:
        super().__init__()
        self.message = message
        self.yes, self.no, self.title_text = yes, no, title
        self.about = about

    def _text(self) -> str:
        return self.message() if callable(self.message) else self.message

    def compose(self) -> ComposeResult:
        with Vertical() as v:
            v.border_title = self.title_text
            yield Static(self._text(), id="confirm-text")
            with Horizontal():
                yield Button(self.no, id="no", variant="primary")
                yield Button(self.yes, id="yes", variant="error")

    def on_mount(self) -> None:
        for no in self.query("#no").results(Button):  # (none if the app closed it before it was mounted)
            no.focus()
        if callable(self.message):
            self.set_interval(0.25, self._refresh_text)

    def _refresh_text(self) -> None:
        self.query_one("#confirm-text", Static).update(self._text())

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(event.button.id == "yes")

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)
