"""qb_log on the Python board (fcb_sim/board/console.py): a line reaches the terminal's console whole, cut at
QB_LOG_MAX bytes; a burst that fills the transmit side is dropped line by line and counted, never sent in part,
and never in the way of the heartbeats."""

from __future__ import annotations

from fcb_sim.board.console import QB_LOG_MAX, qb_log
from term.core.console import Console
from term.core.protocol import LEVEL_ERROR, LEVEL_INFO, Heartbeat
from tests.support.bench_rig import Pc, make_board


def test_a_line_reaches_the_console_with_its_level_and_a_long_one_is_cut() -> None:
    pc = Pc(make_board("python"))
    pc.run(0.1)
    assert qb_log(pc.board.parts, LEVEL_ERROR, "imu: %s after %d tries", "timeout", 3)
    assert qb_log(pc.board.parts, LEVEL_INFO, "x" * 100)
    pc.run(0.1)
    assert [(x.text, x.level) for x in pc.lines] == [("imu: timeout after 3 tries", LEVEL_ERROR),
                                                      ("x" * QB_LOG_MAX, LEVEL_INFO)]
    assert pc.dec.stats.frames_bad == 0


def test_a_burst_is_dropped_whole_lines_and_counted_and_heartbeats_keep_coming() -> None:
    pc = Pc(make_board("python"))
    pc.run(0.1)
    parts = pc.board.parts
    sent = [qb_log(parts, LEVEL_INFO, "burst line %03d padded to be long enough", i) for i in range(400)]
    beats = len(pc.of(Heartbeat))
    pc.console = Console(rate=1e9, burst=10**9)  # the terminal's own limit aside: what the board sent
    pc.run(1.0)
    assert parts.console.dropped == sent.count(False) > 0
    assert parts.console.sent == sent.count(True)
    got = [x.text for x in pc.lines]
    want = [f"burst line {i:03d} padded to be long enough" for i, ok in enumerate(sent) if ok]
    assert got == want  # whole lines, in order, none in part
    assert len(pc.of(Heartbeat)) - beats >= 8  # 10 Hz, undisturbed
