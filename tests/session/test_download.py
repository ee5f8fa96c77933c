"""The log download's state machine (term.session.download) on its own, and against the real board: fcb_sim's Board and
term's LinkSession joined by a lossy byte proxy (two FaultyChannels), all on one simulated clock (bench.download's
``Rig``), so a download of simulated seconds costs a fraction of a second and every seed is exactly repeatable."""

from __future__ import annotations

import zlib

import pytest

from term.core.link import CommandAcked, CommandFailed, PacketReceived
from term.core.protocol import Event, EventCode, LogChunk, LogState, LogStatus, Mode, Nak, Op
from term.session.download import DONE, EMPTY, FAILED, RUNNING, LogDownloader, Request
from term.transports.loopback import Faults
from tests.support.download_rig import Rig, is_type

# --- against the real board ------------------------------------------------------------------------------------


def test_clean_link_downloads_in_one_pass() -> None:
    rig = Rig(seed=1)
    d = rig.download()
    assert d.state == DONE and d.data() == rig.truth()
    assert d.requests == 1 and d.received == d.total_chunks > 100


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_five_percent_of_bytes_damaged_both_ways_is_byte_identical(seed: int) -> None:
    # The fault (issue 11): at 5 % one lost Ack to a resume request ended the download. About half the frames of
    # each kind die here (a 20-byte chunk frame survives 0.95 ** 20 = 36 % of the time).
    rig = Rig(seed=seed)
    rig.faults(Faults(corrupt=0.05), Faults(corrupt=0.05))
    d = rig.download()
    assert d.state == DONE, d.reason
    assert d.data() == rig.truth() and d.verify() is None
    assert d.requests > 3  # it took resumes (the test would be no test on a clean run)
    assert rig.board.log.used == d.used and zlib.crc32(d.data()) == rig.board.log.crc32()


def test_every_logstatus_dropped_fails_cleanly_and_f5_finishes_once_they_pass() -> None:
    # The fault: without a LogStatus the download never ended and never failed. Now it asks for one with a growing
    # pause and, at the deadline, fails with the reason and the chunks it has; resumed, it finishes.
    rig = Rig(seed=3)
    drop_status = Faults(drop_frame=is_type(LogStatus))
    rig.faults(Faults(), drop_status)
    start = rig.now
    d = rig.download()
    assert d.state == FAILED
    assert "no LogStatus (size and CRC-32) from the board in 20 s" in d.reason
    assert "F5" not in d.reason  # every chunk is here: nothing to resume from
    assert d.received == d.total_chunks and d.used == rig.board.log.used and d.crc32 is None
    assert d.deadline_s <= rig.now - start < d.deadline_s + 5
    asks = d.status_asks
    assert 5 < asks < 60  # asked again and again, with pauses, not in a tight loop
    assert rig.down.stats.frames_filtered >= asks
    rig.faults(Faults(), Faults())
    d.resume(rig.now)
    rig.download(dl=d)
    assert d.state == DONE and d.data() == rig.truth() and d.status_asks == asks + 1


def test_logstatus_dropped_and_bytes_damaged_fails_with_a_resume_point() -> None:
    rig = Rig(seed=4)
    drop_status = Faults(corrupt=0.05, drop_frame=is_type(LogStatus))
    rig.faults(Faults(corrupt=0.05), drop_status)
    d = rig.download()
    assert d.state == FAILED and "LogStatus" in d.reason
    rig.faults(Faults(corrupt=0.05), Faults(corrupt=0.05))
    for _ in range(3):  # F5 again while it fails: at 5 % a LogStatus and its ask survive together 1 time in 4
        d.resume(rig.now)
        rig.download(dl=d)
        if d.state == DONE:
            break
        assert "LogStatus" in d.reason
    assert d.state == DONE and d.data() == rig.truth()


def test_ten_percent_fails_cleanly_with_a_resume_point_and_f5_finishes_it() -> None:
    # At 10 % only 12 % of the chunk frames survive: it may not finish within its deadline (shortened here, to
    # see it fail), but every failure names its reason and resume point, and F5 carries on from there. Whether a
    # seed stalls 8 s is chance: seed 5 fails 4 times (seed 1 no longer did once the log's attitude in SAFE followed
    # the DMP, issue 22, instead of a frozen zero).
    rig = Rig(seed=5, record_s=0.2)
    rig.faults(Faults(corrupt=0.10), Faults(corrupt=0.10))
    d = LogDownloader(started=rig.now, deadline_s=8.0)
    failures = []
    for _ in range(20):
        rig.download(dl=d)
        if d.state != FAILED:
            break
        failures.append(d.reason)
        assert "nothing new from the board for 8 s" in d.reason
        assert d.resume_at is None or d.reason.endswith(f"F5 resumes from chunk {d.resume_at}")
        truth = rig.truth()
        assert all(c == truth[12 * i:12 * i + 12].ljust(12, b"\xff") for i, c in d.chunks.items())
        d.resume(rig.now)
    assert d.state == DONE and d.data() == rig.truth()
    assert failures  # the test saw the failure it is about


def test_leaving_safe_ends_the_download_with_the_boards_reason() -> None:
    rig = Rig(seed=2)
    rig.faults(Faults(), Faults(drop=0.3))  # chunks lost: a resume will be needed
    rig.dl = d = LogDownloader(started=rig.now)
    rig.run(1.0, lambda: d.received > 0)
    rig.session.send_command(Op.MODE, Mode.MANUAL, rig.now)  # the board leaves SAFE: it ends the download
    rig.run(30.0, lambda: d.state != RUNNING)
    assert rig.board.mode == Mode.MANUAL
    assert d.state == FAILED and "refused" in d.reason and "SAFE" in d.reason, d.reason
    assert d.resume_at is not None and d.reason.endswith(f"F5 resumes from chunk {d.resume_at}")


def test_an_empty_log_is_said_so() -> None:
    rig = Rig(seed=1)
    assert rig.command(Op.LOG_RESET).value == 0  # type: ignore[attr-defined]
    d = rig.download()
    assert d.state == EMPTY and "empty" in d.reason


# --- the machine on its own: scripted packets and outcomes on a fake clock -------------------------------------


def _chunks(data: bytes) -> list[bytes]:
    return [data[i:i + 12].ljust(12, b"\xff") for i in range(0, len(data), 12)]


class Script:
    """Plays the link for a LogDownloader: what it asks for is recorded; answers are fed by the test."""

    def __init__(self) -> None:
        self.d = LogDownloader(started=0.0)
        self.now = 0.0
        self.asked: list[tuple[float, Request, int]] = []
        self.next_id = 0

    def tick(self, until: float, step: float = 0.01) -> None:
        while self.now < until - 1e-9:
            self.now = round(self.now + step, 6)
            req = self.d.poll(self.now)
            if req is not None:
                self.next_id += 1
                self.asked.append((self.now, req, self.next_id))
                self.d.sent(self.next_id, self.now)

    def last(self) -> tuple[Request, int]:
        return self.asked[-1][1], self.asked[-1][2]

    def ack(self, value: int) -> None:
        req, cmd_id = self.last()
        self.d.on_event(CommandAcked(cmd_id, req.op, req.arg, value), self.now)

    def fail(self, reason: str = "no answer from the board after 4 tries (1.01 s)", nak: Nak | None = None) -> None:
        req, cmd_id = self.last()
        self.d.on_event(CommandFailed(cmd_id, req.op, req.arg, reason, nak), self.now)


DATA = bytes(range(256)) * 2  # 512 bytes: 43 chunks
CHUNKS = _chunks(DATA)
STATUS = LogStatus(LogState.DOWNLOADING, len(DATA), 7, zlib.crc32(DATA))


def test_a_lost_ack_is_retried_with_growing_pauses_not_given_up() -> None:
    s = Script()
    s.tick(0.01)
    assert s.last()[0] == Request(Op.LOG_DOWNLOAD, 0)
    times = []
    for _ in range(6):
        s.fail()
        t = s.now
        s.tick(s.now + 3.0)
        times.append(s.asked[-1][0] - t)
    assert times == sorted(times) and times[0] < 0.2 and times[-1] >= 1.5  # 0.1, 0.2, ... 1.6 s
    assert s.d.state == RUNNING and len(s.asked) == 7


def test_chunks_arriving_count_as_the_answer_and_a_pass_end_triggers_the_resume() -> None:
    s = Script()
    s.tick(0.01)
    for i, c in enumerate(CHUNKS):
        if i not in (5, 6, 30):
            s.d.feed(LogChunk(i, c), s.now)  # the Ack and the LogStatus were lost
    s.fail()  # the session's own retries ran out meanwhile: the chunks say the board took it
    assert s.d.total_chunks is None
    s.tick(s.now + 0.1)
    assert len(s.asked) == 1  # nothing while the pass may be streaming
    s.tick(s.now + 0.5)
    assert s.last()[0] == Request(Op.LOG_STATUS)  # the size is unknown: ask
    s.ack(len(DATA))  # the Ack says the size; its LogStatus is lost
    s.tick(s.now + 0.05)
    assert s.last()[0] == Request(Op.LOG_DOWNLOAD, 5)  # the gap is known now: resume from it
    s.ack(len(CHUNKS))
    s.d.feed(STATUS, s.now)
    s.d.feed(LogChunk(5, CHUNKS[5]), s.now)
    s.d.feed(LogChunk(6, CHUNKS[6]), s.now)
    s.d.on_event(PacketReceived(Event(EventCode.LOG_DONE, 40, 0)), s.now)  # the end of the pass
    s.tick(s.now + 0.05)
    assert s.last()[0] == Request(Op.LOG_DOWNLOAD, 5)  # chunks queued behind the end may still come
    s.tick(s.now + 0.1)
    assert s.last()[0] == Request(Op.LOG_DOWNLOAD, 30)
    s.ack(len(CHUNKS))
    s.d.feed(LogChunk(30, CHUNKS[30]), s.now)
    s.tick(s.now + 0.02)
    assert s.d.state == DONE and s.d.data() == DATA


def test_a_chunk_damaged_past_its_frame_check_is_fetched_again() -> None:
    s = Script()
    s.tick(0.01)
    s.ack(len(CHUNKS))
    s.d.feed(STATUS, s.now)
    for i, c in enumerate(CHUNKS):
        s.d.feed(LogChunk(i, c if i != 9 else b"\x00" * 12), s.now)
    s.tick(s.now + 0.02)
    assert s.d.state == RUNNING and "CRC-32 mismatch" in s.d.problem and s.d.received == 0
    assert s.last()[0] == Request(Op.LOG_DOWNLOAD, 0)


def test_refusals_end_it_with_the_boards_reason() -> None:
    for nak, state, text in ((Nak.LOG_EMPTY, EMPTY, "empty"), (Nak.NOT_IN_SAFE, FAILED, "refused"),
                             (Nak.LOG_BUSY, FAILED, "refused")):
        s = Script()
        s.tick(0.01)
        s.fail("reason from the board", nak)
        assert s.d.state == state and text in s.d.reason, (nak, s.d.reason)


def test_the_deadline_fails_it_with_the_last_problem_and_resume_continues() -> None:
    s = Script()
    s.tick(0.01)
    s.ack(len(CHUNKS))
    s.d.feed(STATUS, s.now)
    for i in range(10):
        s.d.feed(LogChunk(i, CHUNKS[i]), s.now)
    t0 = s.now
    while s.d.state == RUNNING:
        s.tick(s.now + 0.05)
        if s.d._out is not None:  # noqa: SLF001  (every request goes unanswered)
            s.fail()
    assert s.d.state == FAILED and s.now - t0 == pytest.approx(s.d.deadline_s, abs=0.1)
    assert "nothing new from the board for 20 s" in s.d.reason and "no answer from the board" in s.d.reason
    assert s.d.reason.endswith("10 of 43 chunks here: F5 resumes from chunk 10")
    assert s.d.poll(s.now + 1) is None
    s.d.resume(s.now)
    s.tick(s.now + 0.02)
    assert s.d.state == RUNNING and s.last()[0] == Request(Op.LOG_DOWNLOAD, 10)


def test_a_log_that_changed_under_the_download_starts_afresh() -> None:
    s = Script()
    s.tick(0.01)
    s.ack(len(CHUNKS))
    s.d.feed(STATUS, s.now)
    for i in range(10):
        s.d.feed(LogChunk(i, CHUNKS[i]), s.now)
    s.d.feed(STATUS._replace(used=600, crc32=1), s.now)
    assert s.d.received == 0 and s.d.restarts == 1 and s.d.total_chunks == 50


def test_not_connected_is_retried_too() -> None:
    d = LogDownloader(started=0.0)
    req = d.poll(0.0)
    assert req == Request(Op.LOG_DOWNLOAD, 0)
    d.sent(None, 0.0)
    assert d.poll(0.05) is None and "not connected" in d.problem
    assert d.poll(0.11) == req
    assert Mode.SAFE == 0  # the board downloads only in SAFE


def test_next_deadline_names_the_next_instant_poll_has_work() -> None:
    d = LogDownloader(started=0.0)
    assert d.poll(0.0) == Request(Op.LOG_DOWNLOAD, 0)
    d.sent(None, 0.0)  # not connected: the first pause is 0.1 s
    assert d.next_deadline() == pytest.approx(0.1)
    assert d.poll(0.1) is not None
    d.sent(7, 0.1)
    assert d.next_deadline() == pytest.approx(0.1 + d.request_timeout_s)  # waiting for its outcome
    d.on_event(CommandFailed(7, Op.LOG_DOWNLOAD, 0, "refused", Nak.NOT_IN_SAFE), 0.2)
    assert d.state == FAILED and d.next_deadline() == float("inf")
