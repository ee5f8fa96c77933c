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


def test_startup_is_frozen_and_thawed_and_collected_in_full_once_a_process() -> None:
    import gc

    from term.core.heap import freeze_startup, thaw

    full: list[int] = []

    def seen(phase: str, info: dict[str, int]) -> None:
        if phase == "start" and info["generation"] == 2:
            full.append(1)

    gc.callbacks.append(seen)
    try:
        freeze_startup()
        assert gc.get_freeze_count() > 0
        thaw()
        assert gc.get_freeze_count() == 0
        first = len(full)
        freeze_startup()  # a second app in this process (a test's): frozen, not walked again
        thaw()
        assert first <= 1 and len(full) == first
    finally:
        gc.callbacks.remove(seen)
        thaw()
