"""The readiness panel, shown in SAFE (and before the board is heard): why the craft will not arm, before a key is
pressed. One line per check of ``term.session.readiness`` (green, or the one thing to do, in the pilot's own keys),
and on
top the next step: the first screen tells a new pilot to calibrate. A check the board refused a mode for is red
with the refusal, until it is fixed."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text

from term.core.protocol import Mode
from term.input.keymap import KeyBinding
from term.session.model import Model
from term.session.readiness import Check, checks, keys_for, next_step, ready
from term.ui.widgets.base import ModelView

ICON = {"ok": ("✔", "green"), "todo": ("✘", "bold yellow"), "wait": ("…", "dim"), "info": ("·", "cyan")}
SHOWN_IN = (None, Mode.SAFE, Mode.CALIBRATION)  # the modes the panel is shown in (None: no board yet)
_FIGURES = ("flags", "trim_roll", "trim_pitch", "trim_yaw", "trim_lift", "battery", "log_fill")


class ReadinessPanel(ModelView):
    """``keymap``: the pilot's keys, named in the fixes (with the board's step per key press, when the model knows
    it, as a count of presses)."""

    def __init__(self, keymap: tuple[KeyBinding, ...], *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id)
        self.keymap = keymap

    def render_model(self, model: Model, now: float) -> RenderableType:
        self.display = model.mode in SHOWN_IN or model.version_mismatch is not None
        self.screen.set_class(bool(self.display), "safe")  # the screen's layout gives the checks their rows
        for name in _FIGURES:  # redrawn when one of them goes stale
            self.read(model, name, now, figure=False)
        lift_step, trim_step = model.trim_steps()
        found = checks(model, now, self.keymap, lift_step=lift_step, trim_step=trim_step)
        out = Text()
        step = next_step(found)
        if model.link_name.startswith("REPLAY "):  # term replay: what the checks were, nothing to press
            return self._as_recorded(found)
        if step is not None:
            out.append("next: ", style="bold")
            out.append(f"{step.step}\n", style="bold yellow")
        elif ready(found):
            keys = ", ".join(f"{keys_for(self.keymap, f'mode_{m}')} {m.upper()}" for m in ("manual", "full"))
            out.append(f"ready to fly: {keys}, …\n", style="bold green")
        else:  # nothing to do, something not known yet: say what, not a vague wait
            waiting = ", ".join(c.label for c in found if c.state == "wait")
            out.append(f"waiting to hear: {waiting}\n", style="dim")
        for c in found:
            icon, style = ICON[c.state]
            if c.refused:
                icon, style = "✘", "bold red"
            out.append(f"{icon} ", style=style)
            out.append(f"{c.label:<16}", style="" if c.state != "wait" else "dim")
            out.append(c.text, style=style if c.state != "ok" else "")
            out.append("\n")
        out.rstrip()
        return out

    def _as_recorded(self, found: list[Check]) -> Text:
        out = Text("as recorded: the checks as the pilot saw them (a recording flies nothing)\n", style="dim")
        for c in found:
            icon, style = ICON[c.state]
            out.append(f"{icon} ", style=style)
            out.append(f"{c.label:<16}", style="" if c.state != "wait" else "dim")
            out.append({"ok": "ok", "todo": "not ready", "wait": "not known", "info": "noted"}[c.state], style="dim")
            out.append("\n")
        out.rstrip()
        return out
