"""The joystick through pygame-ce, without a window: SDL's dummy video driver, its banner and its stderr kept off
the screen (a TUI owns the terminal). Polled by the app; the mapping itself is pure (``mapping.py``).

Two ways to read a device, chosen when it is plugged in:
- a game pad SDL knows (its GameController database: Xbox, PlayStation, Switch and hundreds more) is read
  through SDL's GameController API, whose axes and buttons sit in the same places on every pad: ``PAD_AXES``
  and ``PAD_BUTTONS`` below, flown with ``GAMEPAD`` (mode 2: left stick yaw and lift, right stick roll and
  pitch, A or cross is fire) whatever the pad's raw layout;
- anything else (a flight stick such as the lab's Logitech, a pad SDL does not know) as raw axes and buttons,
  with the mapping picked by the device's name (``mapping.choose_mapping``).
A mapping forced in the config, or a config mapping matching the device's name, always reads raw axes: the
user's axis numbers are the device's own.

Hot-plug: a stick plugged in later is picked up, one pulled out is reported. With no stick (or no pygame at all)
``poll`` simply reports nothing and the keyboard alone flies.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from term.core.protocol import Joystick
from term.input.mapping import AxisMap, StickMapping, StickState, choose_mapping

# SDL's GameController layout, as indices into the axes and buttons handed to the mapping
PAD_AXES = ("LEFTX", "LEFTY", "RIGHTX", "RIGHTY", "TRIGGERLEFT", "TRIGGERRIGHT")
PAD_BUTTONS = ("A", "B", "X", "Y", "BACK", "GUIDE", "START", "LEFTSTICK", "RIGHTSTICK", "LEFTSHOULDER",
               "RIGHTSHOULDER", "DPAD_UP", "DPAD_DOWN", "DPAD_LEFT", "DPAD_RIGHT")
PAD_FULL = 32767  # the GameController API's axes are -32768..32767 (triggers 0..32767)

GAMEPAD = StickMapping(
    "game controller (mode 2)", (),
    roll=AxisMap(2, deadzone=0.08),
    pitch=AxisMap(3, deadzone=0.08),
    yaw=AxisMap(0, deadzone=0.1),
    lift=AxisMap(1, deadzone=0.05, kind="half"),
    fire=(0,),
)


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Silence fd 2 (C-level: SDL and ALSA print there) for the block; Python's own stderr is untouched."""
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _import_pygame() -> tuple[Any, Any]:
    """pygame (pygame-ce) with its joystick subsystem, and its GameController module (None if it has none)."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ["PYGAME_HIDE_SUPPORT_PROMPT"] = "1"
    # Without a focused window SDL would drop joystick events; we never have a window.
    os.environ.setdefault("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")
    with _quiet_stderr():
        import pygame

        pygame.display.init()  # the event queue needs the (dummy) video subsystem
        pygame.joystick.init()
        try:
            from pygame._sdl2 import controller

            controller.init()
        except Exception:  # a pygame without it: every device is read raw
            controller = None
    return pygame, controller


class _Pad:
    """A device read through SDL's GameController API, in the ``PAD_AXES``/``PAD_BUTTONS`` order."""

    def __init__(self, pg: Any, pad: Any) -> None:
        self._pad = pad
        self._axes = [getattr(pg, f"CONTROLLER_AXIS_{n}") for n in PAD_AXES]
        self._buttons = [getattr(pg, f"CONTROLLER_BUTTON_{n}") for n in PAD_BUTTONS]

    def read(self) -> tuple[list[float], list[bool]]:
        axes = [max(-1.0, min(1.0, self._pad.get_axis(a) / PAD_FULL)) for a in self._axes]
        return axes, [bool(self._pad.get_button(b)) for b in self._buttons]


class _Raw:
    """A device read as raw joystick axes and buttons."""

    def __init__(self, stick: Any) -> None:
        self._stick = stick

    def read(self) -> tuple[list[float], list[bool]]:
        s = self._stick
        return ([s.get_axis(i) for i in range(s.get_numaxes())],
                [bool(s.get_button(i)) for i in range(s.get_numbuttons())])


@dataclass
class PollResult:
    packet: Joystick | None = None  # the new stick value if it changed
    messages: list[str] = field(default_factory=list)  # plugged in / pulled out, for the events list
    disconnected: bool = False  # the active stick was just pulled out


class JoystickPoller:
    """One active stick at a time; ``poll()`` from the app's timer (it never blocks)."""

    def __init__(self, custom: Iterable[StickMapping] = (), *, resolution: int = 64,
                 forced: StickMapping | None = None) -> None:
        self._custom = tuple(custom)
        self._forced = forced
        self.state = StickState(resolution=resolution)
        self._pg: Any = None
        self._controller: Any = None  # pygame._sdl2.controller, if there
        self._stick: Any = None  # the pygame Joystick of the active device (its instance id, its name)
        self._reader: _Pad | _Raw | None = None
        self.name: str | None = None
        self.gamepad = False  # the active device is read through the GameController API
        self.error: str | None = None
        self.axes: list[float] = []  # the last raw read (-1..1), for the joystick screen
        self.buttons: list[bool] = []

    @property
    def connected(self) -> bool:
        return self._stick is not None

    @property
    def mapping(self) -> StickMapping:
        return self.state.mapping

    def start(self) -> list[str]:
        """Initialise pygame; returns messages (a stick found, or why there is no joystick support)."""
        try:
            self._pg, self._controller = _import_pygame()
        except Exception as exc:  # no SDL, no pygame: the keyboard still flies
            self.error = f"joystick support unavailable ({exc}); keyboard only"
            return [self.error]
        msgs: list[str] = []
        with _quiet_stderr():
            count = self._pg.joystick.get_count()
        if count:
            msgs.append(self._open(0))
        return msgs

    def _user_mapping(self, name: str) -> StickMapping | None:
        if self._forced is not None:
            return self._forced
        low = name.lower()
        return next((m for m in self._custom if any(s.lower() in low for s in m.match if s)), None)

    def _open(self, index: int) -> str:
        pg, ctl = self._pg, self._controller
        with _quiet_stderr():
            stick = pg.joystick.Joystick(index)  # open on creation (init() is deprecated in pygame-ce)
            name = stick.get_name()
            mine = self._user_mapping(name)
            pad = None
            if mine is None and ctl is not None:
                with contextlib.suppress(Exception):
                    if ctl.is_controller(index):
                        pad = ctl.Controller(index)
        self._stick = stick
        self.name = name
        self.gamepad = pad is not None
        self._reader = _Pad(pg, pad) if pad is not None else _Raw(stick)
        self.state.mapping = mine or (GAMEPAD if pad is not None else choose_mapping(name, self._custom))
        self.state.reset()
        how = ("game controller, SDL's standard layout" if pad is not None
               else f"{stick.get_numaxes()} axes, {stick.get_numbuttons()} buttons")
        return f"joystick connected: {self.name} ({how}), mapping {self.state.mapping.name}"

    def poll(self) -> PollResult:
        res = PollResult()
        pg = self._pg
        if pg is None:
            return res
        for ev in pg.event.get():
            if ev.type == pg.JOYDEVICEADDED and self._stick is None:
                res.messages.append(self._open(ev.device_index))
            elif ev.type == pg.JOYDEVICEREMOVED and self._stick is not None:
                if ev.instance_id == self._stick.get_instance_id():
                    res.messages.append(f"joystick disconnected: {self.name}")
                    res.disconnected = True
                    self._stick = self._reader = None
                    self.axes, self.buttons = [], []
                    self.name = None
                    self.gamepad = False
                    self.state.reset()
                    res.packet = self.state.current
        if self._reader is not None:
            axes, buttons = self._reader.read()
            self.axes, self.buttons = axes, buttons
            pkt = self.state.update(axes, buttons)
            if pkt is not None:
                res.packet = pkt
        return res

    def close(self) -> None:
        if self._pg is not None:
            with contextlib.suppress(Exception):
                if self._controller is not None:
                    self._controller.quit()
                self._pg.joystick.quit()
                self._pg.display.quit()
        self._pg = self._controller = None
        self._stick = self._reader = None
