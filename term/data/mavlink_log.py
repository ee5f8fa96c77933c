"""MAVLink's log protocol over the board's flash log, for the endpoint (term/data/mavlink.py), on the display's
loop: LOG_REQUEST_LIST asks the board's LogStatus (``Op.LOG_STATUS``, through the station as F4's question does)
and answers LOG_ENTRY: log 1 of 1 with the flash's used bytes, or no log when it is empty. LOG_REQUEST_DATA is
served from the flash log downloaded as F5 does (the app's download: its retries, its resume, its CSV beside), once
it is complete and matches the board's CRC-32, in 90-byte LOG_DATA; a request that comes first waits for it
(``MAX_WAITING`` at most), one past the end is answered with count 0. A board whose log changed (another size or
CRC) is downloaded again. LOG_REQUEST_END forgets what waits.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from term.core.protocol import LogStatus, Op

LOG_DATA_BYTES = 90  # LOG_DATA's payload
MAX_WAITING = 16  # LOG_REQUEST_DATA waiting for the download; more are dropped
LOG_ID = 1  # the board has one log


class LogService:
    """The log protocol (module docstring). ``endpoint`` gives ``send``, ``text``, ``send_command``, the codec
    (``mav``) and the station; ``start_download`` is the app's F5."""

    def __init__(self, endpoint: Any, start_download: Callable[[], None] | None) -> None:
        self.ep = endpoint
        self.start_download = start_download
        self.list_due = False  # the Ack of LOG_STATUS came: the next LogStatus answers the list
        self.data: bytes | None = None  # the flash log downloaded and checked
        self.key: tuple[int, int] | None = None  # its (used, crc32)
        self.wanted: list[tuple[int, int]] = []  # LOG_REQUEST_DATA (offset, count) waiting for the bytes
        self.download: Any = None  # the download it waits for

    def request_list(self, msg: Any) -> None:
        self.ep.send_command(Op.LOG_STATUS, 0, ("log", None))

    def status_answered(self, ok: bool, why: str) -> None:
        if not ok:
            self.ep.text("error", f"log list: {why}")
        else:
            self.list_due = True

    def log_status(self, ls: LogStatus) -> None:
        """A LogStatus from the board: the list's answer if one is due."""
        if not self.list_due:
            return
        self.list_due = False
        mav = self.ep.mav
        entry = mav.log_entry_encode(0, 0, 0, 0, 0) if ls.used == 0 else mav.log_entry_encode(LOG_ID, 1, 1, 0, ls.used)
        self.ep.send([entry])

    def request_data(self, msg: Any) -> None:
        if msg.id != LOG_ID:
            self.ep.text("error", f"log {msg.id}: the board has one log, number {LOG_ID}")
            return
        if len(self.wanted) < MAX_WAITING:
            self.wanted.append((int(msg.ofs), int(msg.count)))
        self.serve()

    def request_end(self, msg: Any) -> None:
        self.wanted.clear()

    def serve(self) -> None:
        """The waiting requests from the checked download, or the download started (F5's)."""
        if not self.wanted:
            return
        st = self.ep.station
        ls = st.model.log_status if st is not None else None
        if self.data is None or (ls is not None and (ls.used, ls.crc32) != self.key):
            if self.download is None and st is not None and self.start_download is not None:
                if st.model.download is None:
                    self.start_download()
                self.download = st.model.download
                if self.download is not None:
                    self.ep.text("info", "downloading the board's flash log (as F5 does): LOG_DATA follows")
            return
        data, mav, out = self.data, self.ep.mav, []
        for ofs, count in self.wanted:
            end = min(len(data), ofs + count)
            if ofs >= end:
                out.append(mav.log_data_encode(LOG_ID, ofs, 0, bytes(LOG_DATA_BYTES)))  # past the end
            for pos in range(ofs, end, LOG_DATA_BYTES):
                chunk = data[pos:min(end, pos + LOG_DATA_BYTES)]
                out.append(mav.log_data_encode(LOG_ID, pos, len(chunk), chunk.ljust(LOG_DATA_BYTES, b"\0")))
        self.wanted.clear()
        self.ep.send(out)

    def tick(self) -> None:
        """The render tick: a download that finished serves what waits (or says why it failed)."""
        d = self.download
        if d is None or getattr(d, "state", "running") == "running":
            return
        self.download = None
        if d.state == "done":
            self.data, self.key = d.data(), (d.used, d.crc32)
            self.serve()
        else:
            self.wanted.clear()
            self.ep.text("error", f"log download: {d.reason}")
