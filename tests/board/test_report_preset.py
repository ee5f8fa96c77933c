"""The `report` preset is the report's board (issue 27), one test a behaviour: its delta log (section 3.5), its
telemetry period (1.9 s) and heartbeat period (324-327 ms, Figure 14), calibration for as long as CALIBRATION is
held (3.6), PANIC's countdown (3.2). The default preset keeps ours. Board time is the clock."""

from __future__ import annotations

import statistics

from fcb_sim.board.board import Board, BoardConfig
from term.core.protocol import (
    REPORT_PANIC_COUNTDOWN_MS,
    SCHEME_DELTA8,
    SCHEME_RICE,
    Attitude,
    Event,
    EventCode,
    Heartbeat,
    Joystick,
    LogChunk,
    Mode,
    Nak,
    Op,
    Status,
)
from tests.support.board_rig import HOVER_LIFT, Pc


def board(preset: str) -> tuple[Board, Pc]:
    b = Board(BoardConfig(seed=1, preset=preset))
    return b, Pc(b)


def heartbeat_gaps(pc: Pc) -> list[int]:
    """Board-ms between the Heartbeats the PC received (each carries the board's clock)."""
    times = [p.board_ms for p in pc.of(Heartbeat)]
    return [b - a for a, b in zip(times, times[1:], strict=False)]


def test_the_report_logs_deltas_and_ours_rice() -> None:
    b, pc = board("report")
    assert b.log.scheme == SCHEME_DELTA8 and b.config.log_scheme == "delta8"  # section 3.5's delta packets
    assert board("default")[0].log.scheme == SCHEME_RICE


def test_the_reports_heartbeat_period() -> None:
    b, pc = board("report")
    pc.run(5.0)
    gaps = heartbeat_gaps(pc)
    assert 324 <= statistics.mean(gaps) <= 327  # Figure 14: 324 ms (SAFE), 327 ms (FULL)
    b, pc = board("default")
    pc.run(2.0)
    assert abs(statistics.mean(heartbeat_gaps(pc)) - 100) < 1


def test_the_reports_telemetry_period() -> None:
    b, pc = board("report")
    pc.run(12.0)
    n = len(pc.of(Attitude))
    assert 12.0 / 1.95 - 1 <= n <= 12.0 / 1.89 + 1  # a telemetry run every 1.9 s (Figure 14: 1910, 1918 ms)
    b, pc = board("default")
    pc.run(1.0)
    assert 48 <= len(pc.of(Attitude)) <= 51  # ours: 50 Hz


def test_the_report_calibrates_for_as_long_as_calibration_is_held() -> None:
    b, pc = board("report")
    assert pc.command(Op.MODE, Mode.CALIBRATION).status == Nak.OK
    pc.run(3.0)
    assert b.mode == Mode.CALIBRATION and not b.modes.calibrated  # no timer: the pilot decides
    assert pc.command(Op.MODE, Mode.SAFE).status == Nak.OK
    assert b.modes.calibrated
    (done,) = [e for e in pc.of(Event) if e.code == EventCode.CALIBRATION_DONE]
    assert done.arg >= 3.0 * 200 * 0.95  # every sample of the 3 s it was held (DMP path: 200 Hz)
    b, pc = board("default")
    pc.command(Op.MODE, Mode.CALIBRATION)
    pc.run(1.2)
    assert b.mode == Mode.SAFE and b.modes.calibrated  # ours: 1 s, then SAFE by itself


def test_the_reports_panic_counts_down_at_a_fixed_level_then_stops() -> None:
    b, pc = board("report")
    pc.command(Op.MODE, Mode.CALIBRATION)
    pc.run(1.0)
    pc.command(Op.MODE, Mode.SAFE)
    assert pc.command(Op.MODE, Mode.FULL).status == Nak.OK
    pc.js = Joystick(0, 0, 0, HOVER_LIFT, 0)
    pc.run(2.0)
    pc.js = Joystick(0, 0, 0, 0, 0)
    assert pc.command(Op.MODE, Mode.PANIC).status == Nak.OK
    start = [c for c in b.modes.changes if c.new == Mode.PANIC][-1].now
    levels = []
    while b.mode == Mode.PANIC:
        pc.run(0.05)
        if b.mode == Mode.PANIC and b.now / 1e6 - start > 0.1:
            levels.append(sum(b.ae) / 4)
    end = [c for c in b.modes.changes if c.old == Mode.PANIC][-1].now
    assert abs(end - start - REPORT_PANIC_COUNTDOWN_MS / 1000) < 0.01  # the countdown, to the control period
    assert b.ae == (0, 0, 0, 0) and b.mode == Mode.SAFE
    assert max(levels) - min(levels) < 60 and max(levels) <= b.core.panic_ae + 30  # a level under hover, held


def download_seconds(preset: str) -> tuple[float, int, list[Status]]:
    """Record 4 s in SAFE, then download: board seconds from the Ack to LOG_DONE, the bytes, the Status seen."""
    b, pc = board(preset)
    pc.run(0.5)
    assert pc.command(Op.LOG_START).status == Nak.OK
    pc.run(4.0)
    assert pc.command(Op.LOG_STOP).status == Nak.OK
    start, first = b.now, len(pc.packets)
    assert pc.command(Op.LOG_DOWNLOAD, 0).status == Nak.OK
    while not any(type(p) is Event and p.code == EventCode.LOG_DONE for p in pc.packets[first:]):
        assert b.now - start < 120e6, "the download did not end in 120 s"
        pc.run(0.1)
    got = sum(len(p.data) for p in pc.packets[first:] if type(p) is LogChunk)
    return (b.now - start) / 1e6, got, [p for p in pc.packets[first:] if type(p) is Status]


def test_the_report_preset_downloads_as_fast_as_the_wire_takes() -> None:
    """The download rides the telemetry task; the report's 1.9 s telemetry period must not pace it (it did:
    0.32 kB/s, a Status every 19 s, and the terminal's readiness said 'not known yet' all the while)."""
    ours_s, ours_bytes, _ = download_seconds("default")
    s, n, status = download_seconds("report")
    assert n / s >= 0.8 * ours_bytes / ours_s  # bytes a second, as the default preset's download
    assert len(status) >= s / 2.5  # the terminal keeps hearing the board's Status while it downloads
