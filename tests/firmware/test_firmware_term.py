"""term against the C reference board: TermApp over term's own serial transport on the pseudo-terminal of
`host_board --pty` (built with ASan and UBSan), as `term --serial PTY` runs it. The terminal connects and shows the
board's version, PANIC is accepted, MANUAL refused with the board's reason, and the board's death is LINK LOST."""

from __future__ import annotations

from term.core.protocol import NAK_TEXT, PROTOCOL_VERSION, Mode, Nak, Role
from term.session.config import Config
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from tests.support.firmware import HostBoard
from tests.support.waits import until


async def test_term_flies_the_c_reference_board() -> None:
    board = HostBoard()
    try:
        # The C board under ASan has no simulator's honest link timer: starved on a busy machine it is silent
        # for a second now and then; a link timeout it cannot trip (the test is of the meaning, not the timing).
        app = TermApp(SerialTransport(board.path), joystick=False, config=Config(link_timeout=3.0))
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            def texts() -> list[str]:
                return [e.text for e in m.events]

            # connected: the board's Hello (its version) and its mode from the telemetry
            await until(pilot, lambda: m.hello is not None and m.mode == Mode.SAFE)
            assert (m.hello.protocol, m.hello.role, m.hello.major, m.hello.minor) == (PROTOCOL_VERSION, Role.BOARD,
                                                                                    0, 1)
            assert m.link is not None and m.link.board_version == PROTOCOL_VERSION
            # PANIC (key 1) is accepted: the board says so and walks PANIC -> SAFE
            app.simulate_key("1")
            await until(pilot, lambda: any("SAFE → PANIC" in t for t in texts()))
            await until(pilot, lambda: any("PANIC → SAFE" in t for t in texts()) and m.mode == Mode.SAFE)
            assert not [e for e in m.events if e.source == "nak"]
            # MANUAL (key 2) is refused, with the board's reason on the screen
            app.simulate_key("2")
            await until(pilot, lambda: any(e.source == "nak" for e in m.events))
            (nak,) = [e for e in m.events if e.source == "nak"]
            assert nak.text == f"NAK mode MANUAL: {NAK_TEXT[Nak.NOT_IMPLEMENTED]}"
            # on the screen too (the panel draws on its own tick: waited for, a busy machine is slow, not wrong)
            await until(pilot, lambda: "not implemented on this board" in str(app.screen.query_one("#events").render()))
            assert not [e for e in m.events if e.source == "link" and e.severity == "error"]
            # the board dies: LINK LOST
            board.kill()
            await until(pilot, lambda: m.link_lost)
            await until(pilot, lambda: any(t.startswith("LINK LOST") for t in texts())
                        and "LINK LOST" in str(app.screen.query_one("#mode").render()))
            assert "LINK LOST" in str(app.screen.query_one("#mode").render())
    finally:
        board.kill()
