"""The motor test screen (Ctrl+O, after a "props off?" question): spin one motor or all at a chosen level, to
check wiring, order and direction on the bench (term/ui/controllers/motortest.py; the board's guards:
docs/modes.md, "The motor test").

Its keys are its own while it shows (``TYPING``: in SAFE the pilot's character keys do not fly): 1-4 pick a motor,
``a`` all four, ``+``/``-`` the level, Enter or ``s`` starts. While motors turn, ANY key stops them (the app tells
the controller before anything else sees the key), and so does leaving the screen (Esc, an F-key) or a lost link.
The motor bars show what the board commands (its Motion telemetry): the turning motor is seen there, as on the
flight screen's motors and the room view.
"""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.screen import Screen

from term.core.protocol import MOTOR_TEST_MAX_LEVEL, MOTOR_TEST_MAX_MS
from term.session.model import Model
from term.ui.controllers.motortest import MotorTestController
from term.ui.screens.flight import panel
from term.ui.widgets.base import ModelView
from term.ui.widgets.events import EventsList
from term.ui.widgets.keybar import KeyBar
from term.ui.widgets.mode import ModeBanner
from term.ui.widgets.motors import MotorBars

LEVEL_STEP = 10
DEFAULT_LEVEL = 150
MOTOR_NAMES = ("ae1 front", "ae2 right", "ae3 back", "ae4 left")


def mask_text(mask: int) -> str:
    if mask == 0xF:
        return "all four motors"
    return ", ".join(name for i, name in enumerate(MOTOR_NAMES) if mask & (1 << i)) or "none"


class MotorTestPanel(ModelView):
    """The test's state: the choice, running or why it ended, the keys."""

    TIME_DEPENDENT = True

    def __init__(self, screen: MotorTestScreen, **kw: object) -> None:
        super().__init__(**kw)  # type: ignore[arg-type]
        self.owner = screen

    def render_model(self, model: Model, now: float) -> RenderableType:
        s, c = self.owner, self.owner.controller
        out = Text()
        out.append("PROPS OFF. ", style="bold red")
        out.append(f"SAFE only; at most {MOTOR_TEST_MAX_MS / 1000:g} s a run; level at most {MOTOR_TEST_MAX_LEVEL} "
                   "(under hover).\n\n")
        out.append("motor  ", style="dim")
        out.append(mask_text(s.mask), style="bold")
        out.append("    level  ", style="dim")
        out.append(f"{s.level}", style="bold")
        out.append("\n\n")
        if c.running:
            left = max(0.0, MOTOR_TEST_MAX_MS / 1000 - (now - c.started))
            out.append(f"SPINNING {mask_text(c.mask)} at {c.level}: ", style="bold yellow")
            out.append(f"{left:.1f} s left. ANY KEY STOPS.", style="bold")
        else:
            why = c.refusal(model)
            if why is not None:
                out.append(f"cannot start: {why}", style="red")
            else:
                out.append("ready", style="green")
            if c.last_end:
                out.append(f"   (last run: {c.last_end})", style="dim")
        out.append("\n\n1 2 3 4 one motor · a all four · + − level · Enter or s start · any key stops · Esc back",
                   style="dim")
        return out


class MotorTestScreen(Screen[None]):
    TYPING = True  # the pilot's character keys are this screen's (keygate): 1-4 pick a motor, not a mode

    def __init__(self, controller: MotorTestController) -> None:
        super().__init__()
        self.controller = controller
        self.mask = 0x1  # ae1 front
        self.level = DEFAULT_LEVEL

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        yield panel(MotorTestPanel(self), "motor test · props off", "motortest")
        yield panel(MotorBars(), "motors (what the board commands)", "motortest-motors")
        yield panel(EventsList(), "events · errors", "events-small")
        yield KeyBar()

    def on_key(self, event: events.Key) -> None:
        key = event.key
        if key in ("1", "2", "3", "4"):
            self.mask = 1 << (int(key) - 1)
        elif key == "a":
            self.mask = 0xF
        elif key in ("plus", "equals_sign", "+", "="):
            self.level = min(MOTOR_TEST_MAX_LEVEL, self.level + LEVEL_STEP)
        elif key in ("minus", "-"):
            self.level = max(LEVEL_STEP, self.level - LEVEL_STEP)
        elif key in ("enter", "s"):
            self.controller.start(self.app.model, self.mask, self.level)  # type: ignore[attr-defined]
        elif key == "escape":
            self.app.pop_screen()
        else:
            return
        event.stop()
        self.app.call_later(self.app.render_now)  # type: ignore[attr-defined]

    def on_screen_suspend(self) -> None:
        self.controller.stop("left the motor test screen")

    def on_unmount(self) -> None:
        self.controller.stop("left the motor test screen")
