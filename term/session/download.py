"""The terminal's log download as a small state machine, sans-IO: packets, command outcomes and time in; the next
command to send and a final outcome out. Nothing here reads a clock or touches a link.

The board's side (docs/flash_log.md): ``LOG_DOWNLOAD first`` is answered with an Ack (value: the number of
chunks) and a ``LogStatus(DOWNLOADING, used, records, crc32)``, then the chunks from ``first`` to the last, then a
``LogStatus`` in its resting state and the event ``LOG_DONE``; ``LOG_STATUS`` is answered with an Ack (value: bytes
used) and a ``LogStatus``. Answers may overtake chunks still queued (the board sends answers first), and any frame
may be lost or damaged on the way.

The policy (``LogDownloader``; it is a ``LogDownload``, so the model feeds it packets and the panel draws it):

- one request at a time: ``poll(now)`` returns the command to send (or None); the caller sends it and reports
  the cmd_id with ``sent``; its outcome comes back through ``on_event`` (the link session's CommandAcked or
  CommandFailed, and the LOG_DONE event). A LOG_DOWNLOAD whose chunks arrive counts as taken, whatever became of
  its Ack: its pass shows as the first chunk at or after the asked one that arrives after it left (a jump back if
  an earlier pass was still streaming);
- a request that fails without a refusal from the board (no answer, not connected) is sent again after a pause
  that grows (``BACKOFF_S``); nothing gives up on a number of tries;
- a pass is over once it has brought a chunk beyond every gap (the rest of it would bring nothing new), or when
  its end (closing LogStatus, LOG_DONE) came and no chunk for ``END_GRACE_S`` (queued chunks may follow the
  end), or when no chunk came for ``quiet_s``. Then the download resumes from the first missing chunk (every
  chunk that arrived is kept), or asks LOG_STATUS while the size or the CRC-32 is unknown (the Ack of LOG_STATUS
  gives the size, only the LogStatus the CRC);
- when every chunk is here and the bytes match the board's CRC-32 the download is ``done``; a mismatch (a
  damaged frame that passed its CRC-16) throws the chunks away and starts again, at most ``MAX_CRC_RESTARTS``
  times;
- ``deadline_s`` without progress (a new chunk, or news of the log's size or CRC) ends it as ``failed`` with the
  reason and the resume point (``reason``, ``resume_at``); the board's refusals (not in SAFE, recording) end it
  at once, an empty log ends it as ``empty``. ``resume(now)`` (F5 again) carries on from the chunks it has.

Time is in seconds on any monotonic clock, passed in. Tests drive it, the real board and a lossy byte proxy on
a simulated clock (tests/session/test_download.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from term.core.link import CommandAcked, CommandFailed, PacketReceived
from term.core.logfile import LogDownload
from term.core.protocol import Event, EventCode, LogChunk, LogState, LogStatus, Nak, Op

DEADLINE_S = 20.0  # no progress for this long: the download fails, with the reason and where F5 resumes
QUIET_S = 0.3  # no chunk for this long: the board's pass is over, though its end did not arrive
END_GRACE_S = 0.1  # after a pass's end arrived, chunks still queued behind it may follow for this long
STATUS_WAIT_S = 0.3  # the LogStatus follows the Ack of LOG_STATUS at once; asked again if it has not come by then
REQUEST_TIMEOUT_S = 3.0  # a request with no outcome at all (its link went away with it) counts as failed
BACKOFF_S = (0.1, 0.2, 0.4, 0.8, 1.6)  # pauses after failed requests in a row; the last one repeats
MAX_CRC_RESTARTS = 3

RUNNING, DONE, EMPTY, FAILED = "running", "done", "empty", "failed"


@dataclass(frozen=True, slots=True)
class Request:
    """A command the download wants sent."""

    op: Op
    arg: int = 0

    def text(self) -> str:
        if self.op == Op.LOG_STATUS:
            return "log status"
        return "log download" if self.arg == 0 else f"log download from chunk {self.arg}"


@dataclass
class _Sent:
    request: Request
    cmd_id: int
    at: float


@dataclass
class _Pass:
    """The board streaming from ``first`` to the end, for the latest LOG_DOWNLOAD."""

    first: int
    streaming: bool  # chunks of an earlier pass may still arrive: this one shows as a jump back
    taken_at: float | None = None  # when its Ack or its first chunk came
    seen: bool = False  # its first chunk arrived: ``top`` counts from there
    top: int = -1  # the highest chunk index it brought
    end_at: float | None = None  # when its closing LogStatus or LOG_DONE arrived


@dataclass
class LogDownloader(LogDownload):
    """A download with its retry policy (module docstring). ``LogDownloader(started=now)``, then ``poll``."""

    deadline_s: float = DEADLINE_S
    quiet_s: float = QUIET_S
    end_grace_s: float = END_GRACE_S
    status_wait_s: float = STATUS_WAIT_S
    request_timeout_s: float = REQUEST_TIMEOUT_S
    backoff_s: tuple[float, ...] = BACKOFF_S
    state: str = RUNNING
    reason: str = ""  # why it failed (or that the log is empty); "" while running and when done
    problem: str = ""  # the last thing that went wrong, for the failure's reason
    requests: int = 0  # commands sent, retries included
    passes: int = 0  # LOG_DOWNLOAD requests the board took
    crc_restarts: int = 0
    status_asks: int = 0  # LOG_STATUS requests sent
    # The machine's own state, not for the constructor.
    _out: _Sent | None = field(default=None, init=False, repr=False)  # the request waiting for its outcome
    _want_sent: Request | None = field(default=None, init=False, repr=False)  # returned by poll, not yet sent
    _failures: int = field(default=0, init=False, repr=False)  # failed requests since the last progress
    _pause_until: float = field(default=0.0, init=False, repr=False)  # the backoff: no request before this
    _progress_at: float = field(default=0.0, init=False, repr=False)  # the deadline runs from here
    _pass: _Pass | None = field(default=None, init=False, repr=False)  # the latest LOG_DOWNLOAD's pass
    _ever_taken: bool = field(default=False, init=False, repr=False)  # a LOG_DOWNLOAD was ever taken
    _chunk_at: float = field(default=-1e9, init=False, repr=False)  # the last chunk's arrival time
    _last_index: int = field(default=-1, init=False, repr=False)  # the last chunk's index
    _statuses: int = field(default=0, init=False, repr=False)  # LogStatus packets received
    _status_acked: tuple[int, float] | None = field(default=None, init=False, repr=False)  # its LogStatus is due
    _last_hole: int | None = field(default=None, init=False, repr=False)  # cache of the highest missing chunk

    def __post_init__(self) -> None:
        self._progress_at = self.started

    # --- input ----------------------------------------------------------------------------------------------

    def feed(self, pkt: Any, now: float) -> bool:
        """A LogStatus or LogChunk from the board (the model calls this for every one); True if it was one."""
        kind = type(pkt)
        if kind is LogChunk:
            i = pkt.index
            new = i not in self.chunks
            super().feed(pkt, now)
            p = self._pass
            if p is not None and not p.seen and i >= p.first and (not p.streaming or i < self._last_index):
                p.seen = True  # its first chunk (after an earlier pass: where the stream jumped back)
                self._taken(p, now)
            if p is not None and p.seen:
                p.top = max(p.top, i)
            self._chunk_at, self._last_index = now, i
            if new:
                self._progress(now)
            return True
        if kind is LogStatus:
            before = (self.used, self.crc32, self.restarts)
            super().feed(pkt, now)
            self._statuses += 1
            if pkt.state != LogState.DOWNLOADING:
                self._pass_end(now)
            if (self.used, self.crc32, self.restarts) != before:
                self._last_hole = None
                self._progress(now)
            return True
        return False

    def on_event(self, ev: Any, now: float) -> None:
        """A link event: the outcome of a request (CommandAcked, CommandFailed), or the board's LOG_DONE event.
        Others are ignored (LogStatus and LogChunk come through ``feed``)."""
        kind = type(ev)
        if kind is PacketReceived:
            pkt = ev.packet
            if type(pkt) is Event and pkt.code == EventCode.LOG_DONE:
                self._pass_end(now)
            return
        if (kind is not CommandAcked and kind is not CommandFailed) or ev.op not in (Op.LOG_DOWNLOAD, Op.LOG_STATUS):
            return
        out = self._out
        if kind is CommandAcked and ev.op == Op.LOG_DOWNLOAD and self.set_size(n_chunks=ev.value):
            self._last_hole = None
            self._progress(now)  # (a late Ack's size news counts too)
        if out is None or out.cmd_id != ev.cmd_id or out.request != Request(Op(ev.op), ev.arg):
            return  # an answer to a request already settled
        self._out = None
        req = out.request
        if kind is CommandAcked:
            if req.op == Op.LOG_DOWNLOAD:
                if self._pass is not None:
                    self._taken(self._pass, now)
            else:
                if self.set_size(used=ev.value):
                    self._last_hole = None
                    self._progress(now)
                self._status_acked = (self._statuses, now)
            return
        if ev.nak is None:
            if req.op == Op.LOG_DOWNLOAD and self._pass is not None and self._pass.taken_at is not None:
                return  # its Ack was lost, but its chunks came
            self._pass = None if req.op == Op.LOG_DOWNLOAD else self._pass
            self._failed(now, f"{req.text()}: {ev.reason}")  # not delivered: again after a pause
        elif ev.nak == Nak.LOG_EMPTY:
            self._finish(EMPTY, "the board's log is empty (F2 starts recording)")
        elif ev.nak == Nak.BAD_ARGUMENT and req.op == Op.LOG_DOWNLOAD:
            # The chunk is past the end: the log was erased or replaced. Start again from its new size.
            self.chunks.clear()
            self.used = self.crc32 = self.n_chunks = self._last_hole = self._pass = None
            self.restarts += 1
            self._ever_taken = False
            self._failed(now, f"{req.text()}: the board's log changed")
        else:
            self._fail(f"the board refused it: {ev.reason}")

    def sent(self, cmd_id: int | None, now: float) -> None:
        """The request ``poll`` returned went out as ``cmd_id`` (None: it could not be sent, e.g. no link)."""
        req = self._want_sent
        if req is None:
            return
        self._want_sent = None
        self.requests += 1
        if cmd_id is None:
            self._failed(now, f"{req.text()}: not connected")
            return
        self._out = _Sent(req, cmd_id, now)
        if req.op == Op.LOG_STATUS:
            self.status_asks += 1
            self._status_acked = None
        else:
            self._pass = _Pass(req.arg, streaming=now - self._chunk_at < self.quiet_s)

    def resume(self, now: float) -> None:
        """Carry on after a failure (F5 again): the chunks that arrived are kept, the deadline starts afresh."""
        if self.state != FAILED:
            return
        self.state, self.reason, self.problem = RUNNING, "", ""
        self._out = self._want_sent = self._pass = self._status_acked = None
        self._failures = 0
        self._pause_until = self._progress_at = now

    # --- output ---------------------------------------------------------------------------------------------

    def poll(self, now: float) -> Request | None:
        """Run the timers; returns the command to send now (then call ``sent``), or None."""
        if self.state != RUNNING or self._check_complete(now):
            return None
        out = self._out
        if out is not None:
            if out.request.op == Op.LOG_DOWNLOAD and self._pass is not None and self._pass.taken_at is not None:
                self._out = None  # its chunks came: its outcome no longer matters
            elif now - out.at >= self.request_timeout_s:
                self._out = None
                self._failed(now, f"{out.request.text()}: no outcome after {self.request_timeout_s:.0f} s")
            else:
                return None
        if now - self._progress_at >= self.deadline_s:
            self._fail_deadline()
            return None
        if now < self._pause_until or self._streaming(now):
            return None
        req = self._next_request(now)
        self._want_sent = req
        return req

    def next_deadline(self) -> float:
        """When ``poll`` may next have something to do (a caller without a steady tick sleeps until then)."""
        if self.state != RUNNING:
            return float("inf")
        times = [self._progress_at + self.deadline_s]
        if self._out is not None:
            times.append(self._out.at + self.request_timeout_s)
        else:
            times.append(self._pause_until)
        p = self._pass
        if p is not None and p.taken_at is not None:
            times.append(max(p.taken_at, self._chunk_at) + self.quiet_s)
            if p.end_at is not None:
                times.append(max(p.end_at, self._chunk_at) + self.end_grace_s)
        if self._status_acked is not None:
            times.append(self._status_acked[1] + self.status_wait_s)
        return min(times)

    @property
    def resume_at(self) -> int | None:
        """The chunk a resumed download starts from (None: none missing)."""
        return self.missing()

    def progress_text(self) -> str:
        total = self.total_chunks
        return f"{self.received} of {total if total is not None else '?'} chunks"

    # --- internals ------------------------------------------------------------------------------------------

    def _progress(self, now: float) -> None:
        self._progress_at = now
        self._failures = 0

    def _taken(self, p: _Pass, now: float) -> None:
        if p.taken_at is None:
            p.taken_at = now
            self.passes += 1
            self._ever_taken = True

    def _pass_end(self, now: float) -> None:
        p = self._pass
        if p is not None and p.taken_at is not None:
            p.end_at = now

    def _highest_hole(self) -> int | None:
        """The highest missing chunk (None: none, or the size is unknown). Holes only close, so the search goes
        down from the last answer: over a whole download it reads each index about once."""
        total = self.total_chunks
        if total is None:
            return None
        start = total - 1 if self._last_hole is None else min(self._last_hole, total - 1)
        for i in range(start, -1, -1):
            if i not in self.chunks:
                self._last_hole = i
                return i
        self._last_hole = -1
        return None

    def _streaming(self, now: float) -> bool:
        """Whether the pass the board is sending may still bring something we lack."""
        p = self._pass
        if p is None or p.taken_at is None:
            return False
        if p.seen and self.total_chunks is not None:
            hole = self._highest_hole()
            if hole is None or p.top > hole:
                return False  # it is past every gap: the rest of it brings nothing new
        if p.end_at is not None and now - max(p.end_at, self._chunk_at) >= self.end_grace_s:
            return False  # it ended, and what was queued behind its end has come
        return now - max(p.taken_at, self._chunk_at) < self.quiet_s  # else: over when it goes quiet

    def _next_request(self, now: float) -> Request | None:
        acked = self._status_acked
        if acked is not None and self._statuses > acked[0]:
            self._status_acked = acked = None  # the LogStatus came
        if not self._ever_taken:
            return Request(Op.LOG_DOWNLOAD, self.missing() or 0)
        first = self.missing() if self.total_chunks is not None else None
        if first is not None:
            self._status_acked = None  # a resumed pass brings a LogStatus of its own
            return Request(Op.LOG_DOWNLOAD, first)
        if acked is not None:  # all that is missing is the LogStatus
            if now - acked[1] < self.status_wait_s:
                return None  # on its way
            self._status_acked = None
            self._failed(now, f"the board's LogStatus (size and CRC-32) did not come (asked {self.status_asks}"
                         f" time{'s' if self.status_asks > 1 else ''})")
            return None
        return Request(Op.LOG_STATUS)  # the size or the CRC-32 is not known yet

    def _failed(self, now: float, problem: str) -> None:
        self.problem = problem
        self._pause_until = now + self.backoff_s[min(self._failures, len(self.backoff_s) - 1)]
        self._failures += 1

    def _check_complete(self, now: float) -> bool:
        if self.used == 0:
            self._finish(EMPTY, "the board's log is empty (F2 starts recording)")
            return True
        total = self.total_chunks
        if self.crc32 is None or total is None or len(self.chunks) < total or not self.done:
            return False
        problem = self.verify()
        if problem is None:
            self._finish(DONE, "")
            return True
        if self.crc_restarts >= MAX_CRC_RESTARTS:
            self._fail(f"{problem} ({self.crc_restarts + 1} times)")
            return True
        self.crc_restarts += 1  # a damaged chunk passed its frame check: fetch everything again
        self.problem = problem
        self.chunks.clear()
        self._last_hole = self._pass = None
        self._ever_taken = False
        self._progress(now)
        return False

    def _finish(self, state: str, reason: str) -> None:
        self.state, self.reason = state, reason
        self._out = self._want_sent = None

    def _fail_deadline(self) -> None:
        wait = f"{self.deadline_s:.0f} s"
        if self.crc32 is None and self.total_chunks is not None and self.missing() is None:
            head = f"no LogStatus (size and CRC-32) from the board in {wait}, asked {self.status_asks} times"
        else:
            head = f"nothing new from the board for {wait}"
        self._fail(f"{head} (last: {self.problem or 'no answer'})")

    def _fail(self, why: str) -> None:
        first = self.missing()
        where = "" if first is None else f": F5 resumes from chunk {first}"
        self._finish(FAILED, f"{why}; {self.progress_text()} here{where}")
