"""The board's link timer: how long the PC has been silent, in board time, honest about a starved simulator.

Sans-IO: the board passes its clock in. ``heard(now)`` at every valid frame; ``silent_us(now)`` is board time since
the last one, less the time the board could not listen. ``starved(now, until, slip=...)``: the real-time driver
(fcb_sim/hosts/serve.py) could not run the board from ``now`` to ``until`` (its process got no CPU): the PC's frames of
that time waited in its input, so that time is not the PC's silence. It returns the lag to report (ms, event
SIM_LAG: the largest since the last report, from 100 ms, at most once a second), or None. docs/board.md, "A starved
simulator and the link's time".
"""

from __future__ import annotations

SIM_LAG_REPORT_US = 100_000  # a simulator this far behind real time says so (event SIM_LAG) ...
SIM_LAG_EVERY_US = 1_000_000  # ... at most this often


class LinkTimer:
    """The PC's silence as the board may count it (module docstring)."""

    def __init__(self) -> None:
        self.last_frame_us: int | None = None  # the last valid frame from the PC
        self._deaf: list[tuple[int, int]] = []  # board times the driver could not run: not silence
        self._lag_max = 0  # the largest lag behind real time not yet reported (µs)
        self._report_at = 0

    def heard(self, now: int) -> None:
        self.last_frame_us = now

    def starved(self, now: int, until_us: int, *, slip: bool = False) -> int | None:
        """The board could not run from ``now`` to ``until_us``; ``slip``: its clock will skip that time instead
        of catching up (so there is no board time to leave out). Returns the lag to report (ms), or None."""
        lag = until_us - now
        if lag <= 0:
            return None
        if not slip:
            self._deaf.append((now, until_us))
        self._lag_max = max(self._lag_max, lag)
        if self._lag_max < SIM_LAG_REPORT_US or now < self._report_at:
            return None
        report, self._lag_max, self._report_at = self._lag_max // 1000, 0, now + SIM_LAG_EVERY_US
        return report

    def silent_us(self, now: int) -> int:
        """Board time since the last valid frame, less the time the board could not listen; 0 before the first."""
        last = self.last_frame_us
        if last is None:
            return 0
        self._deaf = [(a, b) for a, b in self._deaf if b > last]
        return now - last - sum(max(0, min(b, now) - max(a, last)) for a, b in self._deaf)
