"""Dialogs (issue 34): in SAFE Esc closes any dialog (it used to send PANIC, harmless there, and leave the dialog
up); a dialog about a mode closes itself, with a line, when the board leaves it (the erase question stayed over the
panels after the board left SAFE, where Esc is PANIC). The real app on the simulated board."""

from __future__ import annotations

from textual.screen import ModalScreen

from term.core.protocol import Mode
from term.ui.screens.confirm import ConfirmScreen
from term.ui.screens.help import HelpScreen
from tests.support.served_rig import fly_out_of_safe, mode_requests, served


def lines(app) -> list[str]:  # noqa: ANN001
    return [e.text for e in app.model.events]


async def test_esc_in_safe_closes_a_dialog_and_sends_nothing() -> None:
    async with served() as (app, pilot, until):
        await pilot.press("f4")  # erase the log: a question
        await until(lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.press("escape")
        await until(lambda: not isinstance(app.screen, ModalScreen))
        await until(lambda: any("log erase cancelled" in t for t in lines(app)))
        await pilot.press("f1")  # the help: the same
        await until(lambda: isinstance(app.screen, HelpScreen))
        await pilot.press("escape")
        await until(lambda: not isinstance(app.screen, ModalScreen))
        assert mode_requests(app) == []  # no PANIC asked


async def test_the_erase_question_closes_itself_when_the_board_leaves_safe() -> None:
    async with served() as (app, pilot, until):
        await pilot.press("f4")
        await until(lambda: isinstance(app.screen, ConfirmScreen))
        await fly_out_of_safe(app, until)
        await until(lambda: not isinstance(app.screen, ModalScreen))
        await until(lambda: any("erase the flash log" in t and "closed" in t and "MANUAL" in t for t in lines(app)))
        # out of SAFE Esc is PANIC again, with no dialog in the way
        await pilot.press("escape")
        await until(lambda: app.model.mode == Mode.PANIC)


async def test_the_erase_question_is_not_asked_out_of_safe() -> None:
    async with served() as (app, pilot, until):
        await fly_out_of_safe(app, until)
        await pilot.press("f4")
        await until(lambda: any("log erase: only in SAFE (the board is in MANUAL)" in t for t in lines(app)))
        assert not isinstance(app.screen, ModalScreen)
