"""The key bar at the foot of every screen: the keys the screen answers to, each with what it does, on one line; a
click on one presses it.

One widget drawing one line, in place of Textual's ``Footer``: that builds a widget per key (about 30 here) each
time the screen or its bindings change, and styles each twice, which was 170 ms of every F-key's screen change
(a pilot's F7 took a quarter of a second). This draws the same keys, in the same order and colours (the theme's
``$footer-*`` variables), from ``Screen.active_bindings``: the first binding of each action that asks to be shown,
dimmed where the screen refuses it now, and the command palette's key on the right."""

from __future__ import annotations

from typing import ClassVar, NamedTuple

from rich.text import Text
from textual import events
from textual.screen import Screen
from textual.widget import Widget


class Chip(NamedTuple):
    """One key on the bar: where it is drawn (columns ``start`` to ``end``), the key it presses."""

    key: str
    display: str
    description: str
    enabled: bool
    start: int = 0
    end: int = 0


class KeyBar(Widget):
    """The screen's shown keys on one line (module docstring)."""

    DEFAULT_CSS = """
    KeyBar {
        dock: bottom;
        height: 1;
        color: $footer-foreground;
        background: $footer-background;
    }
    KeyBar > .keybar--key {
        color: $footer-key-foreground;
        background: $footer-key-background;
        text-style: bold;
    }
    KeyBar > .keybar--description {
        color: $footer-description-foreground;
        background: $footer-description-background;
    }
    KeyBar > .keybar--disabled {
        text-style: dim;
    }
    KeyBar > .keybar--palette {
        color: $foreground 20%;
    }
    """
    COMPONENT_CLASSES: ClassVar[set[str]] = {"keybar--key", "keybar--description", "keybar--disabled",
                                             "keybar--palette"}
    ALLOW_SELECT = False

    def __init__(self, *, id: str | None = None, classes: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id, classes=classes)
        self.chips: list[Chip] = []  # as last drawn

    def on_mount(self) -> None:
        self.screen.bindings_updated_signal.subscribe(self, self._bindings_changed)

    def _bindings_changed(self, screen: Screen[object]) -> None:
        if self.is_attached and screen is self.screen:
            self.refresh()

    def shown(self) -> tuple[list[Chip], Chip | None]:
        """The keys to show, in the screen's order, and the command palette's (drawn on the right)."""
        palette_key = self.app.COMMAND_PALETTE_BINDING if self.app.ENABLE_COMMAND_PALETTE else None
        chips: list[Chip] = []
        palette: Chip | None = None
        actions: set[str] = set()
        for key, (_node, binding, enabled, _tooltip) in self.screen.active_bindings.items():
            if key == palette_key:
                palette = Chip(binding.key, self.app.get_key_display(binding), binding.description, enabled)
                continue
            if not binding.show or binding.action in actions:
                continue
            actions.add(binding.action)
            chips.append(Chip(binding.key, self.app.get_key_display(binding), binding.description, enabled))
        return chips, palette

    def render(self) -> Text:
        key_style = self.get_component_rich_style("keybar--key", partial=True)
        text_style = self.get_component_rich_style("keybar--description", partial=True)
        dim = self.get_component_rich_style("keybar--disabled", partial=True)
        line = Text(no_wrap=True, overflow="crop", end="")
        chips, palette = self.shown()
        drawn: list[Chip] = []
        for chip in chips:
            start = line.cell_len
            extra = dim if not chip.enabled else None
            line.append(f" {chip.display} ", key_style + extra if extra else key_style)
            line.append(f"{chip.description} " if chip.description else "", text_style + extra if extra else text_style)
            drawn.append(chip._replace(start=start, end=line.cell_len))
        if palette is not None:  # on the right, over what does not fit (as Textual's footer)
            right = Text.assemble(("▏", self.get_component_rich_style("keybar--palette")),
                                  (palette.display, key_style), (f" {palette.description} ", text_style))
            room = self.size.width - right.cell_len
            if room >= 0:
                line.truncate(room, pad=True)
                drawn = [c._replace(end=min(c.end, room)) for c in drawn if c.start < room]
                drawn.append(palette._replace(start=room, end=room + right.cell_len))
                line.append_text(right)
        self.chips = drawn
        return line

    def chip_at(self, x: int) -> Chip | None:
        return next((c for c in self.chips if c.start <= x < c.end), None)

    def on_mouse_down(self, event: events.MouseDown) -> None:
        chip = self.chip_at(event.x)
        if chip is None:
            return
        event.stop()
        if chip.enabled:
            self.app.simulate_key(chip.key)
        else:
            self.app.bell()
