"""Layouts that use the space at each size (issue 34): at 80x24 the link panel's lines fit (they were cut at the
edge), at 220x60 the room view gets room to draw (it had 12 columns: "n -0.03 e")."""

from __future__ import annotations

from term.core.link import LinkStats
from term.core.protocol import Mode, WirelessState
from term.ui.app import TermApp
from term.ui.widgets.link import LinkPanel


def stats(rtt: float | None) -> LinkStats:
    return LinkStats(rtt, rtt, rtt, 0.0, 0.0, 2682.0, 945.0, 2373, 0, 0.01, 0.099, 0.4, False, 10_000, 4_000, 12, 0,
                     0, 40, 4)


async def test_the_link_panel_fits_80_columns_with_both_links() -> None:
    app = TermApp(joystick=False)
    async with app.run_test(size=(80, 24)) as pilot:
        m = app.model
        m.link_name, m.radio_name, m.radio_up = "serial /dev/pts/1", "BLE F0:5A:00:00:00:01", True
        m.mode, m.wireless = Mode.FULL, WirelessState.DISCONNECTED
        m.link, m.radio = stats(17.0), stats(None)
        app.render_now()
        await pilot.pause(0.1)
        panel = app.screen.query_one(LinkPanel)
        width = panel.content_size.width
        lines = str(panel.render()).splitlines()
        assert len(lines) <= panel.content_size.height, lines  # every line shows
        assert all(len(line) <= width for line in lines), (width, lines)  # none cut at the edge
        assert any("cable" in line and "17" in line for line in lines), lines


async def test_at_220x60_the_room_view_has_room() -> None:
    from term.ui.widgets.room import RoomView
    from tests.support.sim_app_rig import sim_app
    from tests.support.waits import until

    async with sim_app(seed=3, size=(220, 60)) as (app, pilot, board):
        view = app.screen.query_one(RoomView)
        await until(pilot, lambda: view.room is not None and view.room.truth is not None)
        assert view.content_size.width >= 44, view.region  # at least what it has at 160x50
        app.render_now()
        await pilot.pause(0.1)
        assert "hdg" in str(view.render())  # the figures' line whole: n, e, h and the heading
