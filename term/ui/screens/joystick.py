"""The joystick screen (F12): the device's live raw axes and buttons, the mapping that flies it (axis, invert, dead
zone, kind for roll, pitch, yaw and lift; the fire button) with what each axis gives now, and buttons that change
the mapping at once and save it to the config file as the device's own mapping.

The poller (``term.input.joystick.JoystickPoller``) comes down as a callable (the app starts it after the screen
exists, and a stick may be plugged in later); a change of the mapping is made on the poller's state, where the
next poll uses it. Saving is the app's (file I/O): the screen posts ``SaveMapping`` up. No mouse needed: Tab
moves between the buttons, Enter presses one; the pilot's keys keep working (PANIC always does).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from rich.console import RenderableType
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Grid, Horizontal
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Button

from term.input.joystick import JoystickPoller
from term.input.mapping import AXIS_MAX, DEADZONE_MAX, FULL, AxisMap, StickMapping
from term.session.model import Model
from term.ui.widgets.bars import cbar, hbar
from term.ui.widgets.base import ModelView
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner

AXES = ("roll", "pitch", "yaw", "lift")
EDITS = (("axis-", "axis ◀", "axis-down"), ("axis+", "axis ▶", "axis-up"), ("invert", "invert", "invert"),
         ("dz-", "dead zone −", "dz-down"), ("dz+", "dead zone +", "dz-up"), ("kind", "kind", "kind"))
_BY_ID = {f"js-{axis}-{wid}": (axis, what) for axis in ("roll", "pitch", "yaw", "lift") for what, _, wid in EDITS}
KINDS = ("center", "throttle", "half")
DEADZONE_STEP = 0.01


class SaveMapping(Message):
    """Save this mapping to the config file as ``device``'s own."""

    def __init__(self, mapping: StickMapping, device: str) -> None:
        super().__init__()
        self.mapping = mapping
        self.device = device


def edited(mapping: StickMapping, axis: str, what: str) -> StickMapping:
    """``mapping`` with one change to one logical axis: "axis-"/"axis+" (raw axis number), "invert", "dz-"/"dz+"
    (dead zone by one percent), "kind" (the next kind)."""
    a: AxisMap = getattr(mapping, axis)
    if what in ("axis-", "axis+"):
        a = replace(a, index=max(0, min(AXIS_MAX, a.index + (1 if what == "axis+" else -1))))
    elif what == "invert":
        a = replace(a, invert=not a.invert)
    elif what in ("dz-", "dz+"):
        dz = a.deadzone + (DEADZONE_STEP if what == "dz+" else -DEADZONE_STEP)
        a = replace(a, deadzone=round(max(0.0, min(DEADZONE_MAX, dz)), 3))
    elif what == "kind":
        a = replace(a, kind=KINDS[(KINDS.index(a.kind) + 1) % len(KINDS)])
    return replace(mapping, **{axis: a})


class JoystickView(ModelView):
    """What the device reads now and what the mapping makes of it."""

    TIME_DEPENDENT = True  # the device moves without the model changing

    def __init__(self, source: Callable[[], JoystickPoller | None], *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id)
        self.source = source

    def render_model(self, model: Model, now: float) -> RenderableType:
        p = self.source()
        out = Text()
        if p is None or not p.connected:
            why = (p.error if p is not None and p.error else "no joystick: plug one in (it is picked up at once); "
                   "the keyboard flies meanwhile")
            out.append(why, style="yellow")
            return out
        width = max(10, (self.content_size.width or 80) - 30)
        kind = "game controller (SDL's layout)" if p.gamepad else "raw axes"
        out.append(f"{p.name}", style="bold")
        out.append(f"  {len(p.axes)} axes, {len(p.buttons)} buttons, read as {kind}\n", style="dim")
        out.append(f"mapping: {p.mapping.name}\n\n", style="bold")
        for i, v in enumerate(p.axes):
            out.append(f"axis {i:<2} ")
            out.append_text(cbar(v * FULL, FULL, width))
            out.append(f" {v:+.2f}\n")
        out.append("buttons ")
        for i, b in enumerate(p.buttons):
            out.append(f"{i}", style="bold reverse green" if b else "dim")
            out.append(" ")
        out.append("\n\n")
        pkt = p.state.current
        m = p.mapping
        for name in AXES:
            a: AxisMap = getattr(m, name)
            out.append(f"{name:<6} axis {a.index:<2} {'inverted' if a.invert else '        '} {a.kind:<8} "
                       f"dead zone {100 * a.deadzone:4.1f} %  ")
            v = getattr(pkt, name)
            if name == "lift":
                out.append_text(hbar(v, 0, FULL, 12, "yellow"))
            else:
                out.append_text(cbar(v, FULL, 13))
            out.append(f" {100 * v / FULL:+4.0f} %\n")
        out.append(f"fire   button {', '.join(str(b) for b in m.fire) or '—'} (PANIC)")
        return out


class JoystickScreen(Screen[None]):
    """The view above a grid of buttons: per logical axis, the raw axis ◀ ▶, invert, dead zone − +, kind."""

    DEFAULT_CSS = """
    JoystickScreen #js-view { height: 1fr; }
    JoystickScreen #js-edit { grid-size: 6; grid-gutter: 0 1; height: auto; padding: 0 1; }
    JoystickScreen #js-edit Button { width: 100%; }
    JoystickScreen #js-bottom { height: 1; padding: 0 1; }
    JoystickScreen #js-bottom Button { margin: 0 2 0 0; }
    """

    def __init__(self, source: Callable[[], JoystickPoller | None]) -> None:
        super().__init__()
        self.source = source

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        view = JoystickView(self.source, id="js-view")
        view.border_title = "joystick"
        yield view
        with Grid(id="js-edit"):
            for axis in AXES:
                for _, label, wid in EDITS:
                    yield Button(f"{axis} {label}" if wid == "axis-down" else label, id=f"js-{axis}-{wid}",
                                 compact=True)
        with Horizontal(id="js-bottom"):
            yield Button("save to the config", id="js-save", compact=True, variant="primary")
        yield KeyBar()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        p = self.source()
        bid = event.button.id or ""
        if p is None or not p.connected:
            self.notify("no joystick connected", severity="warning")
            return
        if bid == "js-save":
            assert p.name is not None
            self.post_message(SaveMapping(p.mapping, p.name))
            return
        axis, what = _BY_ID[bid]
        p.state.mapping = edited(p.mapping, axis, what)
        p.state.reset()  # the next poll sends the stick as the new mapping reads it
