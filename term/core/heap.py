"""The C heap's free pages given back to the system once a minute (glibc's ``malloc_trim``), from the front end's tick.

Why: in a long flight term's Python objects stay flat (the plots' history is preallocated rings, the events list and
the console are bounded), yet its resident memory kept growing about 0.1 MB a minute for the first half hour of the
soak (issue 36): glibc keeps the blocks Python frees (bytes from the serial port, deque blocks, the live server's
buffers) inside its heaps, and the free space there grew as those blocks fragmented it, while the space in use did
not. glibc returns only a free top of a heap by itself; ``malloc_trim(0)`` gives back every whole free page in all
its heaps (madvise), without moving a live block. It runs in C without the GIL (ctypes releases it), so the link's
thread is not held; on term's heap (a few MB free) it takes a millisecond or two.

Elsewhere (macOS, Windows, musl) there is no ``malloc_trim``: ``HeapTrim`` does nothing there.

And Python's own collector: ``freeze_startup()`` moves what start-up built (widgets, libraries) out of the full
collections' reach (``gc.freeze``), since a full collection walks it all holding the GIL; ``thaw()`` undoes that at
shutdown.
"""

from __future__ import annotations

import ctypes
import gc
from collections.abc import Callable

__all__ = ["PROCESS_HEAP", "TRIM_EVERY_S", "HeapTrim", "freeze_startup", "malloc_trim", "thaw"]

TRIM_EVERY_S = 60.0


def _find() -> Callable[[int], int] | None:
    try:
        fn = ctypes.CDLL(None).malloc_trim  # glibc only
    except (AttributeError, OSError, TypeError):  # (TypeError: Windows has no handle for the program itself)
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn  # type: ignore[no-any-return]


malloc_trim = _find()


class HeapTrim:
    """``tick(now)`` at any rate: ``malloc_trim(0)`` when ``every_s`` has passed since the last one (the first tick
    only starts the count). ``trims`` counts them; ``available`` says whether this C library has it."""

    def __init__(self, every_s: float = TRIM_EVERY_S, trim: Callable[[int], int] | None = malloc_trim) -> None:
        self.every_s = every_s
        self._trim = trim
        self._next: float | None = None
        self.trims = 0

    @property
    def available(self) -> bool:
        return self._trim is not None

    def tick(self, now: float) -> bool:
        """Trim if due; whether it trimmed."""
        if self._trim is None:
            return False
        if self._next is None:
            self._next = now + self.every_s
            return False
        if now < self._next:
            return False
        self._next = now + self.every_s
        self._trim(0)
        self.trims += 1
        return True


PROCESS_HEAP = HeapTrim()  # one heap per process: the app's render tick (and bench/soak.py, in its place) tick this


_collected = [False]  # this process has made its one full collection before a freeze


def freeze_startup() -> None:
    """What start-up built, out of the full collections' reach (module docstring). One full collection first, once
    a process: a later app in it (a test's) would walk the whole test run's heap again (140 ms an app) to keep a
    little garbage out of a freeze that its shutdown undoes."""
    if not _collected[0]:
        gc.collect()
        _collected[0] = True
    gc.freeze()


def thaw() -> None:
    """``freeze_startup`` undone (another app in this process, a test's, starts from a clean slate)."""
    gc.unfreeze()
