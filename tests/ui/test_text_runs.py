"""The panels' text pictures (bars, the room view) draw each run of one style as one span: Textual's cost of drawing a
line grows with its spans, and a bar drawn a span per cell cost the controls panel 5.8 ms a frame (3.2 ms in runs)."""

from __future__ import annotations

import pytest
from rich.text import Text

from term.lessons.instructor import Truth
from term.lessons.room import Box, Room
from term.ui.widgets.bars import cbar
from term.ui.widgets.room import draw


def styles_by_cell(text: Text) -> list[str]:
    out = [""] * len(text.plain)
    for span in text.spans:
        for i in range(span.start, span.end):
            out[i] = str(span.style)
    return out


def adjacent_twins(text: Text) -> list[tuple[int, int]]:
    """Spans that touch the one before them and have its style: one run cut in two."""
    spans = sorted(text.spans, key=lambda s: s.start)
    return [(a.start, b.end) for a, b in zip(spans, spans[1:], strict=False) if a.end == b.start and a.style == b.style]


@pytest.mark.parametrize("value", [0.0, 1.0, 50.0, -50.0, 199.0, 200.0, 300.0, -300.0, 1e308, -1e308])
def test_a_centred_bar_is_its_cells_in_runs(value: float) -> None:
    bar = cbar(value, 200.0, 21)
    cells = bar.plain
    assert len(cells) == 21 and cells[10] in "│█"
    # every cell keeps its style: the bar's style where it is filled or clipped, dim elsewhere
    assert styles_by_cell(bar) == ["cyan" if c in "█▶◀" else "dim" for c in cells]
    assert not adjacent_twins(bar)
    assert len(bar.spans) <= 3


def test_the_room_view_is_drawn_in_runs() -> None:
    room = Room()
    room.set_box(Box(1.0, 0.5, 1.0, 1.0))
    for k in range(40):  # a trail, and the craft in the box at the end
        room.update(Truth(t=k * 0.1, n=0.2 + k * 0.02, e=0.5, h=1.0, vn=0.0, ve=0.0, vd=0.0, phi=0.0, theta=0.0,
                          psi=0.3, p=0.0, q=0.0, r=0.0, on_ground=False, volts=12.0, soc=0.9, landings=0,
                          touchdown=0.0, crashes=0, cable=True))
    text, _, _ = draw(room, 60, 16)
    assert not adjacent_twins(text)
    styled = {str(s.style) for s in text.spans}
    assert {"grey35", "cyan", "green", "bold white"} <= styled  # walls, trail, the box with the craft in it, the craft
