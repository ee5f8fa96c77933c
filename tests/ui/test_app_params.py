"""The parameter screen (F11) through Textual's Pilot against the board served by `fcb-sim serve --pty` (the path
of `term --sim`): the board's values listed when it says Hello, search, edit, changed ones marked, a value the
table refuses said at once (nothing sent), the board's own refusal with its reason; the arrows move in the list,
not the pitch trim; a saved set re-applied on connect when the config asks; the report preset's board."""

from __future__ import annotations

from pathlib import Path

from term.core.protocol import PARAMS, Op
from term.session.config import Config
from term.ui.app import TermApp
from term.ui.screens.params import ParamsScreen, ParamTable
from tests.support.app_rig import served, type_into


def cell(app: TermApp, name: str, column: str) -> str:
    return str(app.screen.query_one(ParamTable).get_cell(name, column))


async def test_the_parameter_screen_searches_edits_and_shows_refusals() -> None:
    async with served() as (app, pilot, until):
        app.simulate_key("f11")
        await until(lambda: isinstance(app.screen, ParamsScreen))
        table = app.screen.query_one(ParamTable)
        assert table.row_count == len(PARAMS) and cell(app, "ctrl.p1", "value") == "0.4"
        assert cell(app, "ctrl.p1", "parameter") == "  ctrl.p1"  # not changed: no mark
        # the arrows move in the list (they trim pitch elsewhere)
        before = table.cursor_row
        app.simulate_key("down")
        await until(lambda: table.cursor_row == before + 1)
        # search: every word in the name or the meaning
        app.simulate_key("slash")
        await until(lambda: app.focused is app.screen.query_one("#param-search"))
        for ch in "gyro flown":  # (est.attitude's meaning names est.k_gyro too: a second word picks one)
            if ch == " ":
                await pilot.press("space")
            else:
                app.simulate_key(ch)
        await until(lambda: table.row_count == 1)
        app.simulate_key("enter")  # back to the list
        await until(lambda: app.focused is table)
        app.simulate_key("enter")  # edit the row
        await until(lambda: app.screen.query_one("#param-edit").has_class("editing"))
        assert app.screen.query_one("#param-edit").value == "0.999"  # type: ignore[attr-defined]
        await type_into(app, "0.99")
        app.simulate_key("enter")
        await until(lambda: app.model.params["est.k_gyro"] == 0.99)
        await until(lambda: cell(app, "est.k_gyro", "parameter") == "* est.k_gyro")
        # a value the table refuses: said at once, nothing sent
        search = app.screen.query_one("#param-search")
        search.value = ""  # type: ignore[attr-defined]
        await until(lambda: table.row_count == len(PARAMS))
        table.focus()
        table.move_cursor(row=table.get_row_index("ctrl.p1"))
        app.simulate_key("enter")
        await until(lambda: app.screen.query_one("#param-edit").has_class("editing"))
        await type_into(app, "99")
        app.simulate_key("enter")
        help_line = app.screen.query_one("#param-help")
        await until(lambda: "ctrl.p1 must be a number from 0 to 10" in str(help_line.render()))
        assert app.model.params["ctrl.p1"] == 0.4
        app.simulate_key("escape")  # closes the edit line (typing: the pilot's keys rest)
        await until(lambda: not app.screen.query_one("#param-edit").has_class("editing"))
        # the board's own refusal: the log scheme with a log in the flash
        app.send(Op.LOG_START)
        await pilot.pause(0.3)
        app.send(Op.LOG_STOP)
        await pilot.pause(0.2)
        table.move_cursor(row=table.get_row_index("log.scheme"))
        app.simulate_key("enter")
        await until(lambda: app.screen.query_one("#param-edit").has_class("editing"))
        await type_into(app, "delta8")
        app.simulate_key("enter")
        await until(lambda: app.model.param_refused.get("log.scheme") == "log is busy")
        await until(lambda: cell(app, "log.scheme", "board says") == "log is busy")
        assert app.model.params["log.scheme"] == "rice"


async def test_a_saved_set_is_applied_on_connect(tmp_path: Path) -> None:
    saved = tmp_path / "mine.toml"
    saved.write_text("[ctrl]\np1 = 0.45\n[trim]\nlift_step = 164\n", encoding="utf-8")
    async with served(Config(params_file=saved, params_apply=True)) as (app, pilot, until):
        await until(lambda: app.model.params["ctrl.p1"] == 0.45 and app.model.params["trim.lift_step"] == 164)
        assert any("2 parameters from" in e.text for e in app.model.events)
        assert app.model.trim_steps() == (164, 256)  # the readiness panel counts presses in the board's steps


async def test_term_sim_preset_report_flies_the_reports_board() -> None:
    async with served(preset="report") as (app, pilot, until):
        p = app.model.params
        assert (p["est.attitude"], p["est.k_gyro"], p["est.height"]) == ("complementary", 0.999, "complementary")
        assert (p["ctrl.p1"], p["ctrl.p2"], p["ctrl.yaw_p"]) == (0.4, 111.0, 800.0)
        assert p["sched.scheduler"] == "round-robin" and p["sched.stick_reaction"] is False


async def test_the_table_is_redrawn_only_where_a_value_changed() -> None:
    """Each cell put in the table redraws all of it (about 90 ms): telemetry moves the model many times a second, and
    the screen used to put every cell back each quarter second, a third of a core on F11 in flight."""
    from term.core.protocol import Attitude, Param, ParamValue
    from tests.support.waits import until

    app = TermApp(joystick=False)
    async with app.run_test(size=(160, 50)) as pilot:
        p1 = PARAMS[Param.P1]
        app.model.apply_packet(ParamValue(int(Param.P1), p1.to_raw(p1.default), 0, 1), app.clock())
        app.simulate_key("f11")
        await until(pilot, lambda: isinstance(app.screen, ParamsScreen))
        screen = app.screen
        table = screen.query_one(ParamTable)
        put: list[tuple[object, object]] = []
        update_cell = table.update_cell

        def counted(row: object, col: object, value: object, **kw: object) -> None:
            put.append((row, col))
            update_cell(row, col, value, **kw)  # type: ignore[arg-type]

        table.update_cell = counted  # type: ignore[method-assign]
        for i in range(5):  # telemetry: the model moves, no parameter does
            app.model.apply_packet(Attitude(0, i, 0, 0, 0, 0, 0), app.clock())
            screen.refresh_values()
        assert put == []
        app.model.apply_packet(ParamValue(int(Param.P1), p1.to_raw(0.5), 0, 1), app.clock())
        screen.refresh_values()
        assert {row for row, _ in put} == {p1.name} and ("ctrl.p1", "value") in put
        assert cell(app, p1.name, "value") == "0.5" and cell(app, p1.name, "parameter") == "* ctrl.p1"
