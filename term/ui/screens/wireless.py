"""The wireless screen: a view of the phone (``term.session.phone``: the report's Android app, Appendix A) for the
mouse.

A joystick pad (click or drag: roll and pitch; it springs back to the centre when let go, like the phone's), a lift
slider (click or drag; it stays where it is left), trim buttons, mode buttons, a PANIC button, and the telemetry
the phone showed: battery, mode, attitude, plus which link carries control. What a control does is the phone's
logic; these widgets turn mouse cells into its calls and post the requests it makes up to the app
(``PhoneRequest``), which flies them exactly as the keys would. Attributes down (the phone, the model), messages
up; nothing here calls the app.
"""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.containers import Grid, Horizontal, Vertical
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Button

from term.input.mapping import FULL
from term.session.model import Model
from term.session.phone import MODE_BUTTONS, TRIM_BUTTONS, Phone, Request, link_states, readout
from term.session.texts import BATTERY_FULL_V
from term.ui.widgets.bars import cbar, hbar
from term.ui.widgets.base import STALE_STYLE, ModelView, figure
from term.ui.widgets.battery import LEVEL_STYLE as BATTERY_STYLE
from term.ui.widgets.battery import LOW_END_V
from term.ui.widgets.events import EventsList
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner

LEVEL_STYLE = {"ok": "green", "active": "bold green", "info": "cyan", "warn": "yellow", "alarm": "bold white on red"}


class PhoneRequest(Message):
    """What a phone control asks for (``term.session.phone``'s requests, in order), for the app to carry out."""

    def __init__(self, requests: list[Request]) -> None:
        super().__init__()
        self.requests = tuple(requests)


def _axis(pos: int, size: int) -> int:
    """A cell in 0..size-1 to -FULL..FULL, the middle cell 0 (sizes are odd in practice; even ones lean +)."""
    if size <= 1:
        return 0
    half = (size - 1) / 2
    return max(-FULL, min(FULL, round((pos - half) / half * FULL)))


class _PhoneControl(ModelView, can_focus=False):
    def __init__(self, phone: Phone, *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id)
        self.phone = phone

    def render_model(self, model: Model, now: float) -> RenderableType:
        self.phone.follow(model.stick)
        return self.render()

    def _ask(self, requests: list[Request]) -> None:
        if requests:
            self.post_message(PhoneRequest(requests))
            self.refresh()


class StickPad(_PhoneControl):
    """Roll (left/right) and pitch (up is forward, nose down: negative pitch) from a click or a drag. It shows
    the stick the terminal sends (a hardware joystick's too) and springs back to the centre when let go."""

    DEFAULT_CSS = "StickPad { width: 1fr; height: 1fr; }"

    @property
    def roll(self) -> int:
        return self.phone.roll

    @property
    def pitch(self) -> int:
        return self.phone.pitch

    def _touch(self, x: int, y: int) -> None:
        w, h = self.content_size.width, self.content_size.height
        roll = _axis(max(0, min(w - 1, x)), w)
        pitch = _axis(max(0, min(h - 1, y)), h)  # down the screen is back: positive pitch
        self._ask(self.phone.touch(roll, pitch))

    def on_mouse_down(self, event: events.MouseDown) -> None:
        self.capture_mouse()
        self._touch(event.x, event.y)
        self.refresh()

    def on_mouse_move(self, event: events.MouseMove) -> None:
        if self.phone.touching:
            self._touch(event.x, event.y)

    def on_mouse_up(self, event: events.MouseUp) -> None:
        if not self.phone.touching:
            return
        self.release_mouse()
        self._ask(self.phone.release())
        self.refresh()

    def render(self) -> RenderableType:
        w, h = max(3, self.content_size.width), max(3, self.content_size.height)
        cx, cy = (w - 1) // 2, (h - 1) // 2
        px = round(cx + self.roll / FULL * ((w - 1) / 2))
        py = round(cy + self.pitch / FULL * ((h - 1) / 2))
        out = Text()
        for y in range(h):
            for x in range(w):
                if (x, y) == (px, py):
                    out.append("●", style="bold yellow" if self.phone.touching else "bold cyan")
                elif x == cx and y == cy:
                    out.append("┼", style="dim")
                elif x == cx:
                    out.append("│", style="dim")
                elif y == cy:
                    out.append("─", style="dim")
                else:
                    out.append(" ")
            if y < h - 1:
                out.append("\n")
        return out


class LiftSlider(_PhoneControl):
    """The lift, 0 at the bottom to full at the top: click or drag; it stays where it is left. It shows the lift the
    motors get: the stick the terminal sends (a hardware throttle's too) plus the board's lift trim (the keys' a/z),
    the trim's part in its own colour and said in the label (issue 34: it read 0 % while the craft hovered on a
    50.6 % trim). A click asks for the lift at that level: the stick is what the trim leaves to it."""

    DEFAULT_CSS = "LiftSlider { width: 1fr; height: 1fr; }"

    def __init__(self, phone: Phone, *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(phone, id=id)
        self.trim = 0  # the board's lift trim (Status), stick units

    @property
    def lift(self) -> int:
        return self.phone.lift

    @property
    def total(self) -> int:
        return max(0, min(FULL, self.lift + self.trim))

    def render_model(self, model: Model, now: float) -> RenderableType:
        self.trim = model.status.trim_lift if model.status is not None else 0
        return super().render_model(model, now)

    def _rows(self) -> int:
        return max(2, self.content_size.height - 1)  # the last row is the label

    def _slide(self, y: int) -> None:
        rows = self._rows()
        y = max(0, min(rows - 1, y))
        self._ask(self.phone.slide(max(0, round((rows - 1 - y) / (rows - 1) * FULL) - self.trim)))

    def on_mouse_down(self, event: events.MouseDown) -> None:
        self.capture_mouse()
        self._slide(event.y)

    def on_mouse_move(self, event: events.MouseMove) -> None:
        if self.phone.sliding:
            self._slide(event.y)

    def on_mouse_up(self, event: events.MouseUp) -> None:
        if self.phone.sliding:
            self.phone.let_go_lift()
            self.release_mouse()

    def render(self) -> RenderableType:
        rows, w = self._rows(), max(3, self.content_size.width)
        total = self.total
        level, trim_level = total / FULL * (rows - 1), max(0, min(FULL, self.trim)) / FULL * (rows - 1)
        out = Text()
        for y in range(rows):
            filled = (rows - 1 - y) <= level and total > 0
            trim_part = filled and self.trim > 0 and (rows - 1 - y) <= trim_level
            out.append(("█" if filled else "░") * w, style="cyan" if trim_part else "yellow" if filled else "dim")
            out.append("\n")
        label = f"{100 * total / FULL:.1f}%"
        if self.trim:
            label += f" trim {100 * self.trim / FULL:.1f}"
        out.append(label.center(w)[:max(w, len(label))], style="bold")
        return out


def link_lines(model: Model, out: Text, width: int | None = None) -> None:
    """Which link carries control, and each link's health, in a few lines (the link panel uses them too). With
    ``width`` (a narrow panel) each state loses its explanation in brackets first, then is cut to fit."""
    for ls in link_states(model):
        out.append("▶ " if ls.carries else "  ", style="bold")
        out.append(f"{ls.name:<6}", style="bold" if ls.carries else "")
        state = ls.state
        if width is not None and len(state) + 8 > width:
            state = state.split(" (", 1)[0][: max(4, width - 8)]
        out.append(state, style=LEVEL_STYLE[ls.level])
        out.append("\n")


class PhoneTelemetry(ModelView):
    """What the phone showed: battery, mode, attitude; and the links."""

    TIME_DEPENDENT = True
    MAX_HZ = 8.0

    def urgent(self, model: Model) -> object:
        return (model.mode, model.over_ble, model.control_lost, model.radio_up, model.wireless)

    def render_model(self, model: Model, now: float) -> RenderableType:
        r = readout(model, now)
        for reading in (r.battery, *r.attitude):
            self.readings[reading.name] = reading
        self.mark(r.battery, *r.attitude)
        out = Text()
        out.append("mode     ")
        out.append(r.mode, style="bold red" if r.panic else "bold")
        out.append(f"   wireless {r.wireless}\n", style="dim")
        out.append("battery  ")
        bat = r.battery
        if not bat.shown or bat.value is None:
            out.append("—\n", style="dim")
        else:
            style = STALE_STYLE if bat.stale else BATTERY_STYLE[r.battery_level]
            out.append_text(hbar(bat.value, LOW_END_V, BATTERY_FULL_V, 12, style))
            out.append_text(figure(bat, "5.2f", " V\n", style, pad=" "))
        phi, theta, psi = r.attitude
        if not phi.shown:
            out.append("attitude —\n", style="dim")
        else:
            bar = STALE_STYLE if phi.stale else "cyan"
            out.append("roll  ")
            out.append_text(figure(phi, "+6.1f", "° "))
            out.append_text(cbar(phi.value or 0.0, 30.0, 11, bar))
            out.append("\npitch ")
            out.append_text(figure(theta, "+6.1f", "° "))
            out.append_text(cbar(theta.value or 0.0, 30.0, 11, bar))
            out.append("\nyaw   ")
            out.append_text(figure(psi, "+6.1f", "°"))
            out.append("\n")
        link_lines(model, out)
        return out


class WirelessScreen(Screen[None]):
    """The phone's controls on one screen, for the mouse (F10, or the palette). ``term --ble`` opens here."""

    def __init__(self, phone: Phone | None = None) -> None:
        super().__init__()
        self.phone = phone or Phone()

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        with Horizontal(id="w-main"):
            with Vertical(id="w-pad") as pad:
                pad.border_title = "stick: click or drag"
                yield StickPad(self.phone, id="stick-pad")
            with Vertical(id="w-lift") as lift:
                lift.border_title = "lift"
                yield LiftSlider(self.phone, id="lift-slider")
            with Vertical(id="w-right"):
                yield Button("P A N I C   (1, ESC)", variant="error", id="btn-mode_panic")
                tel = PhoneTelemetry(id="w-telemetry")
                tel.border_title = "telemetry · links"
                yield tel
                with Grid(id="w-modes"):
                    for label, action in MODE_BUTTONS:
                        yield Button(label, variant="success" if action == "mode_safe" else "default",
                                     id=f"btn-{action}", compact=True)
                with Grid(id="w-trims"):
                    for label, action in TRIM_BUTTONS:
                        yield Button(label, id=f"btn-{action}", compact=True)
                with Horizontal(id="w-bottom"):
                    yield Button("hand over (8)", id="btn-handover", compact=True)
                    yield Button("back to cable", id="btn-handback", compact=True)
                ev = EventsList(id="w-events")
                ev.border_title = "events"
                yield ev
        yield KeyBar()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        bid = event.button.id or ""
        requests = self.phone.press(bid.removeprefix("btn-")) if bid.startswith("btn-") else []
        if requests:
            self.post_message(PhoneRequest(requests))
            self.query_one(LiftSlider).refresh()  # PANIC lets go of the lift at once
