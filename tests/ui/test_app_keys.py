"""Issue 22: priority keys mean priority everywhere (Textual's Pilot drives the real app over the real link, a
loopback transport, with the scripted board of conftest.py at the other end).

Out of SAFE, PANIC (1, Esc) and SAFE (0) act from every screen, dialog and focused widget, text boxes included. In
SAFE a text box takes the digits and Esc leaves it. Letters typed into a focused box never reach the flight keys,
however fast they come (a burst posted at once, as a terminal delivers a fast typist's keys)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from textual import events
from textual.command import CommandPalette
from textual.screen import ModalScreen
from textual.widget import Widget
from textual.widgets import Input

from term.core.protocol import Mode, Op
from term.ui.app import TermApp
from term.ui.screens.dirprompt import DirectoryPrompt
from term.ui.screens.flight import FlightScreen
from term.ui.screens.params import ParamsScreen, ParamTable
from tests.support.app_rig import attitude, flying, sent, sent_before_marker
from tests.support.waits import until

GAIN_OPS = {Op.GAIN_P1, Op.GAIN_P2, Op.GAIN_YAW_P, Op.GAIN_HEIGHT_P, Op.GAIN_HEIGHT_D}


def burst(app: TermApp, keys: str) -> None:
    """Keys posted at once, before the app handled the first (a fast typist, or a busy machine)."""
    for ch in keys:
        app.post_message(events.Key("slash" if ch == "/" else ch, ch))


async def in_mode(app: TermApp, pilot, peer, mode: Mode) -> None:  # noqa: ANN001
    await peer.send(attitude(mode))
    await until(pilot, lambda: app.model.mode == mode)


async def test_fast_typing_after_slash_goes_into_the_search_box_not_to_the_gains(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, size=(160, 50)) as (app, pilot, board, peer):
        await in_mode(app, pilot, peer, Mode.SAFE)
        await pilot.press("f11")
        await until(pilot, lambda: isinstance(app.screen, ParamsScreen))
        burst(app, "/timeout")
        search = app.screen.query_one("#param-search", Input)
        await until(pilot, lambda: search.value == "timeout")
        before = await sent_before_marker(pilot, app, board)
        assert not [op for op, _ in before if op in GAIN_OPS | {Op.TRIM_YAW, Op.TRIM_LIFT}], before


async def test_fast_typing_after_enter_goes_into_the_edit_line(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, size=(160, 50)) as (app, pilot, board, peer):
        await in_mode(app, pilot, peer, Mode.SAFE)
        await pilot.press("f11")
        await until(pilot, lambda: isinstance(app.focused, ParamTable))
        board.executed.clear()
        app.post_message(events.Key("enter", "\r"))
        burst(app, "rice")
        edit = app.screen.query_one("#param-edit", Input)
        await until(pilot, lambda: edit.value.endswith("rice"))
        before = await sent_before_marker(pilot, app, board)
        assert not before, before


async def test_in_flight_the_search_box_gives_way_to_panic_safe_and_the_screen_keys(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, size=(160, 50)) as (app, pilot, board, peer):
        await in_mode(app, pilot, peer, Mode.FULL)
        await pilot.press("f11", "slash")
        search = app.screen.query_one("#param-search", Input)
        await until(pilot, lambda: app.focused is search)
        await pilot.press("s", "c", "h", "e", "d", "1")
        await until(pilot, lambda: (Op.MODE, Mode.PANIC) in sent(board))
        assert search.value == "sched"  # the letters are text, the 1 is PANIC
        board.executed.clear()
        await pilot.press("escape")
        await until(pilot, lambda: (Op.MODE, Mode.PANIC) in sent(board))
        await pilot.press("0")
        await until(pilot, lambda: (Op.MODE, Mode.SAFE) in sent(board))
        app.screen.query_one("#param-search", Input).focus()
        await until(pilot, lambda: app.focused is search)
        await pilot.press("f7")
        await until(pilot, lambda: isinstance(app.screen, FlightScreen))


async def test_in_safe_the_search_box_takes_digits_and_escape_leaves_it(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, size=(160, 50)) as (app, pilot, board, peer):
        await in_mode(app, pilot, peer, Mode.SAFE)
        await pilot.press("f11", "slash")
        search = app.screen.query_one("#param-search", Input)
        await until(pilot, lambda: app.focused is search)
        board.executed.clear()
        await pilot.press("y", "a", "w", "1", "0")
        assert search.value == "yaw10"
        await pilot.press("escape")
        await until(pilot, lambda: app.focused is not search)
        before = await sent_before_marker(pilot, app, board)
        assert not before, before
        assert isinstance(app.screen, ParamsScreen)


# --- the walk: every screen, every focusable widget, SAFE and flight ---------------------------------------------

SCREENS: dict[str, Callable[[TermApp], object]] = {
    "flight": lambda app: app.show_screen("flight"),
    "help": lambda app: (app.show_screen("flight"), app.toggle_help()),
    "plots": lambda app: app.show_screen("plots"),
    "plots+chooser": lambda app: (app.show_screen("plots"), app.call_after_refresh(app.screen.action_choose)),
    "profile": lambda app: app.show_screen("profile"),
    "wireless": lambda app: app.show_screen("wireless"),
    "params": lambda app: app.show_screen("params"),
    "joystick": lambda app: app.show_screen("joystick"),
    "erase log?": lambda app: (app.show_screen("flight"), app.ask_log_erase()),
    "palette": lambda app: (app.show_screen("flight"), app.action_command_palette()),
    "directory": lambda app: (app.show_screen("flight"), app.push_screen(DirectoryPrompt(Path("/tmp")))),
}


def focusables(app: TermApp) -> list[Widget | None]:
    """Each widget that can take the focus (none: the screen itself)."""
    return list(app.screen.focus_chain) or [None]


def kinds(widgets: list[Widget | None]) -> list[int]:
    """The index of the first widget of each kind (the keys' routing depends on the kind alone: keygate.py)."""
    first: dict[type, int] = {}
    for i, w in enumerate(widgets):
        first.setdefault(type(w), i)
    return sorted(first.values())


def is_text(w: Widget | None) -> bool:
    return isinstance(w, Input)


async def open_screen(app: TermApp, pilot, name: str) -> None:  # noqa: ANN001
    while len(app.screen_stack) > 1:
        app.close_top_screen()  # (the palette stops its search first, as an F-key's screen change does)
        await pilot.pause()
    SCREENS[name](app)
    await pilot.pause()  # (the queues drained: the screen is up; tests/support/textual_drain.py)
    if name in ("palette", "directory"):  # a text screen: its box takes the focus when it is up
        await settle(pilot, lambda: isinstance(app.focused, Input))


async def settle(pilot, cond: Callable[[], bool], timeout: float = 5.0) -> bool:  # noqa: ANN001
    try:
        await until(pilot, cond, timeout)
    except TimeoutError:
        return False
    return True


async def check_key(app: TermApp, pilot, board, w: Widget | None, key: str, want: Mode, where: str) -> str | None:  # noqa: ANN001
    """Press ``key`` with ``w`` focused: what went wrong, or None."""
    board.executed.clear()
    if is_text(w):
        w.value = ""  # type: ignore[union-attr]
    dialog = app.screen if isinstance(app.screen, ModalScreen) and not isinstance(app.screen, CommandPalette) else None
    await pilot.press(key)
    modes = lambda: [c for c in sent(board) if c[0] == Op.MODE]  # noqa: E731
    if dialog is not None and key == "escape" and app.model.mode == Mode.SAFE:  # issue 34: Esc closes it in SAFE
        closed = await settle(pilot, lambda: app.screen is not dialog)
        return None if closed and not modes() else f"{where}: Esc in SAFE sent {modes()}, dialog closed: {closed}"
    if app.model.mode != Mode.SAFE or not is_text(w):
        if not await settle(pilot, lambda: bool(modes())) or modes() != [(Op.MODE, want)]:
            return f"{where}: sent {modes()}, wanted {want.name} ({app.model.events[-1].text})"
        return None
    typed = [c for c in await sent_before_marker(pilot, app, board) if c[0] == Op.MODE]  # (the key went first)
    if typed:
        return f"{where}: a text box in SAFE sent {typed}"
    if key == "escape":
        return f"{where}: Esc did not leave the box" if app.focused is w and w.is_attached else None  # type: ignore[union-attr]
    return None if w.value == key else f"{where}: {w.value!r} after {key}"  # type: ignore[union-attr]


@pytest.mark.parametrize("mode", [Mode.SAFE, Mode.FULL])
async def test_every_screen_and_widget_obeys_the_safety_keys(scripted_board, mode: Mode) -> None:  # noqa: ANN001
    failures: list[str] = []
    async with flying(scripted_board, size=(160, 50)) as (app, pilot, board, peer):
        await in_mode(app, pilot, peer, mode)
        for name in SCREENS:
            await open_screen(app, pilot, name)
            screen = app.screen
            for i in kinds(focusables(app)):
                for key, want in (("1", Mode.PANIC), ("escape", Mode.PANIC), ("0", Mode.SAFE)):
                    if app.screen is not screen:  # (Esc closed a dialog)
                        await open_screen(app, pilot, name)
                        screen = app.screen
                    w = focusables(app)[i]
                    app.screen.set_focus(w)
                    where = f"{mode.name} {name} {type(w).__name__ if w else 'no focus'} {key}"
                    failure = await check_key(app, pilot, board, w, key, want, where)
                    failures += [failure] if failure else []
                if is_text(w):  # a burst of letters: all text, none a flight key
                    await open_screen(app, pilot, name)
                    w = focusables(app)[i]
                    app.screen.set_focus(w)
                    w.value = ""  # type: ignore[union-attr]
                    board.executed.clear()
                    burst(app, "timeout")
                    await settle(pilot, lambda w=w: w.value == "timeout", 1.0)  # type: ignore[union-attr, misc]
                    flown = await sent_before_marker(pilot, app, board)
                    if flown or w.value != "timeout":  # type: ignore[union-attr]
                        failures.append(f"{mode.name} {name} burst: sent {flown}, box {w.value!r}")  # type: ignore[union-attr]
    assert not failures, "\n".join(failures)


async def test_the_palette_opened_and_typed_into_at_once_never_flies(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, size=(160, 50)) as (app, pilot, board, peer):
        await in_mode(app, pilot, peer, Mode.FULL)
        board.executed.clear()
        app.post_message(events.Key("ctrl+p", None))
        burst(app, "quit")
        await until(pilot, lambda: isinstance(app.screen, CommandPalette))
        assert not await sent_before_marker(pilot, app, board)


# --- a dialog over a live screen keeps the figures behind it live -------------------------------------------------


async def test_the_panels_behind_a_dialog_stay_live() -> None:
    """Issue 22: a lesson's summary froze the panels behind it ("100/100 passed" over M A N U A L, motors 150,
    though the events said MANUAL -> SAFE)."""
    from term.core.protocol import Attitude
    from term.ui.screens.confirm import ConfirmScreen
    from term.ui.widgets.mode import ModeBanner

    app = TermApp(joystick=False)
    async with app.run_test(size=(160, 50)) as pilot:
        app.model.apply_packet(Attitude(int(Mode.MANUAL), 0, 0, 0, 0, 0, 0), app.clock())
        app.render_now()
        await pilot.pause(0.05)
        banner = app.screen.query_one("#mode", ModeBanner)
        assert "M A N U A L" in str(banner.render())
        app.push_screen(ConfirmScreen("a question", "yes", "no"))
        await until(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        app.model.apply_packet(Attitude(int(Mode.SAFE), 0, 0, 0, 0, 0, 0), app.clock())
        app.render_now()
        await pilot.pause(0.05)
        assert "M A N U A L" not in str(banner.render()) and "S A F E" in str(banner.render())


async def test_ctrl_q_in_panic_with_the_motors_stopped_does_not_ask(scripted_board) -> None:  # noqa: ANN001
    """Issue 22: Ctrl+Q in PANIC on the pad (lift 0 %, h 0.00) asked "quit while the motors run?"."""
    from term.core.protocol import Motion
    from term.ui.screens.confirm import ConfirmScreen

    async with flying(scripted_board) as (app, pilot, board, peer):
        await peer.send(attitude(Mode.PANIC), Motion(0, 0, -16384, 180, 180, 180, 180))
        await until(pilot, lambda: app.model.mode == Mode.PANIC and app.model.motion is not None)
        await pilot.press("ctrl+q")  # the motors still turn: it asks
        await until(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.press("enter")  # keep flying
        await until(pilot, lambda: not isinstance(app.screen, ConfirmScreen))
        await peer.send(Motion(0, 0, -16384, 0, 0, 0, 0))
        await until(pilot, lambda: app.model.motion is not None and app.model.motion.ae1 == 0)
        await pilot.press("ctrl+q")
        await until(pilot, lambda: not app.is_running)
    assert app.return_code == 0


async def test_the_terminals_own_parameter_request_failing_is_no_error(scripted_board) -> None:  # noqa: ANN001
    """Issue 22: `list the parameters failed: link lost` after every handover, hand-back and link restore: a
    request the pilot never made. (The scripted board here answers no command at all.)"""
    async with flying(scripted_board, answer=False) as (app, pilot, board, peer):
        await until(pilot, lambda: any(c.op == Op.PARAM_LIST for c in board.commands))
        await until(pilot, lambda: app.model.pending == 0, timeout=10)
        assert not [e.text for e in app.model.events if "list the parameters" in e.text]
        await pilot.press("f11", "r")  # the pilot's own request: its failure is said
        await until(pilot, lambda: any("list the parameters failed" in e.text for e in app.model.events), 10)


async def test_the_readiness_panel_asks_nothing_of_a_recording() -> None:
    """Issue 22: in replay the readiness panel asked to `press ?` (a recording has no board to command)."""
    from term.core.protocol import Attitude, Status

    app = TermApp(joystick=False)
    async with app.run_test(size=(160, 50)) as pilot:
        app.model.apply_packet(Attitude(int(Mode.SAFE), 0, 0, 0, 0, 0, 0), app.clock())
        app.model.apply_packet(Status(0, 0, 0, 0, 0, 42, 10, 0), app.clock())  # not calibrated
        app.render_now()
        await pilot.pause(0.05)
        panel = app.screen.query_one("#readiness")
        assert "press" in str(panel.render())  # live: the keys to press
        app.model.link_name = "REPLAY 00:01 / 00:10 playing  flight.mcap"
        app.model.version += 1
        app.render_now()
        await pilot.pause(0.05)
        text = str(panel.render())
        assert "press" not in text and "?" not in text and "recording" in text, text
