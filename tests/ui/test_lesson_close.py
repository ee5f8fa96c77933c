"""Closing a lesson's summary in SAFE leaves the board as a new flight wants it, each step said (issue 34: the lift
trim stayed at 1 % and a crash still needed c). The real app with the simulator's instructor."""

from __future__ import annotations

from term.ui.widgets.lesson import SummaryScreen
from tests.support.sim_app_rig import sim_app
from tests.support.waits import until


async def test_closing_the_summary_puts_the_lift_trim_back_to_zero() -> None:
    async with sim_app(seed=4, lesson=1) as (app, pilot, board):
        await until(pilot, lambda: app.lessons.driver.run is not None and app.lessons.driver.run.state == "running")
        await pilot.press("3")
        await until(pilot, lambda: "2/3 Arm in MANUAL" in app.lessons.driver.caption)
        await pilot.press("2")
        await until(pilot, lambda: "3/3 Disarm" in app.lessons.driver.caption)
        await pilot.press("0")
        await until(pilot, lambda: isinstance(app.screen, SummaryScreen))
        await pilot.press("a")  # a lift trim of 1 % in SAFE, the summary up (the pilot's keys work under it)
        await until(pilot, lambda: app.model.status is not None and app.model.status.trim_lift > 0)
        await pilot.press("x")
        await until(pilot, lambda: not isinstance(app.screen, SummaryScreen))
        await until(pilot, lambda: app.model.status.trim_lift == 0 and board.modes.trims.lift == 0)
        assert any("lift trim" in e.text and "back to 0" in e.text for e in app.model.events)
