"""The key bar at the foot of each screen (term/ui/widgets/keybar.py): the screen's keys in the key map's order,
PANIC first, the palette's key on the right over what does not fit, a screen's own keys before the app's, and a
click on a key presses it."""

from __future__ import annotations

from term.core.protocol import Mode, Op
from term.ui.widgets.keybar import KeyBar
from tests.support.app_rig import flying, sent
from tests.support.waits import until


async def test_the_bar_starts_with_panic_and_the_modes_and_a_click_presses_a_key(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await pilot.pause(0.1)
        bar = app.screen.query_one(KeyBar)
        keys = [c.description for c in bar.shown()[0]]
        assert keys[:8] == ["PANIC", "SAFE", "CALIB", "MANUAL", "YAW", "FULL", "RAW", "HEIGHT"], keys
        drawn = str(bar.render())
        assert drawn.startswith(" 1 ESC PANIC  0 SAFE ") and drawn.rstrip().endswith("▏^p palette"), drawn
        assert len(drawn) == bar.size.width  # what does not fit is under the palette's key, not wrapped
        safe = next(c for c in bar.chips if c.description == "SAFE")
        await pilot.click(KeyBar, offset=(safe.start + 1, 0))
        await until(pilot, lambda: (Op.MODE, Mode.SAFE) in sent(board))


async def test_a_screens_own_keys_come_first_and_follow_the_screen(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, size=(200, 50)) as (app, pilot, board, peer):
        await pilot.press("f8")
        await until(pilot, lambda: type(app.screen).__name__ == "PlotsScreen")
        await until(pilot, lambda: str(app.screen.query_one(KeyBar).render()).startswith(" p pause/live "))
        await pilot.press("f7")
        await until(pilot, lambda: type(app.screen).__name__ == "FlightScreen")
        assert "pause/live" not in str(app.screen.query_one(KeyBar).render())
