"""The C board's task profile (issue 37: PROFILE answered NOT_IMPLEMENTED, the Status packet's CPU load read 0):
each task timed by hal_time_us() before and after (firmware/board/qb_prof.c). On the host the board's time stands
still in lockstep, so the durations are the host CPU's own (hal_host.c); the periods are the board's, and must be
the Python board's. The arithmetic, the CPU load and the deadline misses with tasks that take time are
`make -C firmware board-test`'s (test_profile, test_profile_in_the_loop)."""

from __future__ import annotations

import re
import shutil
from typing import Any

import pytest

from fcb_sim.board.board import Board
from fcb_sim.board.parts import BoardConfig
from fcb_sim.board.scheduler import TASKS
from fcb_sim.board.timing import WCET99_US
from fcb_sim.hosts import cboard
from term.core.protocol import Ack, Command, Decoder, Op, Profile, Status, encode

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make: the C board's tests are skipped")


def test_the_deadlines_are_the_python_boards() -> None:
    src = (cboard.FIRMWARE / "board" / "qb_prof.c").read_text()
    found = {m.group(1).lower(): int(m.group(2)) for m in re.finditer(r"#define WCET99_(RAW|DMP)_US (\d+)u", src)}
    assert found == WCET99_US


def _profile(board: Any) -> tuple[list[Profile], list[Status], Ack]:
    dec = Decoder()
    for t in range(20_000, 3_000_001, 20_000):
        board.advance(t)
        dec.feed(board.uart_transmit())
    board.uart_receive(encode(Command(9, Op.PROFILE, 0)))
    board.advance(3_300_000)
    got = dec.feed(board.uart_transmit())
    ack = next(p for p in got if type(p) is Ack)
    return [p for p in got if type(p) is Profile], [p for p in got if type(p) is Status], ack


def test_profile_answers_every_task_with_the_python_boards_periods() -> None:
    c_prof, c_status, c_ack = _profile(cboard.CBoard(BoardConfig(seed=3)))
    py_prof, _, py_ack = _profile(Board(BoardConfig(seed=3)))
    assert (c_ack.status, c_ack.value) == (py_ack.status, py_ack.value) == (0, len(TASKS))
    assert [p.task for p in c_prof] == list(range(len(TASKS)))
    for c, py in zip(c_prof, py_prof, strict=True):
        if TASKS[c.task] in ("sensor", "control", "baro", "telemetry", "heartbeat"):
            assert c.period_us == pytest.approx(py.period_us, rel=0.02), TASKS[c.task]
        assert c.mean_us <= c.p99_us <= c.p999_us < 65535
        assert c.misses == 0
    periods = {TASKS[p.task]: p.period_us for p in c_prof}
    assert periods["control"] == pytest.approx(5000, rel=0.01) and periods["heartbeat"] == pytest.approx(100_000, 0.01)
    assert periods["logging"] == 0  # no log recording
    assert 0 < periods["parse"] < 100_000  # every pass reads the UART (a pass that starts the host's clock again
    # at the lockstep time once read as a period of 2**32 µs)
    assert c_status and all(0 <= s.cpu_load <= 100 for s in c_status)
