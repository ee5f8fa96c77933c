"""The parameter screen (F11): the board's parameters from the protocol's table (``term.core.protocol.PARAMS``) with
the values the board last said, searchable, editable, changed ones marked, refusals with the board's reason.

- A row per parameter: ``*`` and bold when its value differs from the table's default; the board's value, unit,
  default, range, whether it may change in flight, and the board's last refusal for it (red), or "…" while a
  set waits for its answer. "?" until the board has said (the app asks for the list when the board says Hello;
  **r** asks again).
- **/** (or a click) goes to the search line: every word typed must be in the name or the meaning.
- **Enter** on a row opens the edit line with its value; Enter there checks the value against the table (a value
  the table refuses is said at once, in one line, and nothing is sent) and posts ``SetParam`` up: the app sends
  ``SET_PARAM``; the board's answer comes back through the model (``Model.params``, ``Model.param_refused``).
  Escape closes the line unchanged (in SAFE: out of SAFE, 1, Esc and 0 are PANIC and SAFE even here; the other
  keys typed into a line are text, term/ui/keygate.py).
- The list claims ↑ ↓ and Enter while it has the focus (``CLAIMED_KEYS``: the app leaves them to it); PANIC, SAFE
  and lift down always work.

The model comes down as a callable; the screen never touches the link (messages up).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.message import Message
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Input, Static

from term.core.protocol import PARAMS, Param, ParamSpec
from term.session.model import Model
from term.session.param_client import ParamError, parse_text
from term.ui.widgets.mode import ModeBanner

COLUMNS = ("parameter", "value", "unit", "default", "range", "in flight", "board says")
_ORDER = sorted(PARAMS.values(), key=lambda s: s.name)
PENDING_S = 2.0  # a set without an answer this long is no longer shown as waiting


class SetParam(Message):
    """Set a parameter on the board (the app sends SET_PARAM)."""

    def __init__(self, param: Param, value: float | str | bool) -> None:
        super().__init__()
        self.param = param
        self.value = value


class ReloadParams(Message):
    """Ask the board for all its parameters again."""


class ParamTable(DataTable[Text]):
    CLAIMED_KEYS = frozenset({"up", "down", "enter", "pageup", "pagedown", "home", "end"})


def matches(spec: ParamSpec, query: str) -> bool:
    """Every word of ``query`` in the parameter's name or meaning (case ignored)."""
    hay = f"{spec.name} {spec.doc}".lower()
    return all(w in hay for w in query.lower().split())


def row_cells(spec: ParamSpec, model: Model, pending: bool) -> tuple[Text, ...]:
    """A parameter's row as the screen shows it."""
    value = model.params.get(spec.name)
    changed = value is not None and spec.to_raw(value) != spec.to_raw(spec.default)
    style = "bold" if changed else ""
    refused = model.param_refused.get(spec.name, "")
    note = Text(refused, style="red") if refused else Text("…" if pending else "", style="dim")
    shown = "?" if value is None else spec.text(value)
    return (Text(("* " if changed else "  ") + spec.name, style=style), Text(shown, style=style or "cyan"),
            Text(spec.unit, style="dim"), Text(spec.text(spec.default), style="dim"), Text(spec.limits_text()),
            Text("yes" if spec.in_flight else "SAFE only", style="" if spec.in_flight else "yellow"), note)


class ParamsScreen(Screen[None]):
    DEFAULT_CSS = """
    ParamsScreen #param-search { height: 3; }
    ParamsScreen #param-table { height: 1fr; }
    ParamsScreen #param-edit { height: 3; display: none; }
    ParamsScreen #param-edit.editing { display: block; }
    ParamsScreen #param-help { height: 2; padding: 0 1; }
    """
    BINDINGS = [  # / and Enter move the focus at once (priority): the keys typed after them are text at once
        Binding("slash", "search", "search", show=False, priority=True),
        Binding("enter", "edit_row", "edit", show=False, priority=True),
        Binding("r", "reload", "reload", show=False),
    ]

    def __init__(self, model: Callable[[], Model]) -> None:
        super().__init__()
        self.model = model
        self.shown: list[ParamSpec] = list(_ORDER)
        self.editing: ParamSpec | None = None
        self.pending: dict[str, tuple[float, object]] = {}  # name -> (when its set was sent, the value then)
        self._version = -1

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        yield Input(placeholder="search: words of a name or meaning (/)", id="param-search")
        table = ParamTable(id="param-table", cursor_type="row", zebra_stripes=True)
        table.border_title = "board parameters (docs/parameters.md)"
        yield table
        yield Input(id="param-edit")
        yield Static("", id="param-help")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one(ParamTable)
        for c in COLUMNS:
            table.add_column(c, key=c)
        self._fill()
        self.set_interval(0.25, self.refresh_values)
        table.focus()
        self._say("Enter: edit the row · /: search · r: ask the board again · * differs from the default")

    # --- the table ------------------------------------------------------------------------------------------

    def _fill(self) -> None:
        table = self.query_one(ParamTable)
        table.clear()
        model = self.model()
        for spec in self.shown:
            table.add_row(*row_cells(spec, model, spec.name in self.pending), key=spec.name)
        self._version = model.version

    def refresh_values(self) -> None:
        """The board's values into the rows (when the model changed)."""
        model = self.model()
        if model.version == self._version:
            return
        self._version = model.version
        now = time.monotonic()
        for name, (sent, before) in list(self.pending.items()):  # answered: refused, changed, or long ago
            if name in model.param_refused or model.params.get(name) != before or now - sent > PENDING_S:
                del self.pending[name]
        table = self.query_one(ParamTable)
        for spec in self.shown:
            for col, cell in zip(COLUMNS, row_cells(spec, model, spec.name in self.pending), strict=True):
                table.update_cell(spec.name, col, cell)

    def on_input_changed(self, event: Input.Changed) -> None:
        if event.input.id != "param-search":
            return
        self.shown = [s for s in _ORDER if matches(s, event.value)]
        self._fill()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        if event.input.id == "param-search":
            self.set_focus(self.query_one(ParamTable))
            return
        spec = self.editing
        if spec is None:
            return
        try:
            value = parse_text(spec, event.value)
        except ParamError as exc:
            self._say(str(exc), "bold red")
            return
        model = self.model()
        self.pending[spec.name] = (time.monotonic(), model.params.get(spec.name))
        self.post_message(SetParam(spec.param, value))
        self._say(f"{spec.name} = {spec.text(value)}: sent; the board's answer shows in the row")
        self._close_edit()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:  # a click on a row
        event.stop()
        self._open_edit(event.row_key.value)

    def _open_edit(self, name: str | None) -> None:
        spec = next((s for s in _ORDER if s.name == name), None)
        if spec is None:
            return
        self.editing = spec
        edit = self.query_one("#param-edit", Input)
        value = self.model().params.get(spec.name)
        edit.value = spec.text(value if value is not None else spec.default)
        edit.border_title = f"{spec.name} ({spec.limits_text()}{' ' + spec.unit if spec.unit else ''}): Enter sets"
        edit.add_class("editing")
        self.set_focus(edit)
        self._say(f"{spec.name}: {spec.doc}")

    def on_key(self, event: events.Key) -> None:
        """Esc leaves a line (in SAFE; out of SAFE it is PANIC, term/ui/keygate.py): the edit line unchanged."""
        if event.key != "escape":
            return
        if self.editing is not None and self.focused is self.query_one("#param-edit"):
            self._close_edit()
            event.stop()
        elif self.focused is self.query_one("#param-search"):
            self.set_focus(self.query_one(ParamTable))
            event.stop()

    def _close_edit(self) -> None:
        self.editing = None
        edit = self.query_one("#param-edit", Input)
        edit.remove_class("editing")
        self.set_focus(self.query_one(ParamTable))

    def _say(self, text: str, style: str = "dim") -> None:
        self.query_one("#param-help", Static).update(Text(text, style=style))

    # --- actions --------------------------------------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "search":  # (a / typed into a line is text)
            return not isinstance(self.focused, Input)
        if action == "edit_row":  # (Enter in a line submits it)
            return isinstance(self.focused, ParamTable)
        return True

    def action_search(self) -> None:
        self.set_focus(self.query_one("#param-search", Input))

    def action_edit_row(self) -> None:
        table = self.query_one(ParamTable)
        if table.row_count:
            self._open_edit(table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value)

    def action_reload(self) -> None:
        self.post_message(ReloadParams())
        self._say("asked the board for its parameters")
