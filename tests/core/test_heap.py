"""term/core/heap.py: glibc's free pages given back once a minute from the front end's tick (issue 36)."""

from __future__ import annotations

import platform
import sys

import pytest

from term.core.heap import HeapTrim, malloc_trim


def test_it_trims_once_a_period_whatever_the_tick_rate() -> None:
    calls: list[int] = []
    h = HeapTrim(60.0, trim=lambda pad: calls.append(pad) or 1)
    ticks = [k / 12 for k in range(12 * 185)]  # the render tick at 12 Hz for 185 s
    done = [t for t in ticks if h.tick(t)]
    assert calls == [0, 0, 0] and h.trims == 3
    assert done == pytest.approx([60.0, 120.0, 180.0], abs=0.1)


def test_without_malloc_trim_it_does_nothing() -> None:
    h = HeapTrim(0.0, trim=None)
    assert not h.available and not h.tick(0.0) and not h.tick(100.0) and h.trims == 0


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc", reason="glibc only")
def test_glibc_has_it_and_it_runs() -> None:
    assert malloc_trim is not None
    h = HeapTrim(0.0)
    h.tick(0.0)
    assert h.tick(0.0) and h.trims == 1
