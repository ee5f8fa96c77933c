"""The heading at rest (issue 35.2): neither path has a compass, so a heading is relative to where the craft
pointed at calibration, and it drifts: the DMP's yaw by its own gyro bias (the simulator's 0.02 °/s, 12° in ten
minutes, much of it on the pad), the RAW filter's by whatever gyro bias it has not learnt.

``HeadingHold`` corrects one path's heading (rad) with what a still craft tells:

- while the craft is still (the flight core says so: on its legs, the motors idle, the gyro quiet) the heading
  does not change, so every change of the path's heading is drift: it goes into ``offset`` and the heading shown
  stays where it was;
- over each still stretch the path's heading against time is fitted by least squares (its slope is the drift rate;
  a 0.1° noise per sample gives 0.0002 °/s over 30 s), and from ``RATE_MIN_S`` on that slope is ``rate``;
- in flight the learnt rate is taken out (``offset`` grows by ``rate`` dt).

``update(psi, still, dt)`` returns the corrected heading; ``offset`` (rad) is how far the path has drifted since
``reset`` (the flight core resets at calibration: the screen shows it as the drift since calibration).
"""

from __future__ import annotations

import math

RATE_MIN_S = 5.0  # s of a still stretch before its slope is taken as the drift rate
RATE_WINDOW_S = 60.0  # s: a longer stretch starts a new fit (keeps the sums small for the chip's floats)
TWO_PI = 2.0 * math.pi


def wrap(a: float) -> float:
    """An angle in (-pi, pi]."""
    return a - TWO_PI * math.floor((a + math.pi) / TWO_PI)


class HeadingHold:
    """One path's heading corrected for its drift (module docstring)."""

    def __init__(self) -> None:
        self.rate = 0.0  # rad/s, the drift rate learnt while still
        self.reset()

    def reset(self) -> None:
        """Drift counted from now (calibration); the learnt rate is kept (it is the gyro's, not the flight's)."""
        self.offset = 0.0
        self._prev: float | None = None
        self._still_end()

    def _still_end(self) -> None:
        self._n = 0
        self._t = self._y = 0.0
        self._st = self._sy = self._sty = self._stt = 0.0

    def update(self, psi: float, still: bool, dt: float) -> float:
        """The path's heading now (rad), whether the craft is still, the time since the last call (s)."""
        prev = self._prev
        self._prev = psi
        d = 0.0 if prev is None else wrap(psi - prev)
        if still:
            self.offset += d  # a still craft does not turn: it is all drift
            if self._t >= RATE_WINDOW_S:
                self._still_end()
            self._t += dt
            self._y += d  # the path's own heading, unwrapped, from the stretch's start
            t, y = self._t, self._y
            self._n += 1
            self._st += t
            self._sy += y
            self._sty += t * y
            self._stt += t * t
            n = self._n
            den = n * self._stt - self._st * self._st
            if t >= RATE_MIN_S and den > 0.0:
                self.rate = (n * self._sty - self._st * self._sy) / den
        else:
            if self._n:
                self._still_end()
            self.offset += self.rate * dt
        return wrap(psi - self.offset)
