"""Where a session goes besides the screen: the recording (term.data.recording) and the live Foxglove server
(term.data.foxglove_server). Each station event goes to both; the events list's new lines too (what the pilot
read), each once; in ``--sim`` the simulator's truth too; in a replay the packets go to the live server (no
transport taps there). A recording that can no longer be written is said once, and the flight goes on.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from term.core.events import FromLink, StationEvent
from term.core.link import PacketReceived
from term.data.recording import SessionRecorder
from term.session.station import Station


class SessionOutputs:
    """The recording and the live server of one session (either may be None)."""

    def __init__(self, station: Station, clock: Callable[[], float], recorder: SessionRecorder | None,
                 live: Any, replaying: bool) -> None:
        self.station = station
        self.clock = clock
        self.recorder = recorder
        self.live = live
        self.replaying = replaying
        self._noted = 0  # the seq of the last events-list entry written
        self._error_said = False

    def recording_failed(self) -> None:
        """The recording's failure, said at once: an alarm in the mode banner and a line (the flight goes on)."""
        rec = self.recorder
        if rec is not None and rec.error and not self._error_said:
            self._error_said = True
            self.station.model.recording_error = rec.error
            self.station.note("error", "term", rec.error)

    def station_event(self, ev: StationEvent) -> None:
        now = self.clock()
        if self.recorder is not None:
            self.recorder.station_event(ev, now)
        if self.live is not None:
            self.live.station_event(ev, now)
            if self.replaying and type(ev) is FromLink and type(ev.event) is PacketReceived:
                self.live.packet(ev.link, "rx", ev.event.packet, now)
        self.notes(now)

    def truth(self, truth: Any) -> None:
        """A sample of the simulator's truth (``--sim``'s instructor channel): recorded and served beside the
        board's estimate, at the same time."""
        now = self.clock()
        for sink in (self.recorder, self.live):
            if sink is not None:
                sink.truth(truth, now)

    def tick(self, now: float) -> None:
        """The render tick: notes written straight into the model (as the log download's), the recorder's flush."""
        self.notes(now)
        if self.recorder is not None:
            self.recorder.poll(now)
            self.recording_failed()  # said once; the flight goes on

    def notes(self, now: float) -> None:
        """The events list's new lines to the recording and the live server (/events: what the pilot read)."""
        if self.recorder is None and self.live is None:
            return
        new = []
        for entry in reversed(self.station.model.events):
            if entry.seq <= self._noted:
                break
            new.append(entry)
        for entry in reversed(new):  # (a merged repeat is written again, with its count)
            text = entry.text if entry.count == 1 else f"{entry.text} (×{entry.count})"
            for sink in (self.recorder, self.live):
                if sink is not None:
                    sink.event(now, entry.severity, entry.source, text)
        if new:
            self._noted = new[0].seq
