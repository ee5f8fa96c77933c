"""The app driven by Textual's Pilot over the real link (LinkSession + Connection) on a loopback transport, with
the scripted board of conftest.py at the other end: every key, every panel, refusals, NAKs, link loss."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from term.core.protocol import (
    Attitude,
    Button,
    Command,
    Event,
    EventCode,
    Flag,
    Gains,
    Height,
    Joystick,
    Mode,
    Motion,
    Nak,
    Op,
    Profile,
    Status,
    field_scale,
)
from term.input.keymap import DEFAULT_KEYMAP
from term.input.mapping import FULL
from term.transports.loopback import loopback_pair
from term.ui.app import TermApp
from term.ui.screens.flight import FlightScreen
from term.ui.screens.help import HelpScreen
from term.ui.screens.plots import PlotsScreen
from term.ui.screens.profile import ProfileScreen
from term.ui.widgets.base import ModelView
from term.ui.widgets.profile import ProfileTable
from tests.support.app_rig import flying, sent, sent_before_marker
from tests.support.waits import until


async def test_a_check_that_nothing_was_sent_can_fail(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        app.send(Op.TRIM_YAW, 1)  # not awaited: the marker's wait covers it
        assert (Op.TRIM_YAW, 1) in await sent_before_marker(pilot, app, board)


async def test_every_board_key_sends_its_command_at_once(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        expected = []
        for b in DEFAULT_KEYMAP:
            if b.action.op is None:
                continue
            for key in b.keys:
                await pilot.press(key)
                expected.append((int(b.action.op), b.action.arg))
                n = len(expected)
                await until(pilot, lambda n=n: len(sent(board)) >= n)
        assert sent(board) == expected
        # every one acknowledged: nothing pending, no failures in the events list
        await until(pilot, lambda: app.model.pending == 0)
        assert not [e for e in app.model.events if e.severity == "error"]


async def test_screen_keys_help_plots_profile_and_back(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        await pilot.press("f1")
        assert isinstance(app.screen, HelpScreen)
        text = str(app.screen.query_one("#help-table").render())
        await pilot.press("2")  # pilot keys work under the help screen
        await until(pilot, lambda: (Op.MODE, Mode.MANUAL) in sent(board))
        await pilot.press("question_mark")
        assert isinstance(app.screen, FlightScreen)
        assert text  # rendered
        await pilot.press("f8")
        assert isinstance(app.screen, PlotsScreen)
        await pilot.press("f9")
        assert isinstance(app.screen, ProfileScreen)
        await pilot.press("f7")
        assert isinstance(app.screen, FlightScreen)
        await pilot.press("f6")  # profile: asks the board and shows the table
        assert isinstance(app.screen, ProfileScreen)
        await until(pilot, lambda: (Op.PROFILE, 0) in sent(board))
        await pilot.press("f7")
        app.model.note(app.clock(), "info", "term", "something")
        await pilot.press("ctrl+l")
        assert not app.model.events


async def test_throttle_up_refuses_to_leave_safe_and_says_so(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        app.set_stick(Joystick(0, 0, 0, FULL // 2, 0))
        await pilot.press("2")
        assert (Op.MODE, Mode.MANUAL) not in await sent_before_marker(pilot, app, board)
        assert "throttle is up" in app.model.events[-1].text
        await until(pilot, lambda: board.joysticks and board.joysticks[-1].lift == FULL // 2)
        await pilot.press("1")  # PANIC always goes
        await until(pilot, lambda: (Op.MODE, Mode.PANIC) in sent(board))
        app.set_stick(Joystick(0, 0, 0, 0, 0))
        await pilot.press("2")
        await until(pilot, lambda: (Op.MODE, Mode.MANUAL) in sent(board))


async def test_fire_button_is_panic(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        app.set_stick(Joystick(100, 0, 0, 0, int(Button.FIRE)))
        await until(pilot, lambda: (Op.MODE, Mode.PANIC) in sent(board))
        board.executed.clear()
        app.set_stick(Joystick(100, 0, 0, 0, int(Button.FIRE)))  # held: not sent again
        assert (Op.MODE, Mode.PANIC) not in await sent_before_marker(pilot, app, board)


async def test_a_nak_is_shown_with_its_reason(scripted_board) -> None:  # noqa: ANN001
    def refuse(cmd: Command) -> Nak:
        return Nak.NOT_CALIBRATED if cmd.op == Op.MODE and cmd.arg == Mode.FULL else Nak.OK

    async with flying(scripted_board, nak=refuse) as (app, pilot, board, _):
        await pilot.press("5")
        await until(pilot, lambda: any(e.source == "nak" for e in app.model.events))
        e = [e for e in app.model.events if e.source == "nak"][0]
        assert e.text == "NAK mode FULL: not calibrated: run CALIBRATION (3) first" and e.severity == "error"
        # (the events list is redrawn at the next render tick, which a busy machine can hold back)
        await until(pilot, lambda: "not calibrated" in str(app.screen.query_one("#events").render()),
                    what=lambda: f"the NAK in the events list: {app.screen.query_one('#events').render()}")


async def test_link_lost_is_unmissable_and_restored(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, link_timeout=0.5) as (app, pilot, board, _):
        await until(pilot, lambda: app.model.link is not None and app.model.link.heartbeats > 0)
        board.silent = True
        await until(pilot, lambda: app.model.link_lost)
        await until(pilot, lambda: "L I N K   L O S T" in str(app.screen.query_one("#link").render()))
        assert "LINK LOST" in str(app.screen.query_one("#mode").render())
        await pilot.press("5")  # a command to a lost link fails with the reason
        await until(pilot, lambda: "link lost" in app.model.events[-1].text)
        board.silent = False
        await until(pilot, lambda: not app.model.link_lost)
        assert "link restored" in " ".join(e.text for e in app.model.events)


async def test_version_mismatch_exits_with_one_line(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board, protocol=99) as (app, pilot, board, _):
        await until(pilot, lambda: app.exit_message is not None)
    assert app.return_code == 3
    assert app.exit_message.startswith("board speaks protocol v99") and "\n" not in app.exit_message


async def test_palette_typing_does_not_fly(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        await pilot.press("ctrl+p")
        await pilot.pause(0.1)
        await pilot.press("5", "1", "a", "backspace", "backspace", "backspace")
        for k in "full control":
            await pilot.press(k if k != " " else "space")
        assert not await sent_before_marker(pilot, app, board)  # the digits and letters went into the palette's input
        await pilot.press("down", "enter")  # runs the first match: "Modes: FULL control ..."
        await until(pilot, lambda: (Op.MODE, Mode.FULL) in sent(board))


def plain(renderable: object) -> str:
    console = Console(width=120, record=True, file=io.StringIO())
    console.print(renderable)
    return console.export_text()


def feed_all(app: TermApp) -> None:
    m, now = app.model, app.clock()
    m.apply_packet(Attitude(Mode.HEIGHT, 1200, -550, 9000, 164, -82, 33), now)
    m.apply_packet(Motion(10, -20, -16384, 410, 395, 402, 980), now)
    def raw(name: str, value: float) -> int:  # in the wire unit the packet table gives
        return round(value / field_scale(Height, name))

    m.apply_packet(Height(101300, raw("height", 1.234), raw("setpoint", 1.5), raw("vz", -0.12), 1040, 2150), now)
    m.apply_packet(Status(int(Flag.CALIBRATED | Flag.ARMED | Flag.LOW_BATTERY | Flag.HEIGHT_HOLD), 10, -20, 5,
                          300, 42, 10, 0), now)
    m.apply_packet(Gains(-800.0, 0.4, 111.0, 1.5, 0.25), now)
    m.apply_packet(Event(EventCode.LOW_BATTERY, 1040, 61000), now)
    m.apply_packet(Profile(0, 20, 95, 332, 1487, 0), now)
    m.apply_packet(Profile(2, 113, 220, 492, 2477, 3), now)


async def test_every_panel_shows_its_data() -> None:
    app = TermApp(joystick=False)
    async with app.run_test(size=(120, 44)) as pilot:
        feed_all(app)
        app.model.set_stick(Joystick(16000, -8000, 0, 12000, 0))
        app.model.joystick_name, app.model.joystick_mapping = "Logitech Extreme 3D", "lab"
        app.render_now()
        await pilot.pause(0.05)

        def text(wid: str) -> str:
            return str(app.screen.query_one(wid).render())

        assert "H E I G H T" in text("#mode") and "LOW BATTERY" in text("#mode")
        assert "roll  +12.0°" in text("#heading") and "090.0°" in text("#heading") and "E" in text("#heading")
        assert "▀" in text("#horizon")
        assert "+10°/s" in text("#rates") and "-5°/s" in text("#rates")
        assert " 980" in text("#motors") and " 410" in text("#motors")
        assert "10.40 V" in text("#battery") and "BELOW 10.5 V" in text("#battery")
        p = text("#pressure")
        assert "101300 Pa" in p and "+1.23 m" in p and "+1.50 m" in p and "-0.12m/s" in p
        c = text("#controls")
        assert "Logitech Extreme 3D" in c and "trim    +10" in c and "P2 111" in c
        assert "throttle up" not in c  # flying (HEIGHT): lift is what it should be, not a warning
        assert "CAL" in c and "LOWBAT" in c and "cpu  42%" in c
        assert "waiting for the board" in text("#link")
        assert "LOW BATTERY 10.40 V" in text("#events")
        await pilot.press("f9")
        await pilot.pause(0.05)
        prof = plain(app.screen.query_one(ProfileTable).render_model(app.model, app.clock()))
        assert "control" in prof and "492" in prof and "2477" in prof
        await pilot.press("f8")
        await until(pilot, lambda: len(app.screen.query("LivePlot")) == 2)
        assert len(app.screen.query("LivePlot")) == 2  # degrees and metres from the default series
        assert all(isinstance(w, ModelView) for w in app.screen.query("#mode"))


async def test_not_connected_commands_say_so() -> None:
    app = TermApp(joystick=False)
    async with app.run_test() as pilot:
        await pilot.press("4")
        assert app.model.events[-1].text == "not sent: mode YAW: not connected"


@pytest.mark.parametrize("key", ["f5"])
async def test_download_needs_a_link(key: str) -> None:
    app = TermApp(joystick=False)
    async with app.run_test() as pilot:
        await pilot.press(key)
        assert "not connected" in app.model.events[-1].text


async def test_download_to_a_chosen_directory(scripted_board, tmp_path) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, _):
        app.download_to()
        await pilot.pause(0.1)
        inp = app.screen.query_one("#directory")
        inp.value = str(tmp_path / "lo")
        inp.cursor_position = len(inp.value)
        await pilot.press("g", "s", "1", "5", "backspace", "backspace", "enter")  # typed keys go to the input
        await until(pilot, lambda: (Op.LOG_DOWNLOAD, 0) in sent(board))
        assert app.log_directory == tmp_path / "logs"
        assert not any(op == Op.MODE for op, _ in sent(board))  # typing the path flew nothing
        app.download_to()
        await pilot.pause(0.1)
        await pilot.press("escape")  # cancels the dialog, not PANIC
        assert (Op.MODE, Mode.PANIC) not in await sent_before_marker(pilot, app, board)
        assert isinstance(app.screen, FlightScreen)


async def test_joystick_policy_from_the_config_and_ctrl_q_quits() -> None:
    from term.session.config import Config

    pair = loopback_pair()
    await pair.b.open()
    app = TermApp(pair.a, joystick=False, config=Config(joystick_policy="on-change"))
    async with app.run_test() as pilot:
        assert app.connection is not None and app.connection.session.change_only
        await pilot.press("ctrl+q")
        await pilot.pause(0.1)
    assert app.return_code == 0 and app.connection is None  # stopped on the way out


async def test_damaged_frames_are_reported_in_the_events_list(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await until(pilot, lambda: app.model.link is not None and app.model.link.frames_ok > 0)
        await peer.t.write(b"\x07\x11\x22\x33\x44\x55\x66\x00" * 3)  # three frames with bad CRCs
        await until(pilot, lambda: any("damaged frames dropped" in e.text for e in app.model.events))
        e = [e for e in app.model.events if "damaged" in e.text][0]
        assert e.text.startswith("3 damaged frames") and e.severity == "warning"


async def test_a_dead_transport_is_reopened(scripted_board) -> None:  # noqa: ANN001
    async with flying(scripted_board) as (app, pilot, board, peer):
        await until(pilot, lambda: app.model.link is not None and app.model.link.frames_ok > 0)
        await peer.stop()
        await peer.t.close()  # the cable is pulled out
        await until(pilot, lambda: any(e.text.startswith("LINK LOST: ") for e in app.model.events))
        assert app.connection is None and app.model.link_lost
        await pilot.press("5")
        assert "not connected" in app.model.events[-1].text
        await peer.start()  # plugged in again
        await until(pilot, lambda: any(e.text.startswith("reconnected to") for e in app.model.events))
        await until(pilot, lambda: not app.model.link_lost)
        await pilot.press("4")
        await until(pilot, lambda: (Op.MODE, Mode.YAW) in sent(board))


async def test_silence_after_a_wireless_handover_says_so(scripted_board) -> None:  # noqa: ANN001
    from term.core.protocol import WirelessState

    async with flying(scripted_board, link_timeout=0.5) as (app, pilot, board, peer):
        await until(pilot, lambda: app.model.link is not None and app.model.link.frames_ok > 0)
        await peer.send(Event(EventCode.WIRELESS_STATE, int(WirelessState.STARTING), 1000))
        await until(pilot, lambda: app.model.handed_over)
        board.silent = True
        await until(pilot, lambda: app.model.link_lost)
        await until(pilot, lambda: "handed over to BLE" in str(app.screen.query_one("#mode").render()))
        assert "handing over to BLE" in str(app.screen.query_one("#link").render())


async def test_the_mode_banner_says_how_far_the_simulator_lags_while_it_does() -> None:
    """Issue 21: a starved simulator says it runs behind real time (SIM_LAG, at most once a second); the flight
    screen shows it under the mode, and drops it a few seconds after the simulator stops saying it."""
    from term.ui.widgets.mode import SIM_LAG_SHOWN_S

    now = [100.0]
    app = TermApp(joystick=False, clock=lambda: now[0])
    async with app.run_test(size=(120, 44)) as pilot:
        app.model.apply_packet(Attitude(Mode.FULL, 0, 0, 0, 0, 0, 0), now[0])
        app.render_now()
        await pilot.pause(0.05)
        assert "behind real time" not in str(app.screen.query_one("#mode").render())
        app.model.apply_packet(Event(EventCode.SIM_LAG, 240, 5000), now[0])
        app.render_now()
        await pilot.pause(0.05)
        assert "simulator 240 ms behind real time" in str(app.screen.query_one("#mode").render())
        now[0] += SIM_LAG_SHOWN_S + 0.1
        app.model.apply_packet(Attitude(Mode.FULL, 0, 0, 0, 0, 0, 0), now[0])
        app.render_now()
        await pilot.pause(0.05)
        assert "behind real time" not in str(app.screen.query_one("#mode").render())
