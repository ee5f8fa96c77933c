"""The console screen through the real link: text the board prints between frames and its Text packets, on a
loopback wire with the scripted board, shown on Ctrl+T, an error line in the events list, the rate limit counted."""

from __future__ import annotations

import term.core.protocol as p
from term.input.keymap import DEFAULT_KEYMAP, help_rows
from term.ui.screens.console import ConsoleScreen
from term.ui.screens.flight import FlightScreen
from term.ui.widgets.console import ConsoleView
from tests.support.app_rig import flying
from tests.support.waits import until


def _texts(app) -> list[str]:  # noqa: ANN001
    return [line.text for _, line in app.model.console]


async def test_printed_text_and_text_packets_show_in_the_console(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await pilot.press("ctrl+t")
        assert isinstance(app.screen, ConsoleScreen)
        await peer.write(b"boot: imu ok\r\n" + board.encoder.encode(p.Heartbeat(99, 1)))
        await peer.send(*p.text_packets("qb_log says hello to the team", p.LEVEL_INFO))
        await peer.write(b"ASSERT failed: qb_flight.c:42\n")
        await until(pilot, lambda: "ASSERT failed: qb_flight.c:42" in _texts(app))
        await until(pilot, lambda: "qb_log says hello to the team" in _texts(app))
        assert _texts(app)[0] == "boot: imu ok"
        await pilot.pause(0.2)  # a render tick
        view = app.screen.query_one(ConsoleView)
        shown = str(view.render())
        assert "boot: imu ok" in shown and "qb_log says hello" in shown
        assert any(e.text == "console: ASSERT failed: qb_flight.c:42" and e.severity == "error"
                   for e in app.model.events)
        assert app.model.link is None or app.model.link.frames_bad == 0  # the text broke no frame
        await pilot.press("f7")
        assert isinstance(app.screen, FlightScreen)


async def test_a_spewing_board_is_rate_limited_and_the_drop_counted(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await peer.write(b"".join(b"spam %d\n" % i for i in range(400)))
        await until(pilot, lambda: app.model.console_dropped > 0)
        assert len(app.model.console) < 400
        await pilot.press("ctrl+t")

        def said() -> str:
            views = app.screen.query(ConsoleView)
            return str(views.first().render()) if views else ""

        await until(pilot, lambda: "dropped by the rate limit" in said())  # (the screen drawn: no fixed pause)


def test_the_help_lists_the_console_key() -> None:
    rows = [(keys, text) for _, keys, text in help_rows(DEFAULT_KEYMAP)]
    assert any("Ctrl+T" in keys.replace("ctrl", "Ctrl").title() or "ctrl+t" in keys.lower() for keys, text in rows
               if "console" in text)
