"""The plotted series' history (term/session/history.py, issue 36): a deque's behaviour in rings allocated up front,
and the model's stores full within the soak's warm-up, counted on a simulated clock."""

from __future__ import annotations

import random
import tracemalloc
from collections import deque

import pytest

from term.core.protocol import Attitude, Compact, Compact2, Height, Motion
from term.session.history import Series
from term.session.model import HISTORY, Model


def test_a_series_reads_as_the_deque_it_replaces() -> None:
    rng = random.Random(36)
    for maxlen in (1, 2, 7, 50):
        s, d = Series(maxlen), deque(maxlen=maxlen)
        for n in range(3 * maxlen + 5):
            sample = (n * 0.02, rng.uniform(-1e3, 1e3))
            s.append(sample)
            d.append(sample)
            assert list(s) == list(d) and list(reversed(s)) == list(reversed(d)) and len(s) == len(d)
            assert s[0] == d[0] and s[-1] == d[-1] and s[len(s) // 2] == d[len(d) // 2]
            assert s[1:3] == list(d)[1:3]
        with pytest.raises(IndexError):
            s[maxlen]
        with pytest.raises(IndexError):
            s[-maxlen - 1]
    s.clear()
    assert list(s) == [] and not s


def test_a_series_holds_all_its_memory_from_the_start() -> None:
    s = Series(HISTORY)
    size = s.nbytes
    assert size == 16 * HISTORY
    for n in range(2 * HISTORY):
        s.append((n / 50, float(n)))
        assert s.nbytes == size
    assert len(s) == HISTORY and s[0] == (HISTORY / 50, float(HISTORY))


def test_the_models_plot_history_holds_its_memory_from_the_first_packet_of_each_kind() -> None:
    """Every telemetry kind at 50 Hz on a simulated clock for more than HISTORY ticks (each series overflows its
    ring): what the model holds after the first packet of each kind does not grow, counted by tracemalloc (the
    deque of tuples it replaces grew about 110 bytes a sample, 5 MB over the 16 series, and filled as slowly as its
    slowest packet came: 25 minutes of the soak). The samples kept stop at HISTORY a series."""
    m = Model(start=0.0)
    kinds = (Attitude(0, 1, 2, 3, 4, 5, 6), Motion(0, 0, 16384, 300, 310, 320, 330),
             Height(101325, 12, 0, 3, 1160, 2100), Compact(0, 0, 1, 2, 3, 1160),
             Compact2(75, 77, 78, 80, 12, 0, 3, 0, 0))

    def tick(k: int) -> None:
        t = k / 50
        for pkt in kinds:
            m.apply_packet(pkt, t)

    tick(0)
    m.series("phi", 60.0, 0.0)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for k in range(1, HISTORY + 100):
            tick(k)
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert grown < 16_000, f"the model's memory grew {grown} bytes after its first packets"
    assert {len(d) for d in m.history.values()} == {HISTORY}, "every series keeps its full window once filled"
    xs, ys = m.series("phi", 60.0, (HISTORY + 99) / 50)
    assert len(xs) == len(ys) > HISTORY // 3 and ys[-1] == pytest.approx(0.01), "the plots read the newest minute"
