"""Long work starts fast and shows progress (issue 22): a replay reads a closed session as the playback goes and
plays the same events as one read whole; export and plot say how far they are. (The timings: bench.long_work.)"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from term.data.export import export
from term.data.plot import plot_log
from term.data.recording import iter_file
from term.data.replay import LOAD_AHEAD_S, Replay, build_timeline
from tests.support.session_writer import write_session


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_session(tmp_path_factory.mktemp("long"), 1.0)  # a minute at full telemetry, 6000 ticks


def test_an_indexed_replay_reads_only_ahead_and_plays_what_a_whole_read_plays(session: Path) -> None:
    replay = Replay.load(session)
    assert replay._more is not None  # read as the playback goes
    assert replay.timeline[-1][0] <= LOAD_AHEAD_S + 1.0 and replay.duration == pytest.approx(60.0, abs=0.05)
    rec_meta_start = int(replay.meta["start_ns"])
    whole = build_timeline(iter_file(session), rec_meta_start)
    played = [(t, ev) for t, ev in _play(replay)]
    assert played == whole
    assert replay.finished and replay.duration == whole[-1][0]
    # Back to the start and forward past the end: the same events again, then nothing more.
    assert replay.seek(0.0) is True
    assert sum(1 for _ in replay.catch_up()) == sum(1 for t, _ in whole if t <= 0.0)
    assert replay.seek(1e9) is False and replay.position == replay.duration


def _play(replay: Replay) -> list[tuple[float, object]]:
    out = []
    while not replay.finished:
        for ev in replay.advance(7.0):
            out.append((replay.clock(), ev))
    return out


def test_export_and_plot_say_how_far_they_are(session: Path, tmp_path: Path) -> None:
    calls: list[tuple[int, int | None]] = []
    res = export(session, tmp_path / "f.mcap", progress=lambda done, total: calls.append((done, total)))
    total = calls[0][1]
    assert total is not None and calls[0] == (0, total) and calls[-1] == (total, total)
    assert len(calls) >= 3 and [c[0] for c in calls] == sorted(c[0] for c in calls)
    assert res.rows > 6000
    calls.clear()
    plot_log(session, tmp_path / "p.png", ["phi"], progress=lambda done, total: calls.append((done, total)))
    assert calls[0] == (0, total) and calls[-1] == (total, total)


@pytest.mark.parametrize("reader", ["replay", "export", "plot"])
def test_the_summary_reads_never_hang_on_a_fifo(tmp_path: Path, reader: str) -> None:
    """The indexed replay and the progress bars read a recording's summary first: through the one reader too, so
    a FIFO named like a recording is one line (a daemon thread guards against a hang: a watchdog, not a timing)."""
    import os
    import threading

    from term.data.plot import PlotError
    from term.data.recording import RecordingError
    from term.data.replay import Replay

    path = tmp_path / "session.mcap"
    os.mkfifo(path)
    said: list[str] = []

    def run() -> None:
        try:
            if reader == "replay":
                Replay.load(path)
            elif reader == "export":
                export(path, tmp_path / "out.mcap", progress=lambda done, total: None)
            else:
                plot_log(path, tmp_path / "p.png", progress=lambda done, total: None)
        except (RecordingError, PlotError, ValueError) as exc:
            said.append(str(exc))

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(30)
    assert not t.is_alive(), f"{reader} hangs on a FIFO"
    assert said and "\n" not in said[0] and str(path) in said[0], said


def test_a_chunk_claiming_a_huge_size_is_one_line_not_an_allocation(tmp_path: Path, session: Path) -> None:
    import struct

    from mcap.opcode import Opcode

    from term.data.recording import Recording

    data = bytearray(session.read_bytes())
    pos = 8
    while pos < len(data):  # the first chunk's uncompressed size: 2**60 bytes
        op, length = struct.unpack_from("<BQ", data, pos)
        if op == Opcode.CHUNK:
            struct.pack_into("<Q", data, pos + 9 + 16, 2**60)
            break
        pos += 9 + length
    bad = tmp_path / "x.mcap"
    bad.write_bytes(bytes(data))
    rec = Recording(bad)
    list(iter_file(bad, rec))  # skipped as damage, counted (issue 36), never allocated
    assert [d.start for d in rec.damage] == [pos] and "(ValueError)" in rec.damage_text


def test_the_bar_is_there_before_a_csvs_first_pass(session: Path, tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A CSV export reads the recording twice (which packet types are there, then the rows): its bar starts at 0
    before the first pass, not after it."""
    import term.data.export as ex

    read = [0]
    real = ex.iter_file

    def counting(*args: Any, **kwargs: Any) -> Iterator[Any]:
        for item in real(*args, **kwargs):
            read[0] += 1
            yield item

    monkeypatch.setattr(ex, "iter_file", counting)
    seen: list[tuple[int, int | None, int]] = []
    export(session, tmp_path / "f.csv", progress=lambda done, total: seen.append((done, total, read[0])))
    assert seen[0][:2] == (0, seen[-1][1]) and seen[0][2] == 0
