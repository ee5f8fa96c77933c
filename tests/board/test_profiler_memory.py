"""The board's profiling statistics are of bounded size (issue 36): task durations in a fixed histogram
(fcb_sim/board/timing.py), the same percentiles as a sorted list to the µs below 1024 µs and within 1/64 above, and
the profiler's memory flat over a long flight."""

from __future__ import annotations

import random
import sys
import tracemalloc
from collections import deque

import pytest

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.timing import DurationHistogram, TaskStats
from fcb_sim.world.physics import World


def _sorted_percentile(data: list[int], q: float) -> float:
    s = sorted(data)
    return float(s[min(len(s) - 1, int(q * len(s)))])


@pytest.mark.parametrize("seed", range(5))
def test_percentiles_are_the_sorted_lists_below_1024_us_and_within_a_64th_above(seed: int) -> None:
    rng = random.Random(seed)
    small = [max(0, int(rng.lognormvariate(4.5, 0.6))) % 1024 for _ in range(20_000)]
    wide = [int(rng.lognormvariate(8.0, 2.5)) for _ in range(20_000)] + [0, 1, 1023, 1024, 2**45]
    for data, exact in ((small, True), (wide, False)):
        h = DurationHistogram()
        for d in data:
            h.add(d)
        for q in (0.0, 0.5, 0.9, 0.99, 0.999, 1.0):
            want, got = _sorted_percentile(data, q), h.percentile(q)
            if exact or want < DurationHistogram.EXACT_US:
                assert got == want, (q, got, want)
            elif want < 2**DurationHistogram.MAX_EXP:
                assert want * (1 - 1 / 64) < got <= want, (q, got, want)


def test_a_bin_s_lower_edge_is_in_the_bin() -> None:
    for us in [*range(0, 5000), *(2**k + j for k in range(10, 41) for j in (-1, 0, 1, 12345))]:
        i = DurationHistogram.index(us)
        assert DurationHistogram.lower(i) <= us and (i + 1 == DurationHistogram.BINS
                                                      or DurationHistogram.lower(i + 1) > us), us


def test_a_hundred_thousand_runs_cost_what_the_first_did() -> None:
    st = TaskStats()
    st.add(0, 100)
    tracemalloc.start()
    try:
        before = tracemalloc.take_snapshot()
        for i in range(1, 100_000):
            st.add(i * 2500, 50 + (i * 7919) % 3000)
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    grown = sum(s.size_diff for s in after.compare_to(before, "filename")
                if s.traceback[0].filename.endswith("timing.py"))
    assert grown < 4096, grown
    assert st.n == 100_000 and 50 <= st.percentile(0.5) <= 3050


def _deep_size(obj: object, seen: set[int] | None = None) -> int:
    """Bytes held by ``obj`` and everything it refers to (containers, instances' attributes)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return 0
    seen.add(id(obj))
    size = sys.getsizeof(obj)
    if isinstance(obj, dict):
        size += sum(_deep_size(k, seen) + _deep_size(v, seen) for k, v in obj.items())
    elif isinstance(obj, list | tuple | set | frozenset | deque):
        size += sum(_deep_size(x, seen) for x in obj)
    elif hasattr(obj, "__dict__"):
        size += _deep_size(vars(obj), seen)
    return size


def test_the_profiler_stays_the_same_size_in_a_long_flight() -> None:
    """The board for 20 simulated seconds, then 60 more: what the profiler holds does not grow (the old queues
    grew by some 400 durations a second until 50,000 a task, 1.6 MB a minute in flight: 190 kB in those 60 s)."""
    board = Board(BoardConfig(seed=3), world=World(3))
    board.advance(20_000_000)
    before = _deep_size(board.prof)
    board.advance(80_000_000)
    after = _deep_size(board.prof)
    runs = sum(st.n for st in board.prof.stats.values())
    assert runs > 35_000 and after - before < 1024, (runs, before, after)
    assert after < 400_000  # some 25 kB of bins a task
    assert board.prof.stats["control"].percentile(0.99) > 0
