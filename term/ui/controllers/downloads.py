"""The log download in the app: F5 or the palette starts it, or resumes one that failed. Its policy (requests
retried with growing pauses until a deadline, resumes from the first gap, the LogStatus asked again) is the sans-IO
``term.session.download.LogDownloader``, which the model feeds the LogStatus and LogChunk packets; the render tick
(``tick``) and the outcomes of its commands (``on_link_event``) drive it. Done, it is checked against the board's
CRC-32 and saved as CSV on a worker (``spawn``), and the events list says where, with the file's own size.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Coroutine
from datetime import datetime
from pathlib import Path
from typing import Any

from term.core.link import PacketReceived
from term.core.logfile import log_filename, write_csv
from term.core.protocol import Event, LogChunk, LogStatus, Op
from term.session.connection import Connection
from term.session.download import EMPTY, FAILED, RUNNING, LogDownloader
from term.session.station import Station

_DOWNLOAD_PACKETS = (LogChunk, LogStatus, Event)  # the packets that may move a download on


class DownloadController:
    """One log download at a time (module docstring). ``send`` is the app's command path, ``connected`` the link
    commands go over (None: not connected), ``spawn`` runs a coroutine off the event loop's hot path (the app's
    worker). ``options``: LogDownloader settings (a test shortens the deadline)."""

    def __init__(self, station: Station, clock: Callable[[], float], send: Callable[[Op, int], int | None],
                 connected: Callable[[], Connection | None],
                 spawn: Callable[[Coroutine[Any, Any, None]], object], log_directory: Path) -> None:
        self.station = station
        self.clock = clock
        self.send = send
        self.connected = connected
        self.spawn = spawn
        self.log_directory = log_directory
        self.options: dict[str, float] = {}
        self.failed: LogDownloader | None = None  # the last download that failed: F5 resumes it

    def start(self) -> None:
        now = self.clock()
        model = self.station.model
        d = model.download
        if d is not None:
            self.station.note("warning", "term", "a log download is already running"
                              + (f" ({d.progress_text()})" if isinstance(d, LogDownloader) else ""))
            return
        if self.connected() is None:
            self.station.note("error", "term", "not sent: log download: not connected")
            return
        d, self.failed = self.failed, None
        if d is not None and d.state == FAILED:
            d.resume(now)
            self.station.note("info", "term", f"log download resumed: {d.progress_text()} here")
        else:
            d = LogDownloader(started=now, **self.options)
        model.download = d
        model.download_note, model.download_note_at = "", None
        self.tick(now)

    def on_link_event(self, ev: object) -> None:
        """A link's event: a command's outcome or LOG_DONE to the download (the model fed it its packets); the next
        request may go at once, not at the next render tick."""
        d = self.station.model.download
        if isinstance(d, LogDownloader) and (type(ev) is not PacketReceived or type(ev.packet) in _DOWNLOAD_PACKETS):
            now = self.clock()
            d.on_event(ev, now)
            self.tick(now)

    def tick(self, now: float) -> None:
        model = self.station.model
        d = model.download
        if not isinstance(d, LogDownloader):
            return
        req = d.poll(now)
        if req is not None:
            # Not connected: the download pauses and tries again (no "not sent" line for every try).
            d.sent(self.send(req.op, req.arg) if self.connected() is not None else None, now)
        if d.state == RUNNING:
            return
        model.download = None
        model.download_note_at = now
        if d.state == EMPTY:
            model.download_note = f"log download: {d.reason}"
        elif d.state == FAILED:
            self.failed = d
            model.download_note = f"log download failed: {d.reason}"
            self.station.note("error", "term", model.download_note)
        else:
            stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.log_directory / log_filename(stamp)
            self.spawn(self._save(d.data(), path, d.rate_kBps(now)))

    async def _save(self, data: bytes, path: Path, rate: float) -> None:
        from term.core.logfile import decode_to_rows

        model = self.station.model
        try:
            rows = await asyncio.to_thread(write_csv, data, path, decode_to_rows)
        except OSError as exc:
            msg = f"cannot write {path}: {exc.strerror}"
            model.note(self.clock(), "error", "term", msg)
            model.download_note, model.download_note_at = msg, self.clock()
            return
        size = path.stat().st_size if path.exists() else 0  # the file's size, not the flash's bytes it came from
        msg = (f"log saved: {path} ({rows} rows, {size:,} bytes; {len(data):,} bytes read from the flash at "
               f"{rate:.2f} kB/s)")
        model.note(self.clock(), "info", "term", msg)
        model.download_note, model.download_note_at = msg, self.clock()
