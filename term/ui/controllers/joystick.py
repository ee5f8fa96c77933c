"""The joystick in the app: started after the first screen (SDL's start-up is slow), polled at ``joystick_hz``; a
joystick lost in flight is PANIC; the joystick screen's "save" writes the mapping into the config file as the
device's own (term.session.config, with tomlkit: the rest of the file is kept as it was).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from term.core.events import JoystickNamed
from term.core.protocol import Joystick, Mode, Op
from term.input.joystick import JoystickPoller
from term.input.mapping import StickMapping
from term.session.config import Config
from term.session.station import Station


class JoystickController:
    """The poller and what its readings do. ``send`` and ``set_stick`` are the app's paths (a key's, the stick's);
    ``every(interval, callback)`` is the app's timer."""

    def __init__(self, station: Station, config: Config, send: Callable[[Op, int], Any],
                 set_stick: Callable[[Joystick], None], every: Callable[[float, Callable[[], None]], Any],
                 hz: float) -> None:
        self.station = station
        self.config = config
        self.send = send
        self.set_stick = set_stick
        self.every = every
        self.hz = hz
        self.poller: JoystickPoller | None = None

    def start(self) -> None:
        from term.session.config import forced_mapping

        poller = JoystickPoller(self.config.joystick_mappings, resolution=self.config.joystick_resolution,
                                forced=forced_mapping(self.config))
        for msg in poller.start():
            self.station.note("info", "joystick", msg)
        self.poller = poller
        if poller.name:
            self.station.emit(JoystickNamed(poller.name, poller.mapping.name))
        self.every(1.0 / self.hz, self.poll)

    def poll(self) -> None:
        if self.poller is None:
            return
        res = self.poller.poll()
        for msg in res.messages:
            self.station.note("warning" if res.disconnected else "info", "joystick", msg)
        if res.messages:
            self.station.emit(JoystickNamed(self.poller.name, self.poller.mapping.name if self.poller.name else ""))
        if res.disconnected and self.station.model.flying:
            self.station.note("error", "joystick", "joystick lost in flight: PANIC")
            self.send(Op.MODE, Mode.PANIC)
        if res.packet is not None:
            self.set_stick(res.packet)

    def save_mapping(self, mapping: StickMapping, device: str) -> None:
        """The joystick screen's "save": the mapping into the config file as ``device``'s own."""
        from term.session.config import ConfigError, default_path, save_joystick_mapping

        path = self.config.source or default_path()
        try:
            name = save_joystick_mapping(path, mapping, device)
        except ConfigError as exc:
            self.station.note("error", "joystick", str(exc))
            return
        mine = replace(mapping, name=name, match=(device,))
        self.config.joystick_mappings = (*(m for m in self.config.joystick_mappings if m.name != name), mine)
        if self.poller is not None:
            self.poller.state.mapping = mine
            self.station.emit(JoystickNamed(self.poller.name, name))
        self.station.note("info", "joystick", f"joystick mapping saved to {path} as [joystick.mappings.{name}]")

    def close(self) -> None:
        if self.poller is not None:
            self.poller.close()
            self.poller = None
