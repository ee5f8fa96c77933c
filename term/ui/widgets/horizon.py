"""The artificial horizon (roll and pitch) with a heading tape, drawn in half-block cells.

Signs (docs/architecture.md): roll positive right side down, pitch positive nose up, yaw positive nose right. As in
an aircraft's attitude indicator the world moves, not the aircraft: banking right tilts the horizon's right end
up; nose up moves the horizon down.
"""

from __future__ import annotations

import math

from rich.console import RenderableType
from rich.text import Text

from term.core.protocol import EventCode
from term.session.model import Model
from term.ui.widgets.base import STALE_STYLE, ModelView, figure

SKY = "rgb(40,110,200)"
GROUND = "rgb(140,90,40)"
PITCH_SPAN = 30.0  # degrees from the centre to the top edge


def horizon_rows(width: int, height: int, roll_deg: float, pitch_deg: float) -> list[Text]:
    """Rows of half-block cells: each cell's top and bottom halves are sky or ground."""
    width, height = max(5, width), max(3, height)
    cx = (width - 1) / 2
    half_rows = height  # vertical resolution in half-cells, counted from the centre: ±height
    t = math.tan(math.radians(max(-89.0, min(89.0, roll_deg))))
    shift = pitch_deg / PITCH_SPAN * half_rows  # in half-cells; positive moves the horizon down
    sky_sky, sky_ground = f"{SKY} on {SKY}", f"{SKY} on {GROUND}"
    ground_sky, ground_ground = f"{GROUND} on {SKY}", f"{GROUND} on {GROUND}"
    lines = [dx * t - shift for dx in (x - cx for x in range(width))]  # horizon height per column, half-cells
    rows = []
    for y in range(height):
        top = (height - 2 * y) - 0.5  # the centre of the cell's top half, in half-cells above the centre
        bottom = top - 1
        text = Text()
        run_style, run = "", 0
        for line in lines:  # consecutive equal cells become one span: a few per row, not one per cell
            if top > line:
                style = sky_sky if bottom > line else sky_ground
            else:
                style = ground_sky if bottom > line else ground_ground
            if style == run_style:
                run += 1
            else:
                if run:
                    text.append("▀" * run, style=run_style)
                run_style, run = style, 1
        text.append("▀" * run, style=run_style)
        rows.append(text)
    # the aircraft symbol, fixed in the centre
    mid = height // 2
    wing = max(1, width // 6)
    start = int(cx) - wing - 1
    symbol = "━" * wing + " ◆ " + "━" * wing
    rows[mid] = rows[mid][:start] + Text(symbol, style="bold yellow") + rows[mid][start + len(symbol):]
    return rows


def heading_tape(width: int, psi_deg: float) -> Text:
    """A compass tape centred on the heading, 3° per column, cardinal letters and labels every 30°."""
    width = max(11, width)
    per_col = 3.0
    cx = width // 2
    cells = [" "] * width
    for col in range(width):
        lo = psi_deg + (col - cx - 0.5) * per_col
        ten = math.ceil(lo / 10) * 10  # the first multiple of 10° in this column's span
        if ten < lo + per_col:
            cells[col] = "┃" if ten % 30 == 0 else "|"
    out = Text("".join(cells), style="dim")
    # labels every 30°
    first = math.floor((psi_deg - cx * per_col) / 30) * 30
    for deg in range(int(first), int(psi_deg + cx * per_col) + 31, 30):
        col = round(cx + (deg - psi_deg) / per_col)
        label = {0: "N", 90: "E", 180: "S", 270: "W"}.get(deg % 360, f"{deg % 360:03d}")
        pos = col - len(label) // 2
        if 0 <= pos and pos + len(label) <= width:
            out = out[:pos] + Text(label, style="bold") + out[pos + len(label):]
    return out


class Horizon(ModelView):
    """The picture only: it redraws only when a half-cell changes, not for every hundredth of a degree."""

    def render_model(self, model: Model, now: float) -> RenderableType:
        w = max(20, self.content_size.width or 36)
        h = max(3, self.content_size.height or 9)
        phi, theta = (self.read(model, n, now, figure=False) for n in ("phi", "theta"))  # a picture: the tape has
        # the numbers
        out = Text()
        rows = horizon_rows(w, h, phi.value if phi.shown and phi.value is not None else 0.0,
                            theta.value if theta.shown and theta.value is not None else 0.0)
        for i, row in enumerate(rows):
            if i:
                out.append("\n")
            out.append_text(row)
        if phi.stale or theta.stale:
            out.stylize(STALE_STYLE)  # an old attitude is not drawn as if it were now
        return out


class HeadingTape(ModelView):
    """The heading tape and the numbers under the horizon."""

    def render_model(self, model: Model, now: float) -> RenderableType:
        w = max(20, self.content_size.width or 36)
        phi, theta, psi = (self.read(model, n, now) for n in ("phi", "theta", "psi"))
        yaw = psi.value if psi.shown and psi.value is not None else 0.0
        out = heading_tape(w, yaw)
        if psi.stale:
            out.stylize(STALE_STYLE)
        out.append("\n")
        hdg = f"{psi.bound}{psi.edge:05.1f}" if psi.bound in (">", "<") else f"{round(yaw, 1) % 360:05.1f}"
        lead = "▲ ".rjust(w // 2 - len(hdg) // 2 + 1)
        out.append(lead, style="bold")
        out.append(f"{hdg}°", style=STALE_STYLE if psi.stale else "bold")
        # no compass: the heading is relative to calibration; the drift the board took out since then
        drift = model.event_args.get(EventCode.HEADING_DRIFT)
        room = w - len(lead) - len(hdg) - 1
        for note in ((f" rel drift {drift / 100:+.1f}°",) if drift is not None else ()) + (" rel",):
            if len(note) <= room:
                out.append(note, style="dim")
                break
        out.append("\n")
        if not phi.known:
            out.append("no attitude yet", style="dim")
        elif phi.stale:  # short figures, to leave room for the age
            out.append_text(figure(phi, "+.0f", "°"))
            out.append(" ")
            out.append_text(figure(theta, "+.0f", "°"))
            out.append(f" {phi.mark}", style="yellow")
        else:
            out.append("roll ")
            out.append_text(figure(phi, "+6.1f", "°"))
            out.append("   pitch ")
            out.append_text(figure(theta, "+6.1f", "°"))
        return out
