"""A plotted series' history: the last ``maxlen`` samples (t, value) in two preallocated rings of doubles.

Contract: ``Series`` is a time-ordered ``Sequence[tuple[float, float]]`` (oldest first; ``len``, indexing with
negative indices, iteration both ways), so a plot reads it as it read the deque it replaces, and ``append((t, v))``
adds a sample, dropping the oldest once ``maxlen`` are kept. Its memory is allocated whole when it is made
(16 bytes a sample: 48 KB for 3,000), never grown: a deque of tuples of floats cost about 110 bytes a sample and
filled as slowly as its slowest packet came, so term's memory grew for 25 minutes of a soak (issue 36).
``nbytes`` is what the rings hold (tests count it on a simulated clock).
"""

from __future__ import annotations

from array import array
from collections.abc import Iterator, Sequence
from typing import overload

__all__ = ["Series"]


class Series(Sequence[tuple[float, float]]):
    """The last ``maxlen`` samples of one series (module docstring)."""

    __slots__ = ("_t", "_v", "_head", "_len", "maxlen")

    def __init__(self, maxlen: int) -> None:
        if maxlen < 1:
            raise ValueError("a series keeps at least one sample")
        self.maxlen = maxlen
        self._t = array("d", bytes(8 * maxlen))  # allocated whole, up front
        self._v = array("d", bytes(8 * maxlen))
        self._head = 0  # where the next sample goes
        self._len = 0

    @property
    def nbytes(self) -> int:
        """Bytes the two rings hold (fixed from the start)."""
        return (len(self._t) + len(self._v)) * self._t.itemsize

    def append(self, sample: tuple[float, float]) -> None:
        """Add (t, value): the newest, replacing the oldest once full (as ``deque(maxlen=...)`` does)."""
        i = self._head
        self._t[i], self._v[i] = sample
        self._head = i + 1 if i + 1 < self.maxlen else 0
        if self._len < self.maxlen:
            self._len += 1

    def clear(self) -> None:
        self._head = self._len = 0

    def __len__(self) -> int:
        return self._len

    def _index(self, i: int) -> int:
        n = self._len
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError("series index out of range")
        return (self._head - n + i) % self.maxlen

    @overload
    def __getitem__(self, i: int) -> tuple[float, float]: ...

    @overload
    def __getitem__(self, i: slice) -> list[tuple[float, float]]: ...

    def __getitem__(self, i: int | slice) -> tuple[float, float] | list[tuple[float, float]]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(self._len))]
        j = self._index(i)
        return self._t[j], self._v[j]

    def __iter__(self) -> Iterator[tuple[float, float]]:
        t, v, m = self._t, self._v, self.maxlen
        start = (self._head - self._len) % m
        for k in range(self._len):
            j = start + k
            if j >= m:
                j -= m
            yield t[j], v[j]

    def __reversed__(self) -> Iterator[tuple[float, float]]:
        t, v, m = self._t, self._v, self.maxlen
        j = self._head
        for _ in range(self._len):
            j = j - 1 if j else m - 1
            yield t[j], v[j]

    def __repr__(self) -> str:
        return f"Series({self._len}/{self.maxlen})"
