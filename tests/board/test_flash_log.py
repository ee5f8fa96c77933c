"""The flash log: both codecs round-trip within their error bound, the flash fills and stops, segments close
by programming their header, and a download survives lost chunks (resume) and is checked end to end."""

from __future__ import annotations

import random
import zlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fcb_sim.board.flash_log import LOG_VARS, FlashLog, LogVar, encode_log
from term.core.logfile import LogDownload, decode_to_rows, write_csv
from term.core.logformat import SCHEME_DELTA8, SCHEME_RICE, decode_log
from term.core.protocol import LogChunk, LogState, LogStatus, Nak

VARS = (LogVar("t", 32), LogVar("a", 1), LogVar("b", 4), LogVar("c", 8))
BOUND = [v.scale // 2 for v in VARS]


def walk(n: int, seed: int, step: int = 40) -> list[tuple[int, ...]]:
    rng = random.Random(seed)
    rows, x = [], [0, 5, -300, 16000]
    for i in range(n):
        x = [i * 2500 + rng.randrange(-30, 30), x[1] + rng.choice((0, 0, 1, -1)),
             x[2] + rng.randrange(-step, step), x[3] + rng.randrange(-4 * step, 4 * step)]
        rows.append(tuple(x))
    return rows


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(-2**31, 2**31 - 1), st.integers(-50_000, 50_000),
                          st.integers(-32768, 32767), st.integers(-32768, 32767)), min_size=1, max_size=60))
def test_rice_round_trip_within_the_bound_for_any_data(rows: list[tuple[int, ...]]) -> None:
    rows = [(r[0] // 2, *r[1:]) for r in rows]  # keep t's quantised index inside int32 arithmetic
    seg = decode_log(encode_log(rows, "rice", VARS))[0]
    assert len(seg.rows) == len(rows) and seg.closed
    for got, want in zip(seg.rows, rows, strict=True):
        assert all(abs(g - w) <= b for g, w, b in zip(got, want, BOUND, strict=True))


def test_delta8_is_exact_to_the_bound_without_overload_and_errors_do_not_accumulate() -> None:
    rows = walk(5000, 1, step=20)  # every change fits 127 * scale
    seg = decode_log(encode_log(rows, "delta8", VARS))[0]
    errors = [max(abs(g - w) - b for g, w, b in zip(got, want, BOUND, strict=True))
              for got, want in zip(seg.rows, rows, strict=True)]
    assert max(errors) <= 0  # the error term keeps every sample within scale/2, even after 5000 records


def test_delta8_overloads_on_a_jump_and_catches_up_rice_does_not() -> None:
    rows = [(0, 0, 0, 0)] * 5 + [(0, 0, 4000, 0)] * 20  # a jump of 1000 steps of 4
    d8 = decode_log(encode_log(rows, "delta8", VARS))[0].rows
    assert d8[5][2] == 127 * 4 and d8[6][2] == 2 * 127 * 4  # slope overload: 127 steps per record ...
    assert decode_log(encode_log(rows + [(0, 0, 4000, 0)] * 20, "delta8", VARS))[0].rows[-1][2] == 4000
    assert decode_log(encode_log(rows, "rice", VARS))[0].rows[5][2] == 4000  # ... an escape code has none


def test_rice_is_smaller_than_delta8_and_zlib_on_smooth_data() -> None:
    rows = walk(4000, 2, step=10)
    rice, d8 = encode_log(rows, "rice", VARS), encode_log(rows, "delta8", VARS)
    raw = b"".join(v.to_bytes(4, "little", signed=True) for r in rows for v in r)
    assert len(rice) < len(d8) < len(raw)
    assert len(rice) < len(zlib.compress(raw, 9))


def test_flash_full_stops_logging_and_everything_written_decodes() -> None:
    log = FlashLog(size=2048, scheme="delta8", variables=VARS)
    assert log.start() == (Nak.OK, log.used)
    n = 0
    for row in walk(1000, 3, step=5):
        log.append(row)
        if log.state != LogState.RECORDING:
            break
        n += 1
    assert log.state == LogState.FULL and log.used <= 2048
    assert log.append((1, 2, 3, 4)) == 0
    assert log.start()[0] == Nak.LOG_FULL
    seg = decode_log(log.contents())[0]
    assert len(seg.rows) == n == log.records and seg.closed


def test_segments_and_reset_only_in_safe() -> None:
    log = FlashLog(variables=VARS)
    for k in range(3):
        log.start()
        for row in walk(50 + k, k):
            log.append(row)
        log.stop()
    segs = decode_log(log.contents())
    assert [len(s.rows) for s in segs] == [50, 51, 52] and all(s.scheme == SCHEME_RICE for s in segs)
    assert log.reset(in_safe=False) == Nak.NOT_IN_SAFE and log.used
    log.start()
    assert log.reset(in_safe=True) == Nak.LOG_BUSY
    log.stop()
    assert log.reset(in_safe=True) == Nak.OK and log.used == 0 and log.contents() == b""


def test_unclosed_segment_decodes_up_to_its_end() -> None:
    log = FlashLog(scheme="delta8", variables=VARS)
    log.start()
    for row in walk(30, 4):
        log.append(row)
    seg = decode_log(log.contents())[0]  # power lost while recording: the header's count is still erased
    assert not seg.closed and len(seg.rows) == 30 and seg.scheme == SCHEME_DELTA8


def test_flash_only_clears_bits() -> None:
    log = FlashLog(variables=VARS)
    log.start()
    log.append((1, 2, 3, 4))
    log.stop()
    before = log.contents()
    log.flash.program(0, b"\xff" * 8)  # programming ones changes nothing on NOR flash
    assert log.contents() == before


def _download(log: FlashLog, crc32: int) -> LogDownload:
    d = LogDownload(started=0.0)
    d.feed(LogStatus(LogState.IDLE, log.used, log.records, crc32), 0.0)
    return d


def test_download_with_lost_chunks_resumes_and_checks_the_crc() -> None:
    log = FlashLog()
    log.start()
    rng = random.Random(5)
    for i in range(400):
        log.append([i * 2500] + [rng.randrange(-100, 100) for _ in LOG_VARS[1:]])
    log.stop()
    d = _download(log, log.crc32())
    first: int | None = 0
    rounds = 0
    while first is not None:
        rounds += 1
        for i in range(first, log.n_chunks):  # the board streams from the asked chunk; a third is lost
            if rng.random() > 0.33:
                d.feed(LogChunk(i, log.chunk(i)), 0.0)
        first = d.missing()
    assert rounds > 1 and d.done and d.verify() is None
    assert d.data() == log.contents()
    bad = _download(log, log.crc32() ^ 1)
    for i in range(log.n_chunks):
        bad.feed(LogChunk(i, log.chunk(i)), 0.0)
    assert "CRC-32 mismatch" in (bad.verify() or "")
    assert "incomplete" in (_download(log, 0).verify() or "")


def test_csv(tmp_path) -> None:
    data = encode_log([(0, 1, 2, 3), (2500, 1, 6, 7)], "rice", VARS)
    path = tmp_path / "log.csv"
    assert write_csv(data, path, decode_to_rows) == 2
    lines = path.read_text().splitlines()
    assert lines[0] == "segment,t,a,b,c"
    assert lines[2].split(",")[:3] == ["0", "2496", "1"]  # t on its 32 µs grid
    assert len(lines) == 3


def test_corrupt_log_is_a_value_error() -> None:
    with pytest.raises(ValueError):
        decode_log(b"XX" + bytes(30))
