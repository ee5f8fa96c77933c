"""The joystick through pygame, without a window: SDL's dummy video driver, its banner and its stderr kept off the
screen (a TUI owns the terminal). Polled by the app; the mapping itself is pure (``mapping.py``).

Hot-plug: a stick plugged in later is picked up, one pulled out is reported. With no stick (or no pygame at all)
``poll`` simply reports nothing and the keyboard alone flies.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from term.input.mapping import StickMapping, StickState, choose_mapping
from term.protocol import Joystick


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


def _import_pygame() -> Any:
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ["PYGAME_HIDE_SUPPORT_PROMPT"] = "1"
    # Without a focused window SDL would drop joystick events; we never have a window.
    os.environ.setdefault("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")
    with _quiet_stderr():
        import pygame

        pygame.display.init()  # the event queue needs the (dummy) video subsystem
        pygame.joystick.init()
    return pygame


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
        self._stick: Any = None
        self.name: str | None = None
        self.error: str | None = None

    @property
    def connected(self) -> bool:
        return self._stick is not None

    @property
    def mapping(self) -> StickMapping:
        return self.state.mapping

    def start(self) -> list[str]:
        """Initialise pygame; returns messages (a stick found, or why there is no joystick support)."""
        try:
            self._pg = _import_pygame()
        except Exception as exc:  # no SDL, no pygame: the keyboard still flies
            self.error = f"joystick support unavailable ({exc}); keyboard only"
            return [self.error]
        msgs: list[str] = []
        with _quiet_stderr():
            count = self._pg.joystick.get_count()
        if count:
            msgs.append(self._open(0))
        return msgs

    def _open(self, index: int) -> str:
        pg = self._pg
        with _quiet_stderr():
            stick = pg.joystick.Joystick(index)
            stick.init()
        self._stick = stick
        self.name = stick.get_name()
        self.state.mapping = self._forced or choose_mapping(self.name, self._custom)
        self.state.reset()
        return (f"joystick connected: {self.name} ({stick.get_numaxes()} axes, {stick.get_numbuttons()} buttons), "
                f"mapping {self.state.mapping.name}")

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
                    self._stick = None
                    self.name = None
                    self.state.reset()
                    res.packet = self.state.current
        stick = self._stick
        if stick is not None:
            axes = [stick.get_axis(i) for i in range(stick.get_numaxes())]
            buttons = [bool(stick.get_button(i)) for i in range(stick.get_numbuttons())]
            pkt = self.state.update(axes, buttons)
            if pkt is not None:
                res.packet = pkt
        return res

    def close(self) -> None:
        if self._pg is not None:
            with contextlib.suppress(Exception):
                self._pg.joystick.quit()
                self._pg.display.quit()
        self._pg = None
        self._stick = None
