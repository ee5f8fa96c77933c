"""The help screen, generated from the key map (the same table the bindings come from)."""

from __future__ import annotations

from rich.table import Table
from textual.app import ComposeResult
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

from term.input.keymap import KeyBinding, help_rows


def help_table(keymap: tuple[KeyBinding, ...]) -> Table:
    table = Table(title="keys (F1 or ? closes)", expand=True, title_style="bold")
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

    def __init__(self, keymap: tuple[KeyBinding, ...]) -> None:
        super().__init__()
        self.keymap = keymap

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            yield Static(help_table(self.keymap), id="help-table")
