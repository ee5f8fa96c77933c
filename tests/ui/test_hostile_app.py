"""Hostile values where a pilot meets them in flight (issue 23): the parameter screen (F11) with 1e308 ended the
whole terminal with a traceback, and a saved set with ``p1 = 1e308`` applied on connect broke the cable link at
Hello. Both are one line now, and the link stays up (Textual's Pilot against `fcb-sim serve --pty`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from term.session.config import Config
from term.ui.screens.params import ParamsScreen, ParamTable
from tests.support.app_rig import served, type_into


async def test_f11_refuses_hostile_values_in_one_line_and_the_terminal_flies_on() -> None:
    async with served() as (app, pilot, until):
        app.simulate_key("f11")
        await until(lambda: isinstance(app.screen, ParamsScreen))
        table = app.screen.query_one(ParamTable)
        for text in ("1e308", "-1e308", "1e-30", "１", "1_0", "9" * 400, "0.12345"):
            table.focus()
            table.move_cursor(row=table.get_row_index("ctrl.p1"))
            app.simulate_key("enter")
            await until(lambda: app.screen.query_one("#param-edit").has_class("editing"))
            await type_into(app, text)
            app.simulate_key("enter")
            await until(lambda: "ctrl.p1" in str(app.screen.query_one("#param-help").render()))
            said = str(app.screen.query_one("#param-help").render())
            assert "ctrl.p1" in said and "\n" not in said.strip(), (text, said)
            assert app.model.params["ctrl.p1"] == 0.4 and app.is_running
            app.simulate_key("escape")
            await until(lambda: not app.screen.query_one("#param-edit").has_class("editing"))
        await pilot.pause(0.3)
        assert app.is_running and not app.model.link_lost


@pytest.mark.parametrize("value", ["1e308", "-" + "9" * 400, "1e-30"])
async def test_a_hostile_set_applied_on_connect_is_one_line_and_the_link_stays(tmp_path: Path, value: str) -> None:
    saved = tmp_path / "set.toml"
    saved.write_text(f"[ctrl]\np1 = {value}\np2 = 120\n")
    async with served(Config(params_file=saved, params_apply=True)) as (app, pilot, until):
        await until(lambda: any("not applied" in e.text for e in app.model.events))
        said = next(e.text for e in app.model.events if "not applied" in e.text)
        assert "ctrl.p1" in said and "\n" not in said
        await pilot.pause(0.3)
        assert app.is_running and not app.model.link_lost and app.model.params["ctrl.p1"] == 0.4
