"""Log start, stop, download and reset from the keys, against the real board (fcb_sim's sans-IO Board paced to
the wall clock behind a loopback link): the download shows progress, resumes across lost chunks, checks the
board's CRC-32 and writes the decoded records as CSV; through a byte proxy that damages 5 % of the bytes both ways
it is byte-identical; with every LogStatus lost it fails with its reason and F5 resumes it (issue 11). The download's
policy on its own, on a simulated clock: tests/session/test_download.py."""

from __future__ import annotations

import asyncio
import contextlib
import csv
import time
from pathlib import Path

import pytest

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.flash_log import encode_log
from fcb_sim.world.physics import World
from term.core.logfile import LogDownload, decode_to_rows
from term.core.logformat import decode_log
from term.core.protocol import SPEC_OF, LogChunk, LogState, LogStatus, Mode, cobs_decode
from term.transports.loopback import Faults, loopback_pair
from term.ui.app import TermApp
from tests.support.waits import until


class RealTimeBoard:
    """The board paced to the wall clock on the board's end of a loopback pair (what serve.py does on a pty),
    ``speed`` times faster (its UART too), to keep the test short."""

    def __init__(self, transport, board: Board, speed: float = 1.0) -> None:  # noqa: ANN001
        self.t, self.board, self.speed = transport, board, speed
        self.t0: float | None = None  # the board boots when the terminal's first bytes arrive
        self.tasks: list[asyncio.Task[None]] = []

    async def start(self) -> None:
        await self.t.open()
        self.tasks = [asyncio.create_task(self._read()), asyncio.create_task(self._run())]

    def _now_us(self) -> int:
        if self.t0 is None:
            return 0
        return int((time.monotonic() - self.t0) * 1e6 * self.speed)

    async def _read(self) -> None:
        with contextlib.suppress(Exception):
            while True:
                data = await self.t.read()
                if self.t0 is None:
                    self.t0 = time.monotonic()
                self.board.advance(self._now_us())
                self.board.uart_receive(data)

    async def _run(self) -> None:
        with contextlib.suppress(Exception):
            while True:
                self.board.advance(self._now_us())
                out = self.board.uart_transmit()
                if out:
                    await self.t.write(out)
                await asyncio.sleep(0.002)

    async def stop(self) -> None:
        for t in self.tasks:
            t.cancel()
        for t in self.tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await t


async def test_log_record_download_as_csv_and_reset(tmp_path: Path) -> None:
    # Lose 3 % of the board's frames: some chunks go missing and the download must resume from the gaps.
    pair = loopback_pair(seed=7, b_to_a=Faults(drop=0.03))
    board = Board(BoardConfig(seed=2, log_scheme="rice"), world=World(2))
    peer = RealTimeBoard(pair.b, board, speed=2.0)
    await peer.start()
    # The board shares the test's loop: a stall of it is no silence of the board (link_timeout: not the 0.5 s).
    app = TermApp(pair.a, joystick=False, log_directory=tmp_path, session_options={"link_timeout": 3.0})
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            await until(pilot, lambda: m.mode == Mode.SAFE)
            # Keys through simulate_key: pilot.press waits for the app to go idle, which a streaming board delays.
            app.simulate_key("f5")  # nothing logged yet: the board says so
            await until(pilot, lambda: any("log is empty" in e.text for e in m.events))
            await until(pilot, lambda: m.download is None and "empty" in m.download_note)
            assert not list(tmp_path.iterdir())
            app.simulate_key("f2")
            await until(pilot, lambda: board.log.recording)
            await pilot.pause(0.8)
            app.simulate_key("f3")
            await until(pilot, lambda: not board.log.recording)
            records = board.log.records
            assert records > 200

            app.simulate_key("f5")  # not pilot.press: that one waits for the app to go idle, after the download
            await until(pilot, lambda: m.download is not None)
            seen_progress = False
            async with asyncio.timeout(20):
                while not m.download_note.startswith(("log saved", "log download")):
                    if m.download is not None and 0 < m.download.fraction < 1:
                        shown = app.screen.query_one("#download")._shown  # what the panel last drew
                        seen_progress = seen_progress or ("kB/s" in str(shown) and "%" in str(shown))
                    await pilot.pause(0.02)
            assert m.download_note.startswith("log saved"), m.download_note
            assert seen_progress, (board.log.used, records, [e.text for e in m.events])
            files = list(tmp_path.glob("quadrupel-log-*.csv"))
            assert len(files) == 1
            # issue 22: the size said is the file's (it said the flash's bytes: 97344 for a file of 710,334)
            assert f"{files[0].stat().st_size:,} bytes" in m.download_note, m.download_note
            with files[0].open() as f:
                rows = list(csv.reader(f))
            assert rows[0][:3] == ["segment", "t_us", "mode"]
            assert len(rows) - 1 == records
            truth = decode_log(board.log.contents()[: board.log.used])[0].rows
            assert [int(v) for v in rows[-1][1:]] == list(truth[-1])

            await until(pilot, lambda: board.download_next is None)  # a resumed pass may still be on its way
            app.simulate_key("f4")  # erase: it asks first, "keep it" has the focus
            from term.ui.screens.confirm import ConfirmScreen

            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen))
            app.simulate_key("tab")
            app.simulate_key("enter")
            await until(pilot, lambda: board.log.used == 0)
            await until(pilot, lambda: any(e.text.startswith("log erased: ") for e in m.events))
            assert not [e for e in m.events if e.severity == "error" and e.source != "nak"]
    finally:
        await peer.stop()


async def _recorded(pilot, app: TermApp, board: Board, seconds: float = 0.5):  # noqa: ANN001, ANN202
    """Record ``seconds`` of log over the (clean) link with F2 and F3; returns ``until``."""
    m = app.model

    await until(pilot, lambda: m.mode == Mode.SAFE)
    app.simulate_key("f2")
    await until(pilot, lambda: board.log.recording)
    await pilot.pause(seconds)
    app.simulate_key("f3")
    await until(pilot, lambda: not board.log.recording and m.pending == 0)
    return until


def _saved_rows(directory: Path) -> list[list[int]]:
    files = list(directory.glob("quadrupel-log-*.csv"))
    assert len(files) == 1
    with files[0].open() as f:
        rows = list(csv.reader(f))
    assert rows[0][:3] == ["segment", "t_us", "mode"]
    return [[int(v) for v in r[1:]] for r in rows[1:]]


@pytest.mark.parametrize("seed", [3, 8])
async def test_download_through_five_percent_byte_damage_is_byte_identical(tmp_path: Path, seed: int) -> None:
    # Issue 11: at 5 % damaged bytes (about half the frames of every kind die) one lost Ack to a resume request
    # used to end the download ("no answer from the board after 4 tries"). The link retries commands every 0.1 s
    # here instead of 0.25 (the board answers within milliseconds), only to keep the test short; the default
    # timing, over more seeds, is tests/session/test_download.py's.
    pair = loopback_pair(seed=seed)
    board = Board(BoardConfig(seed=seed, log_scheme="rice"), world=World(seed))
    peer = RealTimeBoard(pair.b, board, speed=2.0)
    await peer.start()
    app = TermApp(pair.a, joystick=False, log_directory=tmp_path,
                  session_options={"command_timeout": 0.1, "link_timeout": 3.0})
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model
            until = await _recorded(pilot, app, board, seconds=0.25)
            pair.a_to_b.faults = pair.b_to_a.faults = Faults(corrupt=0.05)
            app.simulate_key("f5")
            await until(lambda: m.download is not None)
            d = m.download
            await until(lambda: m.download_note.startswith(("log saved", "log download")), timeout=60)
            assert m.download_note.startswith("log saved"), m.download_note
            truth = board.log.contents()[: board.log.used]
            assert d.data() == truth  # type: ignore[union-attr]
            assert _saved_rows(tmp_path) == [list(r) for r in decode_log(truth)[0].rows]
            assert pair.b_to_a.stats.bytes_corrupted > 100
    finally:
        await peer.stop()


async def test_download_with_every_logstatus_lost_fails_with_its_reason_and_f5_resumes_it(tmp_path: Path) -> None:
    # Issue 11: without a LogStatus (the size and the CRC-32) the download never ended and never failed, and F5
    # said "a log download is already running". Now it asks again with pauses, fails at its deadline (shortened
    # here) with the reason, and F5 resumes it with the chunks it has.
    logstatus = SPEC_OF[LogStatus].type_id
    pair = loopback_pair(seed=5)
    board = Board(BoardConfig(seed=5, log_scheme="rice"), world=World(5))
    peer = RealTimeBoard(pair.b, board, speed=2.0)
    await peer.start()
    app = TermApp(pair.a, joystick=False, log_directory=tmp_path, session_options={"link_timeout": 3.0})
    app.downloads.options = {"deadline_s": 3.0}
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model
            until = await _recorded(pilot, app, board)
            pair.b_to_a.faults = Faults(drop_frame=lambda f: (cobs_decode(f[:-1]) or b"\0")[0] == logstatus)
            app.simulate_key("f5")
            await until(lambda: m.download is not None)
            d = m.download
            await until(lambda: m.download is None, timeout=20)
            note = m.download_note
            assert note.startswith("log download failed: no LogStatus (size and CRC-32) from the board"), note
            assert any(e.text == note and e.severity == "error" for e in m.events)
            assert d.received == d.total_chunks and pair.b_to_a.stats.frames_filtered > 2  # type: ignore[union-attr]
            assert not list(tmp_path.iterdir())

            pair.b_to_a.faults = Faults()  # the LogStatus gets through again
            app.simulate_key("f5")  # resumes: no "already running", the chunks kept
            await until(lambda: any(e.text.startswith("log download resumed: ") for e in m.events))
            await until(lambda: m.download_note.startswith(("log saved", "log download")), timeout=20)
            assert m.download_note.startswith("log saved"), m.download_note
            assert not any("already running" in e.text for e in m.events)
            truth = board.log.contents()[: board.log.used]
            assert d.data() == truth  # type: ignore[union-attr]
            assert _saved_rows(tmp_path) == [list(r) for r in decode_log(truth)[0].rows]
    finally:
        await peer.stop()


def test_download_reassembly_with_gaps_and_a_bad_crc() -> None:
    data = encode_log([[i * 2500] + [i % 5] * 17 for i in range(100)])
    chunks = [data[i:i + 12].ljust(12, b"\xff") for i in range(0, len(data), 12)]
    import zlib

    d = LogDownload(started=0.0)
    d.feed(LogStatus(LogState.DOWNLOADING, len(data), 100, zlib.crc32(data)), 0.0)
    for i, c in enumerate(chunks):
        if i not in (3, 7):
            d.feed(LogChunk(i, c), 0.1)
    assert not d.done and d.missing() == 3 and 0.9 < d.fraction < 1
    d.feed(LogChunk(3, chunks[3]), 0.2)
    assert d.missing() == 7
    d.feed(LogChunk(7, chunks[7]), 0.3)
    assert d.done and d.verify() is None and d.data() == data
    header, rows = decode_to_rows(d.data())
    assert header[1] == "t_us" and len(rows) == 100
    d.feed(LogChunk(0, b"\x00" * 12), 0.4)  # a damaged chunk that still framed correctly
    assert "CRC-32 mismatch" in (d.verify() or "")
