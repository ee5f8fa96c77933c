"""Where the craft is in the room, as the room view draws it: the simulator's truth, a short trail and the lesson's
box, and the geometry that maps metres to the view's braille dots. Sans-IO, no Textual (the widget is
term/ui/widgets/room.py); a real board has no position, so there is no room without ``term --sim``.

The room is the lab the simulator flies in (term.core.protocol's ROOM_HALF_M and ROOM_CEILING_M, the walls and
ceiling fcb_sim's world meets): the pad at its centre, walls ``extent`` m away on every side (3 m: a 6 m room), the
ceiling ``ceiling`` m up. Only a craft beyond them (a simulator without walls) makes it grow (never shrink while the
attempt lasts), so it stays in view. The top view looks down (north up, east right; its dots square), the side
view looks north (east right, the floor at the bottom) with the same metres per dot across, so distances read the
same in both. ``TopView``/``SideView`` give, for a canvas of so many character cells, the cell of a point: the
widget draws with them and the tests check the craft's cell against the simulator's position with them.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from term.core.protocol import ROOM_CEILING_M, ROOM_HALF_M
from term.lessons.instructor import Truth
from term.lessons.observe import Box

EXTENT_M = ROOM_HALF_M  # walls this far from the pad (a 6 m room)
CEILING_M = ROOM_CEILING_M
TRAIL_S = 6.0  # seconds of trail
TRAIL_EVERY_S = 0.1


class Room:
    """The truth as the room view needs it (module docstring)."""

    def __init__(self, extent: float = EXTENT_M) -> None:
        self.truth: Truth | None = None
        self.trail: deque[tuple[float, float, float, float]] = deque()  # (t, n, e, h)
        self.box: Box | None = None
        self.base_extent = extent
        self.extent = extent
        self.version = 0

    def update(self, truth: Truth) -> None:
        self.truth = truth
        far = max(abs(truth.n), abs(truth.e))
        if far > self.extent + 1e-6:  # past the walls: no simulator of ours, but keep it in view
            self.extent = math.ceil(far + 0.5)
        if not self.trail or truth.t - self.trail[-1][0] >= TRAIL_EVERY_S or truth.t < self.trail[-1][0]:
            self.trail.append((truth.t, truth.n, truth.e, truth.h))
            while self.trail and (truth.t - self.trail[0][0] > TRAIL_S or self.trail[0][0] > truth.t):
                self.trail.popleft()
        self.version += 1

    def set_box(self, box: Box | None) -> None:
        """A lesson's box (None: none); the room starts at its own size again."""
        self.box = box
        self.extent = self.base_extent
        self.trail.clear()
        self.version += 1

    @property
    def ceiling(self) -> float:
        high = max(CEILING_M, self.box.high + 0.5 if self.box is not None else 0.0)
        if self.truth is not None and self.truth.h > high + 1e-6:  # above the ceiling: not in our room
            high = math.ceil(self.truth.h + 0.5)
        return high


@dataclass(frozen=True)
class TopView:
    """A top view of ``cols`` x ``rows`` character cells (2 x 4 braille dots each), square dots, the room centred."""

    cols: int
    rows: int
    extent: float

    @property
    def m_per_dot(self) -> float:
        span = 2.0 * self.extent
        return max(span / max(1, 2 * self.cols - 1), span / max(1, 4 * self.rows - 1))

    def dot(self, n: float, e: float) -> tuple[int, int]:
        """(x, y) dot of a point, north up; may fall outside the canvas."""
        k = self.m_per_dot
        x = (2 * self.cols - 1) / 2 + e / k
        y = (4 * self.rows - 1) / 2 - n / k
        return round(x), round(y)

    def cell(self, n: float, e: float) -> tuple[int, int]:
        x, y = self.dot(n, e)
        return x // 2, y // 4


@dataclass(frozen=True)
class SideView:
    """A side view looking north: east across (``m_per_dot`` of the top view, so columns line up), height up from
    the floor at the bottom row to ``ceiling`` at the top."""

    cols: int
    rows: int
    m_per_dot: float
    ceiling: float

    def dot(self, e: float, h: float) -> tuple[int, int]:
        x = (2 * self.cols - 1) / 2 + e / self.m_per_dot
        y = (4 * self.rows - 1) * (1.0 - h / self.ceiling)
        return round(x), round(y)

    def cell(self, e: float, h: float) -> tuple[int, int]:
        x, y = self.dot(e, h)
        return x // 2, y // 4


ARROWS = "↑↗→↘↓↙←↖"  # heading 0 (north) and every 45° clockwise, as the top view draws north up


def arrow(heading_deg: float) -> str:
    return ARROWS[round((heading_deg % 360.0) / 45.0) % 8]
