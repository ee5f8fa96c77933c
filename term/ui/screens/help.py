"""The help screen, generated from the key map (the same table the bindings come from)."""

from __future__ import annotations

from rich.table import Table
from textual.app import ComposeResult
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

from term.input.keymap import KeyBinding, help_rows


def help_table(keymap: tuple[KeyBinding, ...], preset: str = "") -> Table:
    title = f"keys: {preset} (F1 or ? closes)" if preset else "keys (F1 or ? closes)"
    table = Table(title=title, expand=True, title_style="bold")
    table.add_column("group", style="dim")
    table.add_column("key", style="bold cyan")
    table.add_column("action")
    last = None
    for group, keys, text in help_rows(keymap):
        table.add_row(group if group != last else "", keys, text)
        last = group
    return table


class HelpScreen(ModalScreen[None]):
    """Pilot keys keep working underneath: the help never blocks PANIC."""

    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > VerticalScroll { width: 90; height: 90%; border: thick $accent; background: $surface; }
    """

    def __init__(self, keymap: tuple[KeyBinding, ...], preset: str = "") -> None:
        """``preset``: which key preset this is, in words (the lab's map is labelled as the default)."""
        super().__init__()
        self.keymap = keymap
        self.preset = preset

    @property
    def help_title(self) -> str:
        return str(help_table(self.keymap, self.preset).title)

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            yield Static(help_table(self.keymap, self.preset), id="help-table")
