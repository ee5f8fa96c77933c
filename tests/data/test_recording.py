"""Session recording: the file round trip, the standard mcap reader on a closed file, a file cut anywhere (what a
SIGKILL or a pulled cable leaves), rotation, the size bound, and errors that stop the recording, not the flight."""

from __future__ import annotations

import fcntl
import json
import os
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest
from mcap.opcode import Opcode
from mcap.reader import make_reader

from term.core.protocol import PROTOCOL_VERSION, Attitude, Encoder, Heartbeat, HeartbeatAck, Joystick, Mode
from term.data.export import DecodedFrame, decode, export
from term.data.recording import (
    LinkBytes,
    LoggedEvent,
    Recording,
    RecordingError,
    SessionRecorder,
    iter_file,
    iter_session,
    latest,
    list_files,
    scan,
    session_parts,
)

WALL = 1_700_000_000_000_000_000  # ns: 2023-11-14T22:13:20Z


def fly(rec: SessionRecorder, seconds: float, rate: float = 100.0, t0: float = 100.0) -> list[tuple]:
    """Feed ``seconds`` of traffic (telemetry in, joystick out, an event a second) on an injected clock."""
    board, pc = Encoder(), Encoder()
    fed: list[tuple] = []
    n = int(seconds * rate)
    for i in range(n):
        now = t0 + i / rate
        rx = board.encode(Attitude(2, i % 3000, -i % 3000, 0, 16, -16, 0))
        if i % 10 == 0:
            rx += board.encode(Heartbeat(i // 10, 1000 + i * 10))
        rec.received("serial", rx, now)
        fed.append(("serial", "rx", rx, now))
        tx = pc.encode(Joystick(i, -i, 0, 100, 0))
        rec.sent("ble" if i % 2 else "serial", tx, now)
        fed.append(("ble" if i % 2 else "serial", "tx", tx, now))
        if i % int(rate) == 0:
            rec.event(now, "info", "term", f"tick {i}")
            fed.append(("", "events", f"tick {i}", now))
        rec.poll(now)
    return fed


def as_fed(items: list, t0: float = 100.0) -> list[tuple]:
    out = []
    for it in items:
        now = t0 + (it.t_ns - WALL) / 1e9
        if isinstance(it, LinkBytes):
            out.append((it.link, it.direction, it.data, now))
        else:
            out.append(("", "events", it.text, now))
    return out


def same(got: list[tuple], fed: list[tuple]) -> None:
    assert len(got) == len(fed)
    for g, f in zip(got, fed, strict=True):
        assert g[:3] == f[:3]
        assert g[3] == pytest.approx(f[3], abs=1e-6)  # µs resolution


def test_round_trip_in_order_with_times(tmp_path: Path) -> None:
    rec = SessionRecorder(tmp_path, 100.0, wall_ns=WALL)
    fed = fly(rec, 3.0)
    rec.close()
    assert rec.path is not None and rec.path.name == "20231114-221320.mcap"
    info = scan(rec.path)
    assert info.complete and info.meta["protocol"] == str(PROTOCOL_VERSION) and info.meta["part"] == "1"
    assert info.start_ns == WALL and info.duration_s == pytest.approx(2.99, abs=0.01)
    same(as_fed(list(iter_file(rec.path))), fed)


def test_the_mcap_package_reads_a_closed_recording(tmp_path: Path) -> None:
    rec = SessionRecorder(tmp_path, 100.0, wall_ns=WALL)
    fed = fly(rec, 2.0)
    rec.close()
    assert rec.path is not None
    with rec.path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == len(fed)
        topics = {c.topic for c in summary.channels.values()}
        assert topics == {"/serial/rx", "/serial/tx", "/ble/tx", "/events"}
        events = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=["/events"])]
    assert events[0]["message"] == "tick 0" and events[0]["level"] == 2 and events[0]["name"] == "term"
    assert events[0]["timestamp"] == {"sec": WALL // 10**9, "nsec": 0}


def test_a_file_cut_anywhere_reads_up_to_its_last_flush(tmp_path: Path) -> None:
    """What is on disk while the recorder runs is what a SIGKILL leaves: all but the last second is readable."""
    rec = SessionRecorder(tmp_path, 100.0, wall_ns=WALL)
    fed = fly(rec, 5.5)
    assert rec.path is not None
    on_disk = rec.path.read_bytes()  # the recorder is still open: no summary, no footer
    cut = tmp_path / "cut"
    cut.mkdir()
    crashed = cut / "crashed.mcap"
    crashed.write_bytes(on_disk)
    info = scan(crashed)
    assert not info.complete
    got = as_fed(list(iter_file(crashed)))
    assert got, "nothing readable"
    same(got, fed[: len(got)])
    assert fed[-1][3] - got[-1][3] <= 1.0 + 1e-9  # at most the last second lost
    # Cut at many points, inside records too: never an error, always a prefix of what was fed.
    for end in range(8, len(on_disk), max(1, len(on_disk) // 150)):
        crashed.write_bytes(on_disk[:end])
        part = as_fed(list(iter_file(crashed)))
        same(part, fed[: len(part)])
    # A tail of zeros (a file system that had allocated but not written the last block)
    crashed.write_bytes(on_disk + bytes(4096))
    same(as_fed(list(iter_file(crashed))), got)
    rec.close()


def test_flush_by_poll_alone_when_the_link_is_quiet(tmp_path: Path) -> None:
    rec = SessionRecorder(tmp_path, 0.0, wall_ns=WALL)
    rec.received("serial", Encoder().encode(HeartbeatAck(1, 2)), 0.2)
    assert rec.next_deadline() == pytest.approx(1.0)
    rec.poll(0.9)
    assert rec.path is not None
    assert list(iter_file(rec.path)) == []  # still in the open chunk
    rec.poll(1.0)
    assert [type(i) for i in iter_file(rec.path)] == [LinkBytes]
    assert rec.next_deadline() == float("inf")
    rec.close()


def test_rotation_continues_the_session_in_parts(tmp_path: Path) -> None:
    rec = SessionRecorder(tmp_path, 100.0, wall_ns=WALL, max_file_bytes=8_000)
    fed = fly(rec, 6.0)
    rec.close()
    assert len(rec.paths) >= 3
    assert [p.name for p in rec.paths[:3]] == ["20231114-221320.mcap", "20231114-221320.p2.mcap",
                                               "20231114-221320.p3.mcap"]
    assert session_parts(rec.paths[1]) == rec.paths
    assert all(scan(p).complete for p in rec.paths)
    same(as_fed(list(iter_session(rec.paths[0]))), fed)


def test_the_directory_is_bounded_oldest_first(tmp_path: Path) -> None:
    for k in range(3):
        r = SessionRecorder(tmp_path, 0.0, wall_ns=WALL + k * 3600 * 10**9)
        fly(r, 2.0)
        r.close()
    sizes = [p.stat().st_size for p in list_files(tmp_path)]
    assert len(sizes) == 3
    bound = sizes[1] + sizes[2] + 1000  # room for the two newest and the new file's header
    r = SessionRecorder(tmp_path, 0.0, wall_ns=WALL + 4 * 3600 * 10**9, max_total_bytes=bound)
    r.close()
    names = [p.name for p in list_files(tmp_path)]
    assert names == ["20231114-231320.mcap", "20231115-001320.mcap", "20231115-021320.mcap"]
    assert latest(tmp_path).name == "20231115-021320.mcap"


def test_two_sessions_in_one_second_keep_both(tmp_path: Path) -> None:
    a = SessionRecorder(tmp_path, 0.0, wall_ns=WALL)
    b = SessionRecorder(tmp_path, 0.0, wall_ns=WALL)
    a.close()
    b.close()
    assert a.path != b.path and b.path is not None and b.path.name == "20231114-221320-2.mcap"
    assert latest(tmp_path) == b.path


def test_an_unwritable_directory_stops_the_recording_not_the_caller(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    rec = SessionRecorder(blocker / "recordings", 0.0, wall_ns=WALL)
    assert not rec.recording and rec.error and "recording stopped" in rec.error
    rec.received("serial", b"\x01\x02\x00", 0.1)
    rec.event(0.1, "info", "term", "still flying")
    rec.poll(5.0)
    rec.close()


def test_a_full_disk_stops_the_recording_not_the_caller(tmp_path: Path) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    rec = SessionRecorder(tmp_path, 0.0, wall_ns=WALL)
    assert rec.recording and rec._file is not None
    rec._file.close()
    rec._file = open("/dev/full", "wb")  # noqa: SIM115  # the same writer, now onto a device that is always full
    rec._writer._Writer__stream = rec._file  # type: ignore[union-attr]
    for i in range(300):
        rec.received("serial", bytes(range(1, 20)) + b"\x00", i * 0.01)
    assert not rec.recording and rec.error and "No space left" in rec.error
    rec.close()


def test_what_is_not_a_recording_is_one_clear_error(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("t_us,phi\n1,2\n")
    with pytest.raises(RecordingError, match="not a session recording"):
        scan(p)
    with pytest.raises(RecordingError, match="cannot read"):
        scan(tmp_path / "missing.mcap")
    with pytest.raises(RecordingError, match="no session recordings"):
        latest(tmp_path / "empty")


def test_a_damaged_chunk_inside_is_skipped_and_counted(tmp_path: Path) -> None:
    rec = SessionRecorder(tmp_path, 100.0, wall_ns=WALL)
    fly(rec, 3.0)
    rec.close()
    assert rec.path is not None
    data = bytearray(rec.path.read_bytes())
    pos, chunks = 8, []
    while pos < len(data):  # the record headers: opcode, length
        op, length = struct.unpack_from("<BQ", data, pos)
        if op == Opcode.CHUNK:
            chunks.append((pos, length))
        if op == Opcode.FOOTER:
            break
        pos += 9 + length
    at, length = chunks[1]
    data[at + length - 20 : at + length - 10] = bytes(10)  # inside the second chunk's compressed messages
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "x.mcap").write_bytes(bytes(data))
    whole = list(iter_file(rec.path))
    got = Recording(bad / "x.mcap")
    items = list(iter_file(bad / "x.mcap", got))  # the damaged chunk is skipped, the rest read (issue 36)
    assert [d.start for d in got.damage] == [at] and got.complete
    assert 0 < len(items) < len(whole) and f"at byte {at:,}" in got.damage_text


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a pty and /proc")
def test_term_killed_in_flight_leaves_a_recording_readable_up_to_its_last_second(tmp_path: Path) -> None:
    """`term --sim` in a real terminal, SIGKILLed while telemetry streams: no close, no summary. The file reads
    to within a second of the kill, frames in order, and exports to a complete MCAP."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "term.cli.main", "--sim", "--no-joystick", "--no-radio",
                             "--record-dir", str(tmp_path)], stdin=slave, stdout=slave, stderr=slave,
                            start_new_session=True, env={**os.environ, "TERM": "xterm-256color"})
    os.close(slave)
    drawn = b""
    try:
        deadline = time.monotonic() + 30
        started: float | None = None
        while time.monotonic() < deadline:  # keep draining the screen: term must never block on it
            if select.select([master], [], [], 0.05)[0]:
                drawn = (drawn + os.read(master, 65536))[-200_000:]
            if started is None and b"link OK" in drawn:
                started = time.monotonic()
            if started is not None and time.monotonic() - started > 2.5:
                break
        assert started is not None, "term --sim did not come up"
        killed_at = time.time_ns()
        proc.kill()  # SIGKILL: nothing of term runs after this
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    files = list_files(tmp_path)
    assert len(files) == 1
    info = scan(files[0])
    assert not info.complete and info.last_ns is not None
    assert killed_at - info.last_ns <= 1.5e9  # the flush period (1 s), and room for a loaded machine
    frames = [p for i in decode(iter_file(files[0])) if isinstance(i, DecodedFrame) and i.direction == "rx"
              for p in [i.packet]]
    attitudes = [p for p in frames if isinstance(p, Attitude)]
    assert len(attitudes) > 50 and all(p.mode == Mode.SAFE for p in attitudes)
    (tmp_path / "out").mkdir()  # (export makes no folder: a typo in a path is said, not created)
    res = export(files[0], tmp_path / "out" / "flight.mcap")
    assert not res.complete and res.rows > len(frames)
    with (tmp_path / "out" / "flight.mcap").open("rb") as f:
        assert make_reader(f).get_summary() is not None


async def test_the_app_records_its_events_list_and_says_once_when_the_recording_stops(tmp_path: Path) -> None:
    from term.ui.app import TermApp

    rec = SessionRecorder(tmp_path, time.monotonic())
    app = TermApp(None, joystick=False, recorder=rec)
    async with app.run_test(size=(120, 44)) as pilot:
        app.station.note("info", "term", "first line")
        app.model.note(app.clock(), "warning", "term", "straight into the model")  # as the log download does
        await pilot.pause(0.2)
        rec.flush(app.clock())  # (a failure drops what waits in the open chunk)
        rec._fail(OSError(28, "No space left on device"))
        await pilot.pause(0.3)
        said = [e.text for e in app.model.events if "recording stopped" in e.text]
        assert said == ["recording stopped: [Errno 28] No space left on device"]
        app.station.note("info", "term", "after the stop")
        await pilot.pause(0.2)
    rec.close()
    assert rec.path is not None
    lines = [(i.severity, i.text) for i in iter_file(rec.path) if isinstance(i, LoggedEvent)]
    assert ("info", "first line") in lines and ("warning", "straight into the model") in lines
    assert not any("after the stop" in t for _, t in lines)
