"""The C board's flash log (issue 37: LOG_* answered NOT_IMPLEMENTED): firmware/board/qb_log.c writes the same bytes
as fcb_sim's encoder for the same records, delta8 and Rice, and a flight's log downloads and decodes with term's
decoder. The same flight on both boards is tests/firmware/test_cboard_diff.py's."""

from __future__ import annotations

import math
import random
import re
import shutil
import zlib
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fcb_sim.board.flash_log import LOG_VARS, encode_log
from fcb_sim.board.parts import BoardConfig
from fcb_sim.hosts import cboard
from fcb_sim.world.physics import World
from term.core import logformat
from term.core.link import LinkSession
from term.core.protocol import (
    SCHEME_DELTA8,
    SCHEME_RICE,
    Ack,
    Command,
    Decoder,
    Joystick,
    LogChunk,
    LogState,
    LogStatus,
    Mode,
    Nak,
    Op,
    encode,
)
from term.session.download import DONE
from term.transports.loopback import Faults, FaultyChannel
from tests.support.download_rig import NEUTRAL, Rig

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make: the C board's tests are skipped")
SCHEMES = (SCHEME_DELTA8, SCHEME_RICE)


@pytest.fixture(scope="module")
def board() -> cboard.CBoard:
    return cboard.CBoard(BoardConfig(seed=1))


def test_the_c_logs_format_is_the_python_boards() -> None:
    src = (cboard.FIRMWARE / "board" / "qb_log.c").read_text()
    names = re.search(r"VAR_NAMES\[QB_LOG_VARS\]\[9\] = \{(.*?)\};", src, re.S).group(1)  # type: ignore[union-attr]
    scales = re.search(r"VAR_SCALES\[QB_LOG_VARS\] = \{(.*?)\};", src, re.S).group(1)  # type: ignore[union-attr]
    assert re.findall(r'"(\w+)"', names) == [v.name for v in LOG_VARS]
    assert [int(s) for s in scales.split(",")] == [v.scale for v in LOG_VARS]
    consts = dict(re.findall(r"#define (LOG_FORMAT_VERSION|RICE_ESCAPE|RICE_RESET) (\d+)", src))
    assert {k: int(v) for k, v in consts.items()} == {"LOG_FORMAT_VERSION": logformat.LOG_FORMAT_VERSION,
                                                      "RICE_ESCAPE": logformat.RICE_ESCAPE,
                                                      "RICE_RESET": logformat.RICE_RESET}


def _flight_rows(n: int, seed: int) -> list[tuple[int, ...]]:
    """Rows like a flight's: smooth signals with noise, steps (a mode change, a motor jump) and a spike."""
    rng = random.Random(seed)
    rows = []
    for i in range(n):
        t = 1_000_000 + 5000 * i + rng.randrange(-3, 4)
        mode = 5 if 50 <= i < 250 else 0
        att = [round(300 * math.sin(i / (20 + k))) + rng.randrange(-5, 6) for k in range(3)]
        rates = [rng.randrange(-400, 401) for _ in range(3)]
        acc = [rng.randrange(-900, 901), rng.randrange(-900, 901), 16384 + rng.randrange(-300, 301)]
        ae = [0] * 4 if mode == 0 else [480 + rng.randrange(-40, 41) for _ in range(4)]
        height = i // 3 + (5000 if i == 120 else 0)
        rows.append((t, mode, *att, *rates, *acc, *ae, height, 101325 - i // 10 + rng.randrange(-2, 3), 1180))
    return rows


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_flights_rows_give_the_same_bytes(board: cboard.CBoard, scheme: int) -> None:
    rows = _flight_rows(400, seed=scheme)
    data = board.log_encode(rows, scheme)
    assert data == encode_log(rows, scheme)
    (seg,) = logformat.decode_log(data)
    assert len(seg.rows) == len(rows) and seg.closed


_INT32 = st.integers(-(2**31), 2**31 - 1)
_ROW = st.one_of(st.tuples(*[_INT32] * len(LOG_VARS)),
                 st.tuples(*[st.integers(-300, 300)] * len(LOG_VARS)))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(SCHEMES), st.lists(_ROW, min_size=1, max_size=40))
def test_any_rows_give_the_same_bytes(board: cboard.CBoard, scheme: int, rows: list[tuple[int, ...]]) -> None:
    """Extremes included: int32's ends (delta8's slope overload, Rice's escapes and a residual past 32 bits)."""
    assert board.log_encode(rows, scheme) == encode_log(rows, scheme)


def _drive(b: cboard.CBoard, dec: Decoder, until: int, got: list[Any], lift: int = 0) -> None:
    while b.now < until:
        b.advance(b.now + 20_000)
        b.uart_receive(encode(Joystick(0, 0, 0, lift, 0)))
        got += dec.feed(b.uart_transmit())


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_flights_log_downloads_and_decodes(scheme: int) -> None:
    from fcb_sim.hosts.cboard import _pilot_lift

    b = cboard.CBoard(BoardConfig(seed=2, log_scheme="delta8" if scheme == SCHEME_DELTA8 else "rice"))
    dec, got = Decoder(), []
    _drive(b, dec, 200_000, got)
    for i, (op, arg) in enumerate(((Op.LOG_START, 0), (Op.MODE, Mode.CALIBRATION))):
        b.uart_receive(encode(Command(i + 1, op, int(arg))))
    _drive(b, dec, 1_500_000, got)
    b.uart_receive(encode(Command(3, Op.MODE, int(Mode.FULL))))
    while b.now < 3_500_000:
        _drive(b, dec, b.now + 20_000, got, _pilot_lift(b.world, 1.0))
    b.uart_receive(encode(Command(4, Op.LOG_DOWNLOAD, 0)))  # refused: not in SAFE
    _drive(b, dec, b.now + 40_000, got)
    for i, op in enumerate((Op.LOG_STOP, Op.MODE, Op.LOG_STATUS, Op.LOG_DOWNLOAD)):
        b.uart_receive(encode(Command(5 + i, op, int(Mode.PANIC) if op == Op.MODE else 0)))
    _drive(b, dec, b.now + 200_000, got)  # PANIC: the download is refused (not SAFE) ...
    _drive(b, dec, b.now + 6_000_000, got)  # ... the descent, SAFE by itself
    b.uart_receive(encode(Command(9, Op.LOG_DOWNLOAD, 0)))
    _drive(b, dec, b.now + 3_000_000, got)
    acks = {a.cmd_id: a for a in got if type(a) is Ack}
    assert acks[1].status == Nak.OK and acks[4].status == acks[8].status == Nak.NOT_IN_SAFE
    assert acks[9].status == 0 and acks[9].value > 50
    chunks = {c.index: c.data for c in got if type(c) is LogChunk}
    assert sorted(chunks) == list(range(acks[9].value))
    data = b"".join(chunks[i] for i in range(len(chunks)))
    final = [s for s in got if type(s) is LogStatus][-1]
    data = data[: final.used]
    assert final.state == LogState.IDLE and zlib.crc32(data) == final.crc32
    (seg,) = logformat.decode_log(data)
    assert seg.closed and seg.scheme == scheme and len(seg.rows) == final.records > 300
    modes = [row[1] for row in seg.rows]
    assert Mode.FULL in modes and Mode.CALIBRATION in modes
    t = [row[0] for row in seg.rows]
    assert all(0 < b2 - a2 <= 5032 + 32 for a2, b2 in zip(t, t[1:], strict=False))  # one record per control step


class _CRig(Rig):
    """tests/support/download_rig.Rig with the C board in place of the Python board (the terminal's side as it is)."""

    def __init__(self, seed: int, record_s: float) -> None:
        self.board = cboard.CBoard(BoardConfig(seed=seed, log_scheme="rice"), world=World(seed))  # type: ignore
        self.session = LinkSession(0.0)
        self.session.set_joystick(NEUTRAL)
        self.up, self.down = FaultyChannel(seed=seed * 2), FaultyChannel(seed=seed * 2 + 1)
        self.now = 0.0
        self.dl = None
        self.events = []
        self.up.send(self.session.hello(), 0.0)
        self.run(0.3)
        self.command(Op.LOG_START)
        self.run(record_s)
        self.command(Op.LOG_STOP)
        self.run(0.1)


@pytest.mark.parametrize("seed", [1, 2])
def test_the_terminals_download_takes_the_c_boards_log_through_a_damaging_link(seed: int) -> None:
    """F5's download (term.session.download.LogDownloader) against the C board, 3 % of the bytes damaged both ways:
    the whole log, its CRC-32 the board's, decoded by term's decoder."""
    rig = _CRig(seed, record_s=1.0)
    rig.faults(Faults(corrupt=0.03), Faults(corrupt=0.03))
    d = rig.download()
    assert d.state == DONE, d.reason
    assert d.verify() is None and zlib.crc32(d.data()) == d.crc32
    (seg,) = logformat.decode_log(d.data())
    assert seg.closed and len(seg.rows) > 150 and seg.scheme == SCHEME_RICE
