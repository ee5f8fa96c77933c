"""The room view: where the craft really is, from above and from the side, with the lesson's box (term --sim).

Drawn from ``term.lessons.room.Room`` (the simulator's truth; set by the app: attributes down) at the app's render rate,
in braille dots: the walls dim, the pad a cross, the box green while the craft is inside it and yellow while it
is not, the last seconds of its path as a dotted trail, and the craft as an arrow pointing where its nose points
(top view) and a diamond (side view). The last line gives the figures (position from the pad, height, heading,
in the box or not); the bottom border the room's size and the wind. Without the simulator (a real board has no
position) the panel says so.
"""

from __future__ import annotations

import math

from rich.text import Text

from term.lessons.room import Room, SideView, TopView, arrow
from term.session.model import Model
from term.ui.widgets.base import ModelView

NO_ROOM = "No room view: a real board has no position. term --sim has one."
WALL, PAD, TRAIL, BOX_IN, BOX_OUT, CRAFT, FLOOR = ("grey35", "grey50", "cyan", "green", "yellow", "bold white",
                                                    "grey50")
_PRIORITY = {WALL: 0, FLOOR: 0, PAD: 1, TRAIL: 2, BOX_OUT: 3, BOX_IN: 3}
_BITS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))  # [y % 4][x % 2]


class Canvas:
    """Braille dots on ``cols`` x ``rows`` cells; each cell keeps the style of its most important dot; a glyph
    (the craft) replaces a cell."""

    def __init__(self, cols: int, rows: int) -> None:
        self.cols, self.rows = cols, rows
        self.bits = [[0] * cols for _ in range(rows)]
        self.style: list[list[str | None]] = [[None] * cols for _ in range(rows)]
        self.glyph: dict[tuple[int, int], tuple[str, str]] = {}

    def set(self, x: int, y: int, style: str) -> None:
        cx, cy = x // 2, y // 4
        if 0 <= cx < self.cols and 0 <= cy < self.rows and x >= 0 and y >= 0:
            self.bits[cy][cx] |= _BITS[y % 4][x % 2]
            old = self.style[cy][cx]
            if old is None or _PRIORITY.get(style, 9) >= _PRIORITY.get(old, 9):
                self.style[cy][cx] = style

    def line(self, x0: int, y0: int, x1: int, y1: int, style: str, dash: int = 0) -> None:
        n = max(abs(x1 - x0), abs(y1 - y0), 1)
        for i in range(n + 1):
            if dash and (i // dash) % 2:
                continue
            self.set(round(x0 + (x1 - x0) * i / n), round(y0 + (y1 - y0) * i / n), style)

    def rect(self, x0: int, y0: int, x1: int, y1: int, style: str, dash: int = 0) -> None:
        self.line(x0, y0, x1, y0, style, dash)
        self.line(x1, y0, x1, y1, style, dash)
        self.line(x1, y1, x0, y1, style, dash)
        self.line(x0, y1, x0, y0, style, dash)

    def put(self, cx: int, cy: int, glyph: str, style: str) -> None:
        self.glyph[(min(max(cx, 0), self.cols - 1), min(max(cy, 0), self.rows - 1))] = (glyph, style)

    def row(self, cy: int) -> Text:
        """One row of cells, one span per run of a style (Textual's cost of drawing a line grows with its spans)."""
        t = Text()
        bits, styles = self.bits[cy], self.style[cy]
        run: list[str] = []
        run_style = ""
        for cx in range(self.cols):
            g = self.glyph.get((cx, cy))
            if g is not None:
                char, style = g
            elif bits[cx]:
                char, style = chr(0x2800 + bits[cx]), styles[cx] or ""
            else:
                char, style = " ", ""
            if style != run_style and run:
                t.append("".join(run), style=run_style)
                run = []
            run.append(char)
            run_style = style
        if run:
            t.append("".join(run), style=run_style)
        return t


def draw(room: Room, width: int, height: int) -> tuple[Text, TopView, SideView]:
    """The room in ``width`` x ``height`` cells: the two views over the figures line. Also returns the views'
    geometry (where each point is drawn)."""
    rows = max(1, height - 1)
    top_cols = max(4, (width - 1) // 2)
    side_cols = max(4, width - 1 - top_cols)
    top = TopView(top_cols, rows, room.extent)
    side = SideView(side_cols, rows, top.m_per_dot, room.ceiling)
    tc, sc = Canvas(top_cols, rows), Canvas(side_cols, rows)
    t = room.truth
    # walls, pad and floor
    x0, y0 = top.dot(room.extent, -room.extent)
    x1, y1 = top.dot(-room.extent, room.extent)
    tc.rect(x0, y0, x1, y1, WALL, dash=1)
    px, py = top.dot(0.0, 0.0)
    for dx, dy in ((-1, 0), (1, 0), (0, -1), (0, 1), (0, 0)):
        tc.set(px + dx, py + dy, PAD)
    fx0, fy = side.dot(-room.extent, 0.0)
    fx1, _ = side.dot(room.extent, 0.0)
    sc.line(fx0, fy, fx1, fy, FLOOR)
    for wall in (-room.extent, room.extent):
        wx, _ = side.dot(wall, 0.0)
        _, wy = side.dot(wall, room.ceiling)
        sc.line(wx, fy, wx, wy, WALL, dash=1)
    cx0, cy = side.dot(-room.extent, room.ceiling)
    cx1, _ = side.dot(room.extent, room.ceiling)
    sc.line(cx0, cy, cx1, cy, WALL, dash=1)  # the ceiling the simulator's craft meets
    # the lesson's box
    b = room.box
    inside = t is not None and b is not None and b.distance(t.n, t.e, t.h) == 0.0
    if b is not None:
        style = BOX_IN if inside else BOX_OUT
        bx0, by0 = top.dot(b.north + b.size / 2, b.east - b.size / 2)
        bx1, by1 = top.dot(b.north - b.size / 2, b.east + b.size / 2)
        tc.rect(bx0, by0, bx1, by1, style)
        sx0, sy0 = side.dot(b.east - b.size / 2, b.high)
        sx1, sy1 = side.dot(b.east + b.size / 2, b.low)
        sc.rect(sx0, sy0, sx1, sy1, style)
    # the trail and the craft
    for _, n, e, h in list(room.trail)[:-1]:
        tc.set(*top.dot(n, e), TRAIL)
        sc.set(*side.dot(e, h), TRAIL)
    if t is not None:
        cx, cy = top.cell(t.n, t.e)
        tc.put(cx, cy, arrow(t.heading_deg), CRAFT)
        sx, sy = side.cell(t.e, max(0.0, t.h))
        sc.put(sx, sy, "◆", CRAFT)
    out = Text()
    for r in range(rows):
        out.append_text(tc.row(r))
        out.append(" ")
        out.append_text(sc.row(r))
        out.append("\n")
    out.append_text(figures(room, inside))
    return out, top, side


def figures(room: Room, inside: bool) -> Text:
    """Position from the pad, height, heading, and whether in the lesson's box: one short line."""
    t = room.truth
    if t is None:
        return Text("waiting for the simulator's truth…", style="dim")
    n, e, h = (round(x, 2) + 0.0 for x in (t.n, t.e, t.h))  # + 0.0: a craft on the pad reads 0.00, never -0.00
    text = Text(f"n {n:+.2f} e {e:+.2f} h {h:.2f} m hdg {round(t.heading_deg) % 360:03d}°")
    if t.contact in ("ceiling", "wall"):  # the simulator says it: the craft is pressed on a surface
        text.append(f"  at the {t.contact}", style="bold yellow")
    if room.box is not None:
        text.append("  in box" if inside else "  outside", style=BOX_IN if inside else BOX_OUT)
    return text


def room_name(room: Room) -> str:
    """The room by its size: "6 × 6 × 3 m room" (across, across, high)."""
    side = f"{2 * room.extent:.0f}"
    return f"{side} × {side} × {room.ceiling:.0f} m room"


_COMPASS = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


def wind_text(room: Room) -> str:
    """The wind as a pilot says it: its speed, where it blows from, its gusts."""
    t = room.truth
    if t is None or not (t.wind_n or t.wind_e or t.gust):
        return ""
    speed = math.hypot(t.wind_n, t.wind_e)
    origin = _COMPASS[round(math.degrees(math.atan2(-t.wind_e, -t.wind_n)) % 360 / 45) % 8]
    gusts = f" ±{t.gust:.1f}" if t.gust else ""
    return f"wind {speed:.1f} m/s" + (f" from {origin}" if speed >= 0.05 else "") + gusts


class RoomView(ModelView):
    """The room view (module docstring). ``room`` is the app's (None: a real board: the panel says why)."""

    TIME_DEPENDENT = True
    MAX_HZ = 15.0

    def __init__(self, room: Room | None = None, *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id, classes="absent" if room is None else None)
        self.room = room
        self.top: TopView | None = None
        self.side: SideView | None = None
        self._drawn = -1

    def render_model(self, model: Model, now: float) -> Text:
        room = self.room
        if room is None:
            self.subtitle("")
            return Text(NO_ROOM, style="dim")
        w, h = self.content_size.width, self.content_size.height
        if w < 8 or h < 2:
            return Text("")
        text, self.top, self.side = draw(room, w, h)
        self._drawn = room.version
        wind = wind_text(room)
        self.subtitle(f"top · side (looking N) · {room_name(room)}" + (f" · {wind}" if wind else ""))
        return text
