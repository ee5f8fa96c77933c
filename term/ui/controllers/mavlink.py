"""A MAVLink ground station in the app (``term --mavlink``): the endpoint (term/data/mavlink.py) attached to the
station when the app mounts (its commands run on the display's loop), its ticks and the station's events handed
on, the pilot's own commands taking control back, and the palette's two commands (hand control to the ground
station, take it back). Without ``--mavlink`` every call does nothing."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterable
from typing import Any

from textual.app import SystemCommand


class MavlinkControl:
    """The endpoint (or None) of ``term --mavlink`` for one app: ``notify`` shows a refusal as a toast."""

    def __init__(self, endpoint: Any, station: Any, notify: Callable[..., Any]) -> None:
        self.endpoint = endpoint
        self.station = station
        self.notify = notify

    def start(self, start_download: Callable[[], None]) -> None:
        """Attach the endpoint to the station (its commands run on this loop), start it, say where it sends."""
        mav = self.endpoint
        if mav is None:
            return
        loop = asyncio.get_running_loop()
        mav.attach(self.station, lambda fn, *args: loop.call_soon_threadsafe(fn, *args), start_download)
        mav.start()
        self.station.note("info", "mavlink", f"MAVLink: sending the flight to {mav.url} (palette: hand control)")

    def tick(self, now: float) -> None:
        if self.endpoint is not None:
            self.endpoint.tick(now)

    def station_event(self, ev: Any) -> None:
        if self.endpoint is not None:
            self.endpoint.station_event(ev)

    def pilot_command(self) -> None:
        """The pilot commanded the board from term: a ground station that was handed control gives it back."""
        if self.endpoint is not None:
            self.endpoint.pilot_command()

    def handover(self) -> None:
        why = self.endpoint.handover() if self.endpoint is not None else "no --mavlink"
        if why is not None:
            self.station.note("error", "mavlink", f"not handed over: {why}")
            self.notify(why, title="MAVLink handover", severity="warning")

    def commands(self) -> Iterable[SystemCommand]:
        if self.endpoint is not None:
            yield SystemCommand("MAVLink: hand control to the ground station", f"{self.endpoint.url}: its "
                                "MANUAL_CONTROL flies (in SAFE; any key of yours takes it back)", self.handover)
            yield SystemCommand("MAVLink: take control back", "from the ground station", self.endpoint.handback)
