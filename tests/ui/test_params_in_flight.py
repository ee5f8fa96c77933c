"""F11 in flight (issue 34): out of SAFE a value is stepped with the arrows (the table's step, x10 with PageUp and
PageDown) and Enter sends it; nothing is typed, so a digit or Esc never lands in a box; in SAFE the value is typed
and Esc cancels the edit. The focus never stays in a box once the screen is closed. The real app on the simulated
board (tests/support/app_rig.py)."""

from __future__ import annotations

from textual.widgets import Input

from term.core.protocol import Mode
from term.ui.screens.params import ParamsScreen, ParamTable
from tests.support.served_rig import fly_out_of_safe, mode_requests, served


def help_line(app) -> str:  # noqa: ANN001
    return str(app.screen.query_one("#param-help").render())


async def open_row(app, pilot, until, name: str) -> None:  # noqa: ANN001
    await pilot.press("f11")
    await until(lambda: isinstance(app.screen, ParamsScreen))
    table = app.screen.query_one(ParamTable)
    await until(lambda: app.focused is table)
    table.move_cursor(row=table.get_row_index(name))
    await pilot.press("enter")


async def test_in_flight_the_arrows_step_a_value_and_enter_sends_it() -> None:
    async with served() as (app, pilot, until):
        await fly_out_of_safe(app, until)
        asked = len(mode_requests(app))
        await open_row(app, pilot, until, "ctrl.p1")
        await until(lambda: app.screen.query_one("#param-step").has_class("editing"))
        assert not isinstance(app.focused, Input)  # no box to type into in flight
        said = help_line(app)
        assert "↑" in said and "PgUp" in said and "Enter sends" in said, said
        await pilot.press("up")  # the table's step: 0.05
        await pilot.press("pageup")  # x10: 0.5
        await pilot.press("down")
        assert "0.9" in str(app.screen.query_one("#param-step").render())
        assert app.model.params["ctrl.p1"] == 0.4  # nothing sent before Enter
        await pilot.press("enter")
        await until(lambda: app.model.params["ctrl.p1"] == 0.9)
        assert app.model.mode == Mode.MANUAL and len(mode_requests(app)) == asked  # no key flew the craft
        assert not app.screen.query_one("#param-step").has_class("editing")
        # a SAFE-only parameter says so and opens nothing
        table = app.screen.query_one(ParamTable)
        table.move_cursor(row=table.get_row_index("link.heartbeat_ms"))
        await pilot.press("enter")
        await until(lambda: "only in SAFE" in help_line(app))
        assert not app.screen.query_one("#param-step").has_class("editing")


async def test_in_safe_a_value_is_typed_and_esc_cancels_the_edit_without_panic() -> None:
    async with served() as (app, pilot, until):
        await open_row(app, pilot, until, "ctrl.p1")
        edit = app.screen.query_one("#param-edit", Input)
        await until(lambda: app.focused is edit)
        assert "Esc" in help_line(app)
        await pilot.press("escape")
        await until(lambda: app.focused is app.screen.query_one(ParamTable))
        assert not edit.has_class("editing") and mode_requests(app) == []  # no PANIC asked


async def test_leaving_safe_while_typing_closes_the_box_with_a_line() -> None:
    async with served() as (app, pilot, until):
        await open_row(app, pilot, until, "ctrl.p1")
        edit = app.screen.query_one("#param-edit", Input)
        await until(lambda: app.focused is edit)
        await fly_out_of_safe(app, until)
        await until(lambda: not edit.has_class("editing"))
        assert not isinstance(app.focused, Input)
        assert "left SAFE" in help_line(app)


async def test_the_focus_never_stays_in_a_box_after_the_screen_closes() -> None:
    async with served() as (app, pilot, until):
        await open_row(app, pilot, until, "ctrl.p1")
        params = app.screen
        await until(lambda: app.focused is params.query_one("#param-edit"))
        await pilot.press("f7")  # the flight screen
        await until(lambda: not isinstance(app.screen, ParamsScreen))
        assert not isinstance(app.focused, Input)
        assert not params.query_one("#param-edit").has_class("editing")
        await pilot.press("f11")  # back: the list has the focus, not a box
        await until(lambda: isinstance(app.screen, ParamsScreen))
        await until(lambda: app.focused is params.query_one(ParamTable))
        # the search box too
        await pilot.press("slash")
        await until(lambda: app.focused is params.query_one("#param-search"))
        await pilot.press("f7")
        await until(lambda: not isinstance(app.screen, ParamsScreen))
        await pilot.press("f11")
        await until(lambda: isinstance(app.screen, ParamsScreen))
        await until(lambda: app.focused is params.query_one(ParamTable))


async def test_a_value_that_breaks_a_rule_is_said_before_it_is_sent() -> None:
    async with served() as (app, pilot, until):
        await open_row(app, pilot, until, "link.timeout_ms")
        edit = app.screen.query_one("#param-edit", Input)
        await until(lambda: app.focused is edit)
        edit.value = "50"
        await pilot.press("enter")
        await until(lambda: "link.timeout_ms ≥ 2 × link.heartbeat_ms" in help_line(app))
        assert app.screen.pending == {} and app.model.params["link.timeout_ms"] == 500  # nothing sent
