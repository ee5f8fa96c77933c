"""The log download in the app: F5 or the palette starts it, or resumes one that failed (``LogDownloads``, mixed
into ``TermApp``). Its policy is the sans-IO ``term.session.download.LogDownloader``."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from datetime import datetime
from pathlib import Path

from term.core.link import PacketReceived
from term.core.logfile import log_filename, write_csv
from term.core.protocol import Event, LogChunk, LogStatus
from term.session.download import EMPTY, FAILED, RUNNING, LogDownloader
from term.session.model import Model
from term.ui.screens.dirprompt import DirectoryPrompt

_DOWNLOAD_PACKETS = (LogChunk, LogStatus, Event)  # the packets that may move a download on


class LogDownloads:
    """The log download: F5 or the palette starts it, or resumes one that failed; its policy (requests retried with
    growing pauses until a deadline, resumes from the first gap, the LogStatus asked again) is the sans-IO
    ``term.session.download.LogDownloader``, which the model feeds the LogStatus and LogChunk packets; the render tick
    (``_check_download``) and the outcomes of its commands (``_download_event``) drive it. Done, it is checked
    against the board's CRC-32 and saved as CSV. Mixed into ``TermApp`` (its model, clock, send and workers)."""

    model: Model
    clock: Callable[[], float]
    log_directory: Path
    download_options: dict[str, float] = {}  # LogDownloader settings (a test shortens the deadline)
    _failed_download: LogDownloader | None = None  # the last download that failed: F5 resumes it

    def local_log_download(self) -> None:
        now = self.clock()
        d = self.model.download
        if d is not None:
            self.station.note("warning", "term", "a log download is already running"
                              + (f" ({d.progress_text()})" if isinstance(d, LogDownloader) else ""))
            return
        if self.control_connection() is None:
            self.station.note("error", "term", "not sent: log download: not connected")
            return
        d = self._failed_download
        self._failed_download = None
        if d is not None and d.state == FAILED:
            d.resume(now)
            self.station.note("info", "term", f"log download resumed: {d.progress_text()} here")
        else:
            d = LogDownloader(started=now, **self.download_options)
        self.model.download = d
        self.model.download_note = ""
        self._check_download(now)

    def _download_event(self, ev: object) -> None:
        """A link's event: a command's outcome or LOG_DONE to the download (the model fed it its packets); the next
        request may go at once, not at the next render tick."""
        d = self.model.download
        if isinstance(d, LogDownloader) and (type(ev) is not PacketReceived or type(ev.packet) in _DOWNLOAD_PACKETS):
            now = self.clock()
            d.on_event(ev, now)
            self._check_download(now)

    def _check_download(self, now: float) -> None:
        d = self.model.download
        if not isinstance(d, LogDownloader):
            return
        req = d.poll(now)
        if req is not None:
            # Not connected: the download pauses and tries again (no "not sent" line for every try).
            d.sent(self.send(req.op, req.arg) if self.control_connection() is not None else None, now)
        if d.state == RUNNING:
            return
        self.model.download = None
        if d.state == EMPTY:
            self.model.download_note = f"log download: {d.reason}"
        elif d.state == FAILED:
            self._failed_download = d
            self.model.download_note = f"log download failed: {d.reason}"
            self.station.note("error", "term", self.model.download_note)
        else:
            stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.log_directory / log_filename(stamp)
            self.run_worker(self._save_log(d.data(), path, d.rate_kBps(now)), exclusive=False)

    async def _save_log(self, data: bytes, path: Path, rate: float) -> None:
        from term.core.logfile import decode_to_rows

        try:
            rows = await asyncio.to_thread(write_csv, data, path, decode_to_rows)
        except OSError as exc:
            msg = f"cannot write {path}: {exc.strerror}"
            self.model.note(self.clock(), "error", "term", msg)
            self.model.download_note = msg
            return
        msg = f"log saved: {path} ({len(data)} bytes, {rows} rows, {rate:.2f} kB/s)"
        self.model.note(self.clock(), "info", "term", msg)
        self.model.download_note = msg

    def download_to(self) -> None:
        """Ask for a directory, then download there."""
        def chosen(path: Path | None) -> None:
            if path is None:
                return
            self.log_directory = path
            self.local_log_download()

        self.push_screen(DirectoryPrompt(self.log_directory), chosen)
