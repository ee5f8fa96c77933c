"""Status lines expire (issue 34: a failed log download's line stayed for five minutes; F11's error line outlived
the edit): the download panel's outcome line and the parameter screen's help line go after STATUS_LINE_S, the
events list keeps what they said."""

from __future__ import annotations

import pytest
from textual.widgets import Input

from term.ui.app import TermApp
from term.ui.screens.params import HINT, ParamsScreen
from term.ui.widgets.base import STATUS_LINE_S
from term.ui.widgets.download import DownloadPanel
from tests.support.served_rig import served


async def test_the_download_panels_line_goes_after_its_time() -> None:
    app = TermApp(joystick=False)
    async with app.run_test(size=(120, 44)) as pilot:
        panel = app.screen.query_one(DownloadPanel)
        app.model.download_note = "log download failed: nothing new from the board for 20 s"
        app.model.download_note_at = app.clock()
        app.render_now()
        await pilot.pause(0.05)
        assert panel.display and "failed" in str(panel.render())
        app.model.download_note_at = app.clock() - STATUS_LINE_S - 1
        app.render_now()
        await pilot.pause(0.05)
        assert not panel.display


async def test_the_parameter_screens_error_line_goes_with_its_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("term.ui.screens.params.STATUS_LINE_S", 0.5)
    async with served() as (app, pilot, until):
        await pilot.press("f11")
        await until(lambda: isinstance(app.screen, ParamsScreen))
        await pilot.press("enter")  # the first row, typed (SAFE)
        edit = app.screen.query_one("#param-edit", Input)
        await until(lambda: app.focused is edit)
        edit.value = "nonsense"
        await pilot.press("enter")
        help_line = app.screen.query_one("#param-help")
        await until(lambda: "nonsense" in str(help_line.render()))
        await pilot.press("escape")  # the edit closed: the error goes with it
        await until(lambda: "nonsense" not in str(help_line.render()))
        await until(lambda: str(help_line.render()) == HINT, timeout=5)
