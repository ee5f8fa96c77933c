"""A recording played instead of a flight (``term replay``): the wall time since the last step plays it on, seeks
jump (back: a fresh model brought forward to the point), and the pilot's replay keys pause, speed it up or down.
The link panel says it is a replay; a ``term --sim`` recording's truth moves the room view.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from term.data.recording import TruthSample
from term.data.replay import Replay
from term.lessons.instructor import truth_from
from term.lessons.room import Room
from term.session.model import Model
from term.session.station import Station

SEEK_S = 5.0  # what the left and right keys jump


class ReplayController:
    """Plays ``replay`` into the station (its events reach the model as a link's would); ``redraw`` is the app's."""

    def __init__(self, replay: Replay, station: Station, redraw: Callable[[], None],
                 wall: Callable[[], float] = time.monotonic, room: Room | None = None) -> None:
        """``room``: the room view's, fed the recorded truth (a ``term --sim`` recording: where the craft was)."""
        self.replay = replay
        self.station = station
        self.redraw = redraw
        self.wall = wall
        self.room = room
        self._last_wall: float | None = None

    def _play(self, events: Iterable[Any]) -> None:
        for ev in events:
            if type(ev) is TruthSample:
                truth = truth_from(ev.data) if isinstance(ev.data, dict) else None
                if truth is not None and self.room is not None:
                    self.room.update(truth)
            else:
                self.station.emit(ev)

    def step(self) -> str:
        """Play on by the wall time since the last step; the replay's status (for the app's subtitle)."""
        replay = self.replay
        wall = self.wall()
        dt, self._last_wall = (0.0 if self._last_wall is None else wall - self._last_wall), wall
        self._play(replay.advance(dt))
        self._name_link()
        return replay.status()

    def seek(self, t: float) -> None:
        """Jump to ``t`` s into the recording (back: a fresh model brought forward to it)."""
        replay = self.replay
        if replay.seek(t):
            old = self.station.model
            self.station.model = Model(start=0.0, radio_name=old.radio_name, primary_ble=old.primary_ble)
        self._play(replay.catch_up())
        self._name_link()
        self.redraw()

    def act(self, what: str) -> str:
        """A replay key: pause, faster, slower, back, forward, start; the status after it."""
        replay = self.replay
        if what == "pause":
            replay.paused = not replay.paused
        elif what == "faster":
            replay.faster()
        elif what == "slower":
            replay.slower()
        elif what in ("back", "forward"):
            self.seek(replay.position + (SEEK_S if what == "forward" else -SEEK_S))
        elif what == "start":
            self.seek(0.0)
        return replay.status()

    def _name_link(self) -> None:
        self.station.model.link_name = f"{self.replay.status()}  {Path(self.replay.source).name}"
