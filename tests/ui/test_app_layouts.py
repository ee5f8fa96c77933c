"""The flight screen at the terminal sizes pilots use (issue 22): 80x24 (a terminal's default), 100x30, 160x50 and
220x60. At every size, in SAFE and in flight, the mode, height, attitude, battery, link and the last events are on
the screen; the larger sizes use their rows (no block of empty rows, the room view and horizon grow). Snapshots of
each size, fed by the seeded board of tests/ui/test_app_snapshot.py (update deliberately with --snapshot-update)."""

from __future__ import annotations

import pytest
from textual.geometry import Region

from term.core.protocol import Mode
from term.session.model import Model
from tests.support.app_rig import app_for, seeded_flight

SIZES = [(80, 24), (100, 30), (160, 50), (220, 60)]


@pytest.fixture(scope="module")
def flying() -> tuple[Model, float]:
    return seeded_flight()


@pytest.fixture(scope="module")
def safe() -> tuple[Model, float]:
    """The same board 1 s in: SAFE, calibrating (the readiness checks shown)."""
    return seeded_flight(seconds=1.0)


def screen_lines(app) -> list[str]:  # noqa: ANN001
    """The screen's text as the terminal shows it (the compositor's lines)."""
    return ["".join(seg.text for seg in strip) for strip in app.screen._compositor.render_strips()]


async def shown(flight: tuple[Model, float], size: tuple[int, int]) -> tuple[list[str], dict[str, Region]]:
    app = app_for(flight)
    async with app.run_test(size=size) as pilot:
        await pilot.pause()
        app.render_now()
        await pilot.pause()
        screen = app.screen
        regions = {wid: screen.query_one(f"#{wid}").region for wid in
                   ("mode", "attitude", "pressure", "battery", "link", "events")}
        visible = {wid: r for wid, r in regions.items()
                   if screen.query_one(f"#{wid}").display and screen.region.contains_region(r) and r.area}
        return screen_lines(app), visible


@pytest.mark.parametrize("size", SIZES, ids=[f"{w}x{h}" for w, h in SIZES])
@pytest.mark.parametrize("state", ["flying", "safe"])
async def test_every_size_shows_mode_height_attitude_battery_link_events(size, state, request) -> None:  # noqa: ANN001
    flight = request.getfixturevalue(state)
    lines, visible = await shown(flight, size)
    assert set(visible) == {"mode", "attitude", "pressure", "battery", "link", "events"}
    text = "\n".join(lines)
    mode = "F U L L" if flight[0].mode == Mode.FULL else "C A L I B R A T I O N"
    assert mode in text
    for word in ("height", "roll", "pitch", " V", "link OK", "RTT", "lift"):
        assert word in text, word
    last = flight[0].events[-1].text
    assert last[:16] in text  # the newest event (it may wrap in a narrow panel)


@pytest.mark.parametrize("size", [(160, 50), (220, 60)], ids=["160x50", "220x60"])
@pytest.mark.parametrize("state", ["flying", "safe"])
async def test_large_screens_have_no_block_of_empty_rows(size, state, request) -> None:  # noqa: ANN001
    lines, _ = await shown(request.getfixturevalue(state), size)
    blank = [i for i, line in enumerate(lines[:-1]) if not line.strip()]
    assert len(blank) <= 3, blank  # the banner's two blank rows, at most one more


async def test_the_horizon_and_room_grow_at_220x60(flying) -> None:  # noqa: ANN001
    app = app_for(flying)
    async with app.run_test(size=(220, 60)) as pilot:
        await pilot.pause()
        assert app.screen.query_one("#horizon").size.height >= 16
        assert app.screen.query_one("#attitude").size.width >= 60


async def test_resizing_in_flight_keeps_mode_height_battery_link(flying) -> None:  # noqa: ANN001
    app = app_for(flying)
    async with app.run_test(size=(160, 50)) as pilot:
        for size in ((100, 30), (80, 24), (220, 60), (80, 24), (160, 50)):
            await pilot.resize_terminal(*size)
            await pilot.pause()
            app.render_now()
            await pilot.pause()
            text = "\n".join(screen_lines(app))
            for word in ("F U L L", "height", " V", "link OK"):
                assert word in text, (size, word)


@pytest.mark.parametrize("size", SIZES, ids=[f"{w}x{h}" for w, h in SIZES])
def test_snapshot_flying(snap_compare, flying, size) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flying), terminal_size=size)


@pytest.mark.parametrize("size", SIZES, ids=[f"{w}x{h}" for w, h in SIZES])
def test_snapshot_safe(snap_compare, safe, size) -> None:  # noqa: ANN001
    assert snap_compare(app_for(safe), terminal_size=size)


async def test_80x24_keeps_mode_height_battery_link_under_a_lessons_bar_and_a_download_line(flying) -> None:  # noqa: ANN001
    app = app_for(flying)
    async with app.run_test(size=(80, 24)) as pilot:
        app.screen.query_one("#lesson-bar").add_class("running")  # a lesson's two rows
        app.model.download_note = "log saved: flight.csv"  # the download panel's row
        app.model.version += 1
        app.render_now()
        await pilot.pause()
        app.render_now()
        await pilot.pause()
        text = "\n".join(screen_lines(app))
        for word in ("F U L L", "height", " V", "link OK", "roll", "PANIC", "log saved", "param ctrl.p2"):
            assert word in text, word
        events = app.screen.query_one("#events").region
        assert events.bottom <= 23 and events.height >= 3  # whole, above the footer: the screen does not scroll


async def test_the_link_panels_two_links_fit_at_160x50() -> None:
    """Over BLE the link panel gives each link two lines: at 160x50 with the room view (term --sim) they are whole
    (they wrapped into each other)."""
    from term.lessons.room import Room
    from term.ui.app import TermApp
    from tests.support.app_rig import seeded_handover

    app = TermApp(joystick=False, clock=lambda: 3.0)
    app.model = seeded_handover()
    app.lessons.room = Room()  # the room panel as term --sim has it
    async with app.run_test(size=(160, 50)) as pilot:
        await pilot.pause()
        app.render_now()
        await pilot.pause()
        text = "\n".join(screen_lines(app))
        for line in ("heartbeat — (over BLE)", "rx/tx 0/1500", "rx/tx 994/224", "heartbeat 70 ms ago"):
            assert line in text, line
        assert "…" not in "\n".join(line for line in text.splitlines() if "RTT" in line)
