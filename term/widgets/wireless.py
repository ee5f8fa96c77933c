"""The wireless screen: the phone's controls (the report's Android app, Appendix A) for the mouse.

A joystick pad (click or drag: roll and pitch; it springs back to the centre when let go, like the phone's), a lift
slider (click or drag; it stays where it is left), trim buttons, mode buttons, a PANIC button, and the telemetry
the phone showed: battery, mode, attitude, plus which link carries control. Widgets post messages up; the screen
turns them into the app's own calls (``send``, ``perform``, ``set_screen_stick``), so a click flies exactly what
the key would.
"""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.containers import Grid, Horizontal, Vertical
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Button, Footer

from term.input.mapping import FULL
from term.model import Model, mode_name
from term.protocol import Mode, Op, WirelessState
from term.widgets.bars import cbar, hbar
from term.widgets.base import ModelView
from term.widgets.events import EventsList
from term.widgets.mode import ModeBanner


def _axis(pos: int, size: int) -> int:
    """A cell in 0..size-1 to -FULL..FULL, the middle cell 0 (sizes are odd in practice; even ones lean +)."""
    if size <= 1:
        return 0
    half = (size - 1) / 2
    return max(-FULL, min(FULL, round((pos - half) / half * FULL)))


class StickPad(ModelView, can_focus=False):
    """Roll (left/right) and pitch (up is forward, nose down: negative pitch) from a click or a drag. It shows
    the stick the terminal sends (a hardware joystick's too) and springs back to the centre when let go."""

    DEFAULT_CSS = "StickPad { width: 1fr; height: 1fr; }"

    class Moved(Message):
        def __init__(self, roll: int, pitch: int) -> None:
            super().__init__()
            self.roll = roll
            self.pitch = pitch

    def __init__(self, *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id)
        self.roll = 0
        self.pitch = 0
        self._dragging = False

    def render_model(self, model: Model, now: float) -> RenderableType:
        if not self._dragging:
            self.roll, self.pitch = model.stick.roll, model.stick.pitch
        return self.render()

    def _set_from(self, x: int, y: int) -> None:
        w, h = self.content_size.width, self.content_size.height
        roll = _axis(max(0, min(w - 1, x)), w)
        pitch = _axis(max(0, min(h - 1, y)), h)  # down the screen is back: positive pitch
        if (roll, pitch) != (self.roll, self.pitch):
            self.roll, self.pitch = roll, pitch
            self.post_message(self.Moved(roll, pitch))
            self.refresh()

    def on_mouse_down(self, event: events.MouseDown) -> None:
        self._dragging = True
        self.capture_mouse()
        self._set_from(event.x, event.y)

    def on_mouse_move(self, event: events.MouseMove) -> None:
        if self._dragging:
            self._set_from(event.x, event.y)

    def on_mouse_up(self, event: events.MouseUp) -> None:
        if not self._dragging:
            return
        self._dragging = False
        self.release_mouse()
        self.recentre()

    def recentre(self) -> None:
        if (self.roll, self.pitch) != (0, 0):
            self.roll = self.pitch = 0
            self.post_message(self.Moved(0, 0))
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
                    out.append("●", style="bold yellow" if self._dragging else "bold cyan")
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


class LiftSlider(ModelView, can_focus=False):
    """The lift, 0 at the bottom to full at the top: click or drag; it stays where it is left. It shows the lift
    the terminal sends (a hardware throttle's too)."""

    DEFAULT_CSS = "LiftSlider { width: 1fr; height: 1fr; }"

    class Changed(Message):
        def __init__(self, lift: int) -> None:
            super().__init__()
            self.lift = lift

    def __init__(self, *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id)
        self.lift = 0
        self._dragging = False

    def render_model(self, model: Model, now: float) -> RenderableType:
        if not self._dragging:
            self.lift = model.stick.lift
        return self.render()

    def _rows(self) -> int:
        return max(2, self.content_size.height - 1)  # the last row is the label

    def set_lift(self, lift: int, *, post: bool = True) -> None:
        lift = max(0, min(FULL, lift))
        if lift != self.lift:
            self.lift = lift
            if post:
                self.post_message(self.Changed(lift))
            self.refresh()

    def _set_from(self, y: int) -> None:
        rows = self._rows()
        y = max(0, min(rows - 1, y))
        self.set_lift(round((rows - 1 - y) / (rows - 1) * FULL))

    def on_mouse_down(self, event: events.MouseDown) -> None:
        self._dragging = True
        self.capture_mouse()
        self._set_from(event.y)

    def on_mouse_move(self, event: events.MouseMove) -> None:
        if self._dragging:
            self._set_from(event.y)

    def on_mouse_up(self, event: events.MouseUp) -> None:
        if self._dragging:
            self._dragging = False
            self.release_mouse()

    def render(self) -> RenderableType:
        rows, w = self._rows(), max(3, self.content_size.width)
        level = self.lift / FULL * (rows - 1)
        out = Text()
        for y in range(rows):
            filled = (rows - 1 - y) <= level and self.lift > 0
            out.append(("█" if filled else "░") * w, style="yellow" if filled else "dim")
            out.append("\n")
        out.append(f"{100 * self.lift / FULL:3.0f}%".center(w), style="bold")
        return out


def _link_line(out: Text, name: str, state: str, style: str, carries: bool) -> None:
    out.append("▶ " if carries else "  ", style="bold")
    out.append(f"{name:<6}", style="bold" if carries else "")
    out.append(state, style=style)
    out.append("\n")


def link_lines(model: Model, out: Text) -> None:
    """Which link carries control, and each link's health, in a few lines (the link panel uses them too)."""
    s = model.link
    over_ble = model.over_ble
    primary = "ble" if model.primary_ble else "cable"
    if model.primary_ble and not model.heard:
        state, style = "connected: waiting for the handover (8 on the cable terminal)", "yellow"
    elif s is None or s.since_last_frame_s is None:
        state, style = "waiting for the board…", "yellow"
    elif model.link_lost and model.radio_name and over_ble:
        state, style = "silent: flying over BLE", "cyan"
    elif model.link_lost:
        state, style = "LINK LOST", "bold white on red"
    else:
        rtt = "" if s.rtt_last_ms is None else f", RTT {s.rtt_last_ms:.0f} ms"
        state, style = f"OK{rtt}", "green"
    _link_line(out, primary, state, style, carries=not model.radio_name or not over_ble)
    if not model.radio_name:
        return
    r = model.radio
    if not model.radio_up:
        state, style = model.radio_note or "not connected", "yellow"
    elif model.radio_lost:
        state, style = "BLE LINK LOST", "bold white on red"
    elif model.wireless == WirelessState.STARTED:
        rtt = "" if r is None or r.rtt_last_ms is None else f", RTT {r.rtt_last_ms:.0f} ms"
        state, style = f"flying over BLE{rtt}", "bold green"
    elif model.wireless == WirelessState.STARTING:
        state, style = "STARTING: answering the board's heartbeats", "yellow"
    else:
        state, style = "connected, idle (8 in SAFE hands over)", "green"
    _link_line(out, "ble", state, style, carries=over_ble)


class PhoneTelemetry(ModelView):
    """What the phone showed: battery, mode, attitude; and the links."""

    TIME_DEPENDENT = True
    MAX_HZ = 8.0

    def urgent(self, model: Model) -> object:
        return (model.mode, model.over_ble, model.control_lost, model.radio_up, model.wireless)

    def render_model(self, model: Model, now: float) -> RenderableType:
        out = Text()
        out.append("mode     ")
        out.append(mode_name(model.mode), style="bold red" if model.mode == Mode.PANIC else "bold")
        try:
            ws = WirelessState(model.wireless).name
        except ValueError:
            ws = str(model.wireless)
        out.append(f"   wireless {ws}\n", style="dim")
        v = model.battery_v
        out.append("battery  ")
        if v is None:
            out.append("—\n", style="dim")
        else:
            style = "bold red" if v < 10.5 else "yellow" if v < 11.1 else "green"
            out.append_text(hbar(v, 10.0, 12.6, 12, style))
            out.append(f" {v:5.2f} V\n", style=style)
        if model.over_ble and model.compact is not None:
            c = model.compact
            phi, theta, psi = c.phi / 100, c.theta / 100, c.psi / 100
        elif model.attitude is not None:
            a = model.attitude
            phi, theta, psi = a.phi / 100, a.theta / 100, a.psi / 100
        else:
            phi = theta = psi = None
        if phi is None:
            out.append("attitude —\n", style="dim")
        else:
            out.append(f"roll  {phi:+6.1f}° ")
            out.append_text(cbar(phi, 30.0, 11))
            out.append(f"\npitch {theta:+6.1f}° ")
            out.append_text(cbar(theta, 30.0, 11))
            out.append(f"\nyaw   {psi:+6.1f}°\n")
        link_lines(model, out)
        return out


MODE_BUTTONS = (
    ("SAFE", "mode_safe", "success"),
    ("MANUAL", "mode_manual", "default"),
    ("CALIB", "mode_calibration", "default"),
    ("YAW", "mode_yaw", "default"),
    ("FULL", "mode_full", "default"),
    ("RAW", "mode_raw", "default"),
    ("HEIGHT", "mode_height", "default"),
)
TRIM_BUTTONS = (  # (label, key-map action): the same actions as the keys, so trims step alike
    ("roll ◀", "roll_up"), ("roll ▶", "roll_down"),
    ("pitch ▲", "pitch_down"), ("pitch ▼", "pitch_up"),
    ("yaw ↺", "yaw_down"), ("yaw ↻", "yaw_up"),
    ("lift −", "lift_down"), ("lift +", "lift_up"),
)


class WirelessScreen(Screen[None]):
    """The phone's controls on one screen, for the mouse (F10, or the palette). ``term --ble`` opens here."""

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        with Horizontal(id="w-main"):
            with Vertical(id="w-pad") as pad:
                pad.border_title = "stick: click or drag"
                yield StickPad(id="stick-pad")
            with Vertical(id="w-lift") as lift:
                lift.border_title = "lift"
                yield LiftSlider(id="lift-slider")
            with Vertical(id="w-right"):
                yield Button("P A N I C   (1, ESC)", variant="error", id="btn-mode_panic")
                tel = PhoneTelemetry(id="w-telemetry")
                tel.border_title = "telemetry · links"
                yield tel
                with Grid(id="w-modes"):
                    for label, action, variant in MODE_BUTTONS:
                        yield Button(label, variant=variant, id=f"btn-{action}", compact=True)  # type: ignore[arg-type]
                with Grid(id="w-trims"):
                    for label, action in TRIM_BUTTONS:
                        yield Button(label, id=f"btn-{action}", compact=True)
                with Horizontal(id="w-bottom"):
                    yield Button("hand over (8)", id="btn-handover", compact=True)
                    yield Button("back to cable", id="btn-handback", compact=True)
                ev = EventsList(id="w-events")
                ev.border_title = "events"
                yield ev
        yield Footer()

    def on_mount(self) -> None:
        self.query_one(LiftSlider).set_lift(self.app.model.stick.lift, post=False)  # type: ignore[attr-defined]

    def on_screen_resume(self) -> None:
        self.query_one(LiftSlider).set_lift(self.app.model.stick.lift, post=False)  # type: ignore[attr-defined]

    def on_button_pressed(self, event: Button.Pressed) -> None:
        app = self.app
        bid = event.button.id or ""
        event.stop()
        if bid == "btn-handover":
            app.send(Op.WIRELESS, 1)  # type: ignore[attr-defined]
        elif bid == "btn-handback":
            app.send(Op.WIRELESS, 0)  # type: ignore[attr-defined]
        elif bid.startswith("btn-"):
            app.action_pilot(bid[4:])  # type: ignore[attr-defined]
            if bid == "btn-mode_panic":  # as the phone: PANIC lets go of the lift too
                self.query_one(LiftSlider).set_lift(0, post=False)
                app.set_screen_stick(lift=0)  # type: ignore[attr-defined]

    def on_stick_pad_moved(self, message: StickPad.Moved) -> None:
        self.app.set_screen_stick(roll=message.roll, pitch=message.pitch)  # type: ignore[attr-defined]

    def on_lift_slider_changed(self, message: LiftSlider.Changed) -> None:
        self.app.set_screen_stick(lift=message.lift)  # type: ignore[attr-defined]
