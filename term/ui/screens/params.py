"""The parameter screen (F11): the board's parameters from the protocol's table (``term.core.protocol.PARAMS``) with
the values the board last said, searchable, editable, changed ones marked, refusals with the board's reason.

- A row per parameter: ``*`` and bold when its value differs from the table's default; the board's value, unit,
  default, range, whether it may change in flight, and the board's last refusal for it (red), or "…" while a
  set waits for its answer. "?" until the board has said (the app asks for the list when the board says Hello;
  **r** asks again).
- **/** (or a click) goes to the search line: every word typed must be in the name or the meaning.
- **Enter** on a row, in SAFE, opens the edit line with its value; Enter there checks the value against the table
  and the rules between parameters (``PARAM_RULES``: a value refused is said at once, in one line, and nothing is
  sent) and posts ``SetParam`` up: the app sends ``SET_PARAM``; the board's answer comes back through the model
  (``Model.params``, ``Model.param_refused``). Esc closes the line unchanged.
- **Out of SAFE nothing is typed** (DESIGN: a value is changed in flight by steps, never typed; 0, 1 and Esc fly the
  craft there, term/ui/keygate.py): Enter on a row opens the stepper (``ParamStepper``) at the board's value; ↑ → step
  it up, ↓ ← down by the table's step (``ParamSpec.nudge``), PageUp/PageDown by ten; Enter sends it (after the same
  checks, and "only shorter in flight" for the link timeouts), Backspace leaves it. A SAFE-only parameter opens
  nothing and says so. A text edit open when the board leaves SAFE closes with a line.
- The list and the stepper claim their keys while they have the focus (``CLAIMED_KEYS``: the app leaves them to
  them); PANIC, SAFE and lift down always work. The screen hidden (another screen, a dialog over it) closes the edit
  and leaves the focus in the list: never in a box.

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
from textual.widgets import DataTable, Input, Static

from term.core.protocol import PARAM_BY_NAME, PARAMS, Param, ParamSpec, broken_rules
from term.session.model import Model
from term.session.param_client import ParamError, parse_text
from term.ui.widgets.base import STATUS_LINE_S
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner

COLUMNS = ("parameter", "value", "unit", "default", "range", "in flight", "board says")
_ORDER = sorted(PARAMS.values(), key=lambda s: s.name)
PENDING_S = 2.0  # a set without an answer this long is no longer shown as waiting
HINT = ("Enter: change the row (typed in SAFE; stepped with the arrows in flight) · /: search · r: ask the board "
        "again · * differs from the default")


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


class ParamStepper(Static, can_focus=True):
    """A value stepped by keys, never typed (out of SAFE): ``spec``'s raw value moved by its step."""

    CLAIMED_KEYS = frozenset({"up", "down", "left", "right", "pageup", "pagedown", "enter", "backspace"})
    BINDINGS = [
        Binding("up,right", "step(1)", "up", show=False),
        Binding("down,left", "step(-1)", "down", show=False),
        Binding("pageup", "step(10)", "up x10", show=False),
        Binding("pagedown", "step(-10)", "down x10", show=False),
        Binding("enter", "send", "send", show=False),
        Binding("backspace", "leave", "leave", show=False),
    ]

    class Done(Message):
        """Enter (``value`` set) or Backspace (``value`` None)."""

        def __init__(self, spec: ParamSpec, value: float | str | bool | None) -> None:
            super().__init__()
            self.spec = spec
            self.value = value

    def __init__(self, **kw: object) -> None:
        super().__init__("", **kw)  # type: ignore[arg-type]
        self.spec: ParamSpec | None = None
        self.start: float | str | bool = 0
        self.value: float | str | bool = 0

    def begin(self, spec: ParamSpec, value: float | str | bool) -> None:
        self.spec, self.start, self.value = spec, value, value
        self._show()

    def action_step(self, presses: int) -> None:
        if self.spec is not None:
            self.value = step_value(self.spec, self.value, presses)
            self._show()

    def action_send(self) -> None:
        if self.spec is not None:
            self.post_message(self.Done(self.spec, self.value))

    def action_leave(self) -> None:
        if self.spec is not None:
            self.post_message(self.Done(self.spec, None))

    def _show(self) -> None:
        spec = self.spec
        if spec is None:
            return
        unit = f" {spec.unit}" if spec.unit else ""
        line = Text.assemble((f"{spec.name}: ", "bold"), spec.text(self.start), " → ",
                             (spec.text(self.value), "bold cyan" if self.value != self.start else "cyan"), unit)
        self.update(line)


def step_value(spec: ParamSpec, value: float | str | bool, presses: int) -> float | str | bool:
    """``value`` moved by ``presses`` of the parameter's step, kept inside the table's range (an enum's choices
    in turn, a bool flipped by any press)."""
    if spec.kind == "bool":
        return (not value) if presses % 2 else value
    lo, hi = spec.raw_range
    if spec.kind == "enum":
        raw = spec.to_raw(value) if value in spec.choices else lo
        return spec.from_raw(lo + (raw - lo + presses) % (hi - lo + 1))
    step = max(1, round(spec.nudge / spec.scale))
    raw = min(hi, max(lo, spec.to_raw(value) + presses * step))
    return spec.from_raw(raw)


def refusal(spec: ParamSpec, value: float | str | bool, model: Model, *, can_fly: bool) -> str:
    """Why the board would refuse ``spec`` = ``value`` now, said before anything is sent ("" if it would not):
    SAFE only, only shorter in flight, or a rule between parameters broken with the board's other values."""
    if can_fly and not spec.in_flight:
        return f"{spec.name} changes only in SAFE"
    now = model.params.get(spec.name)
    if can_fly and spec.shorter_in_flight and now is not None and spec.to_raw(value) > spec.to_raw(now):
        return f"{spec.name} may only get shorter in flight (now {spec.text(now)} {spec.unit})"
    values = {s.param: model.params[s.name] for s in PARAMS.values() if s.name in model.params}
    values[spec.param] = value
    broken = [r for r in broken_rules(values) if spec.param in (r.big, r.small)]
    if broken:
        rule = broken[0]
        return f"{spec.name} = {spec.text(value)} breaks the rule {rule.text()} ({rule.now_text(values)})"
    return ""


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


def same_cell(a: Text, b: Text) -> bool:
    """The same text drawn the same way (rich's ``==`` leaves out the text's own style)."""
    return a.plain == b.plain and a.style == b.style and a.spans == b.spans


class ParamsScreen(Screen[None]):
    DEFAULT_CSS = """
    ParamsScreen #param-search { height: 3; }
    ParamsScreen #param-table { height: 1fr; }
    ParamsScreen #param-edit { height: 3; display: none; }
    ParamsScreen #param-edit.editing { display: block; }
    ParamsScreen #param-step { height: 3; display: none; border: round $accent; padding: 0 1; }
    ParamsScreen #param-step.editing { display: block; }
    ParamsScreen #param-step:focus { border: round $accent-lighten-2; }
    ParamsScreen #param-help { height: 2; padding: 0 1; }
    """
    BINDINGS = [  # / and Enter move the focus at once (priority): the keys typed after them are text at once
        Binding("slash", "search", "search", show=False, priority=True),
        Binding("enter", "edit_row", "edit", show=False, priority=True),
        Binding("r", "reload", "reload", show=False),
    ]

    def __init__(self, model: Callable[[], Model], can_fly: Callable[[], bool] = lambda: False) -> None:
        """``can_fly``: out of SAFE on a live board (the app's ``can_fly``): values are stepped, never typed."""
        super().__init__()
        self.model = model
        self.can_fly = can_fly
        self.shown: list[ParamSpec] = list(_ORDER)
        self.editing: ParamSpec | None = None
        self._said_at: float | None = None  # when the help line last said something other than the hint
        self.pending: dict[str, tuple[float, object]] = {}  # name -> (when its set was sent, the value then)
        self._version = -1
        self._cells: dict[str, tuple[Text, ...]] = {}  # each row as last put in the table

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        yield Input(placeholder="search: words of a name or meaning (/)", id="param-search")
        table = ParamTable(id="param-table", cursor_type="row", zebra_stripes=True)
        table.border_title = "board parameters (docs/parameters.md)"
        yield table
        yield Input(id="param-edit")
        yield ParamStepper(id="param-step")
        yield Static("", id="param-help")
        yield KeyBar()

    def on_mount(self) -> None:
        table = self.query_one(ParamTable)
        for c in COLUMNS:
            table.add_column(c, key=c)
        self._fill()
        self.set_interval(0.25, self.refresh_values)
        table.focus()
        self._say(HINT)

    # --- the table ------------------------------------------------------------------------------------------

    def _fill(self) -> None:
        table = self.query_one(ParamTable)
        table.clear()
        model = self.model()
        self._cells.clear()
        for spec in self.shown:
            cells = self._cells[spec.name] = row_cells(spec, model, spec.name in self.pending)
            table.add_row(*cells, key=spec.name)
        self._version = model.version

    def refresh_values(self) -> None:
        """The board's values into the rows (when the model changed); a text edit closed when the board left
        SAFE (its digits and Esc fly the craft now)."""
        if self._said_at is not None and self.editing is None and time.monotonic() - self._said_at > STATUS_LINE_S:
            self._say(HINT)
        if self.editing is not None and self.query_one("#param-edit").has_class("editing") and self.can_fly():
            name = self.editing.name
            self._close_edit()
            self._say(f"the board left SAFE: the edit of {name} is closed, nothing sent; in flight Enter on a row "
                      "steps its value with the arrows", "bold yellow")
        model = self.model()
        if model.version == self._version:
            return
        self._version = model.version
        now = time.monotonic()
        for name, (sent, before) in list(self.pending.items()):  # answered: refused, changed, or long ago
            if name in model.param_refused or model.params.get(name) != before or now - sent > PENDING_S:
                del self.pending[name]
        table = self.query_one(ParamTable)
        for spec in self.shown:  # only the cells that changed: each update redraws the whole table (90 ms)
            cells = row_cells(spec, model, spec.name in self.pending)
            before = self._cells.get(spec.name, ())
            for i, (col, cell) in enumerate(zip(COLUMNS, cells, strict=True)):
                if i >= len(before) or not same_cell(cell, before[i]):
                    table.update_cell(spec.name, col, cell)
            self._cells[spec.name] = cells

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
        if self._send(spec, value):
            self._close_edit()

    def _send(self, spec: ParamSpec, value: float | str | bool) -> bool:
        """Post the set if nothing the terminal knows refuses it (else say why); whether it went."""
        model = self.model()
        why = refusal(spec, value, model, can_fly=self.can_fly())
        if why:
            self._say(why, "bold red")
            return False
        self.pending[spec.name] = (time.monotonic(), model.params.get(spec.name))
        self.post_message(SetParam(spec.param, value))
        self._say(f"{spec.name} = {spec.text(value)}: sent; the board's answer shows in the row")
        return True

    def on_param_stepper_done(self, message: ParamStepper.Done) -> None:
        message.stop()
        if message.value is None:
            self._close_edit()
            self._say(f"{message.spec.name}: left unchanged")
        elif self._send(message.spec, message.value):
            self._close_edit()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:  # a click on a row
        event.stop()
        self._open_edit(event.row_key.value)

    def _open_edit(self, name: str | None) -> None:
        spec = PARAM_BY_NAME.get(name or "")
        if spec is None:
            return
        value = self.model().params.get(spec.name)
        value = value if value is not None else spec.default
        limits = f"{spec.limits_text()}{' ' + spec.unit if spec.unit else ''}"
        if self.can_fly():
            if not spec.in_flight:
                self._say(f"{spec.name} changes only in SAFE: land and press 0 first", "bold yellow")
                return
            self.editing = spec
            stepper = self.query_one(ParamStepper)
            stepper.begin(spec, value)
            stepper.border_title = f"{spec.name} ({limits})"
            stepper.add_class("editing")
            self.set_focus(stepper)
            step = "its choices in turn" if spec.kind == "enum" else ("flips it" if spec.kind == "bool" else
                                                                     f"step {spec.text(spec.nudge)}")
            self._say(f"in flight: ↑ ↓ (→ ←) {step} · PgUp PgDn ×10 · Enter sends · Backspace leaves it · "
                      f"0 SAFE, 1/Esc PANIC as ever. {spec.doc}")
            return
        self.editing = spec
        edit = self.query_one("#param-edit", Input)
        edit.value = spec.text(value)
        edit.border_title = f"{spec.name} ({limits}): Enter sets, Esc cancels"
        edit.add_class("editing")
        self.set_focus(edit)
        self._say(f"type the value · Enter sets · Esc cancels (in SAFE only: in flight values are stepped). {spec.doc}")

    def on_key(self, event: events.Key) -> None:
        """Esc leaves a line (in SAFE; out of SAFE it is PANIC, term/ui/keygate.py): the edit line unchanged."""
        if event.key != "escape":
            return
        if self.editing is not None and self.focused is self.query_one("#param-edit"):
            self._close_edit()
            self._say("edit cancelled: nothing sent")
            event.stop()
        elif self.focused is self.query_one("#param-search"):
            self.set_focus(self.query_one(ParamTable))
            event.stop()

    def _close_edit(self) -> None:
        self.editing = None
        self.query_one("#param-edit", Input).remove_class("editing")
        self.query_one(ParamStepper).remove_class("editing")
        self.set_focus(self.query_one(ParamTable))

    def on_screen_suspend(self) -> None:
        """Hidden (another screen, a dialog): no edit left open, no box keeps the focus (the keys typed later
        belong to the pilot)."""
        if self.editing is not None:
            self._close_edit()
            self._say(HINT)
        self.set_focus(self.query_one(ParamTable))

    def _say(self, text: str, style: str = "dim") -> None:
        """The help line: ``text`` for STATUS_LINE_S, then the hint again (an error never outlives its moment)."""
        self._said_at = None if text == HINT else time.monotonic()
        self.query_one("#param-help", Static).update(Text(text, style=style))

    # --- actions --------------------------------------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "search":  # (a / typed into a line is text)
            return not isinstance(self.focused, Input)
        if action == "edit_row":  # (Enter in a line submits it, in the stepper sends)
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
