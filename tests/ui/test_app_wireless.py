"""The wireless side of the terminal, through its own app (Textual's Pilot) and real parts:

- the handover end to end as `term --sim` runs it: `fcb-sim serve --pty --ble-hci` in a child process (the real
  board, its real bumble radio), the app's cable over the pty and its radio over BleTransport + our bleak backend
  over bumble: cable -> STARTING -> STARTED -> fly over BLE -> the connection lost -> DISCONNECTED and PANIC,
  the cable carries control again, the radio comes back by itself;
- the wireless screen's controls (mouse clicks and drags) send the right commands and sticks;
- a snapshot of the wireless screen, fed by a handover on a simulated clock (the sans-IO board, no wall clock).
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable

import pytest

from term.core.protocol import Attitude, Command, Decoder, Joystick, Mode, Motion, Op, WirelessState
from term.input.mapping import FULL
from term.session.model import Model
from term.session.sim import SimBoard
from term.session.station import RADIO_SESSION
from term.transports.base import Transport
from term.transports.ble import BleTransport
from term.transports.loopback import loopback_pair
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from term.ui.screens.flight import FlightScreen
from term.ui.screens.wireless import LiftSlider, StickPad, WirelessScreen
from tests.support.app_rig import seeded_handover
from tests.support.waits import until

S = WirelessState


class Recording(Transport):
    """A BLE transport with a tap: the size of every notification read, and every frame written, decoded."""

    def __init__(self, inner: BleTransport) -> None:
        self.inner = inner
        self.name = inner.name
        self.notifications: list[int] = []
        self.sent: list[object] = []
        self._decoder = Decoder()

    async def open(self) -> None:
        await self.inner.open()

    async def close(self) -> None:
        await self.inner.close()

    async def read(self) -> bytes:
        data = await self.inner.read()  # one notification per read
        self.notifications.append(len(data))
        return data

    async def write(self, data: bytes) -> None:
        await self.inner.write(data)
        self.sent += self._decoder.feed(data)

    def joysticks(self) -> list[Joystick]:
        return [p for p in self.sent if type(p) is Joystick]

    def commands(self) -> list[tuple[int, int]]:
        return [(p.op, p.arg) for p in self.sent if type(p) is Command]


async def test_the_handover_through_the_app_end_to_end() -> None:
    sim = SimBoard(seed=3, radio=True)
    port = sim.start()
    try:
        radio = Recording(BleTransport(sim.ble_address, hci=sim.ble_hci, timeout=5.0))
        app = TermApp(SerialTransport(port), joystick=False, radio=radio)
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            def said(text: str) -> bool:
                return any(text in e.text for e in m.events)

            await until(pilot, lambda: m.mode == Mode.SAFE and m.radio_up and m.link is not None)
            assert not m.over_ble and app.control_connection() is app.connection

            # A connection alone changes nothing; the stick still: only keep-alives over BLE (change-only).
            before = len(radio.joysticks())
            t0 = time.monotonic()
            await until(pilot, lambda: len(radio.joysticks()) - before >= 2, what="two keep-alives")
            quiet = radio.joysticks()[before:]
            elapsed = time.monotonic() - t0
            assert len(set(quiet)) == 1  # the same value again: keep-alives only, at most one per keep-alive period
            assert len(quiet) <= elapsed / RADIO_SESSION["keepalive"] + 2, (len(quiet), elapsed)
            assert m.wireless == S.DISCONNECTED and not radio.notifications  # the board says nothing over BLE

            # Key 8 (a real key event) in SAFE, over the cable: STARTING, then STARTED once the radio answered.
            app.simulate_key("8")
            await until(pilot, lambda: m.over_ble)
            assert said("wireless STARTING") and said("wireless STARTED")
            assert app.control_connection() is app.radio_connection
            # The cable falls silent: expected, and said so; no alarm.
            await until(pilot, lambda: m.link_lost)
            assert said("flying over BLE") and not m.control_lost
            await pilot.pause(0.1)
            banner = str(app.screen.query_one("#mode").render())
            assert "over BLE" in banner and "LINK LOST" not in banner
            assert "silent: flying over BLE" in str(app.screen.query_one("#link").render())

            # Fly over BLE: MANUAL goes over the radio, then the lift; the board's mode comes back in Compact.
            app.simulate_key("2")
            await until(pilot, lambda: m.mode == Mode.MANUAL)
            assert (Op.MODE, Mode.MANUAL) in radio.commands()
            await until(pilot, lambda: m.compact is not None and m.compact.mode == Mode.MANUAL)
            assert m.compact.wireless == S.STARTED
            before = len(radio.joysticks())
            t0 = time.monotonic()
            lifts = [8000 + 600 * i for i in range(1, 11)]
            for lift in lifts:  # ten distinct stick values: a frame for each change, plus keep-alives only
                app.set_stick(Joystick(0, 0, 0, lift, 0))
                await pilot.pause(0.03)
            await until(pilot, lambda: radio.joysticks() and radio.joysticks()[-1].lift == 14000)
            elapsed = time.monotonic() - t0
            sent = [js.lift for js in radio.joysticks()[before:]]
            changes = sum(1 for a, b in zip(sent, sent[1:], strict=False) if a != b) + 1
            assert set(sent) <= set(lifts) | {radio.joysticks()[before - 1].lift}
            assert len(sent) - changes <= elapsed / RADIO_SESSION["keepalive"] + 1, (sent, elapsed)
            assert changes >= 5  # (a starved sender may skip a value that was replaced within its 10 ms)
            await pilot.pause(0.3)
            assert m.mode == Mode.MANUAL

            # Every notification is at most 20 bytes, and the board filled them.
            assert radio.notifications and max(radio.notifications) <= 20
            assert sum(radio.notifications) / len(radio.notifications) > 15

            # The radio is gone (its HCI transport dropped: out of range): the board goes DISCONNECTED and PANICs,
            # and the cable carries control again.
            hci = app.radio.inner._client._backend._host.transport  # (on the link's thread, where the radio runs)
            await app.station.runner.run(hci.close()) if app.station.runner is not None else await hci.close()
            await until(pilot, lambda: said("BLE LOST"))
            assert not m.over_ble and app.control_connection() is app.connection
            assert said("PANICs (it was flying over BLE)")
            await until(pilot, lambda: m.attitude is not None and m.attitude.mode == Mode.PANIC and not m.link_lost)
            assert said("wireless DISCONNECTED")
            await until(pilot, lambda: m.motion is not None and m.motion.ae1 > 0 and m.mode == Mode.PANIC)
            assert isinstance(m.motion, Motion)  # the full telemetry is back on the cable
            # PANIC ends in SAFE by itself; then the cable flies: MANUAL is acknowledged over the cable.
            app.set_stick(Joystick(0, 0, 0, 0, 0))
            await until(pilot, lambda: m.mode == Mode.SAFE and m.motion.ae1 == 0, 8.0)
            app.simulate_key("2")
            await until(pilot, lambda: isinstance(m.attitude, Attitude) and m.attitude.mode == Mode.MANUAL)
            assert radio.commands().count((Op.MODE, Mode.MANUAL)) == 1  # not over the radio this time
            app.simulate_key("0")
            # The radio came back by itself (retry with a pause), and the board is not handed over.
            await until(pilot, lambda: m.radio_up, 10.0)
            assert sum("radio connected" in e.text for e in m.events) == 2 and m.wireless == S.DISCONNECTED
    finally:
        sim.stop()


# --- the wireless screen's controls, with the mouse ---------------------------------------------------------


async def test_the_wireless_screen_controls_send_the_right_commands(scripted_board) -> None:  # noqa: ANN001
    import time

    from tests.support.app_rig import LoopBoard, sent
    from tests.support.waits import until

    pair = loopback_pair()
    board = scripted_board(start=time.monotonic())
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    from term.session.station import RADIO_SESSION

    app = TermApp(pair.a, joystick=False, session_options={**RADIO_SESSION, "link_timeout": 0.5},
                  primary_ble=True, start_screen="wireless")
    try:
        async with app.run_test(size=(100, 32)) as pilot:
            await until(pilot, lambda: board.hellos)
            assert isinstance(app.screen, WirelessScreen)  # term --ble opens here

            await pilot.click("#btn-mode_manual")
            await until(pilot, lambda: (Op.MODE, Mode.MANUAL) in sent(board))
            await pilot.click("#btn-roll_up")
            await pilot.click("#btn-lift_down")
            await until(pilot, lambda: [(Op.TRIM_ROLL, 1), (Op.TRIM_LIFT, -1)] == sent(board)[-2:])

            # Drag the lift slider from the bottom to the top row: full lift, and it stays there.
            slider = app.screen.query_one(LiftSlider)
            rows = slider.content_size.height - 1
            await pilot.mouse_down(slider, offset=(2, rows - 1))
            assert slider.lift == 0
            await pilot.hover(slider, offset=(2, rows // 2))
            assert 0.3 * FULL < slider.lift < 0.7 * FULL
            await pilot.hover(slider, offset=(2, 0))
            await pilot.mouse_up(slider, offset=(2, 0))
            await until(pilot, lambda: app.model.stick.lift == FULL)
            assert slider.lift == FULL
            await until(pilot, lambda: board.joysticks and board.joysticks[-1].lift == FULL)

            # The pad: press at its right edge, half way up: full roll right and half forward; let go: centred.
            pad = app.screen.query_one(StickPad)
            w, h = pad.content_size.width, pad.content_size.height
            await pilot.mouse_down(pad, offset=(w - 1, (h - 1) // 4))
            await until(pilot, lambda: board.joysticks[-1].roll == FULL)
            assert board.joysticks[-1].pitch < -0.3 * FULL and board.joysticks[-1].lift == FULL
            await pilot.mouse_up(pad, offset=(w - 1, (h - 1) // 4))
            await until(pilot, lambda: board.joysticks[-1][:2] == (0, 0))
            assert app.model.stick == Joystick(0, 0, 0, FULL, 0)

            await pilot.click("#btn-handover")  # over BLE alone the board would not read it: said, not sent
            assert "press 8 on the cable terminal" in app.model.events[-1].text
            assert (Op.WIRELESS, 1) not in sent(board)

            await pilot.click("#btn-mode_panic")
            await until(pilot, lambda: sent(board)[-1] == (Op.MODE, Mode.PANIC))
            assert slider.lift == 0  # PANIC lets go of the lift, as the phone's button did

            # F7 goes to the flight screen, F10 back; the palette has "reconnect now".
            await pilot.press("f7")
            assert isinstance(app.screen, FlightScreen)
            await pilot.press("f10")
            assert isinstance(app.screen, WirelessScreen)
            titles = [c.title for c in app.get_system_commands(app.screen)]
            assert "Link: reconnect now" in titles and "Link: hand control back to the cable" in titles
            app.reconnect_now()
            assert app.model.events[-1].text == "every link is connected"
    finally:
        await peer.stop()


# --- a snapshot of the wireless screen ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def handover() -> Model:
    return seeded_handover()


def test_the_seeded_handover_is_what_the_screen_claims(handover: Model) -> None:
    m = handover
    assert m.wireless == S.STARTED and m.over_ble and m.mode == Mode.MANUAL
    assert m.link_lost and not m.control_lost  # the cable is silent, as it should be
    assert any("flying over BLE" in e.text for e in m.events)
    assert m.compact is not None and m.radio is not None and m.radio.rtt_last_ms is not None


def test_snapshot_wireless_screen(snap_compare, handover: Model) -> None:  # noqa: ANN001
    app = TermApp(joystick=False, clock=lambda: 3.0, start_screen="wireless")
    app.model = handover
    assert snap_compare(app, terminal_size=(100, 32))


def test_snapshot_flight_screen_over_ble(snap_compare, handover: Model) -> None:  # noqa: ANN001
    """The link panel with both links: the radio carries control (▶), the cable is silent as it should be."""
    app = TermApp(joystick=False, clock=lambda: 3.0)
    app.model = handover
    assert snap_compare(app, terminal_size=(120, 44))


# --- freshness through a handover: no stale figure unmarked --------------------------------------------------


class TwoLinkBoard:
    """fcb_sim's Board paced to the wall clock behind two loopback pairs: its UART on one, its BLE radio on the
    other (each notification written as it comes). What ``fcb-sim serve --pty --ble-hci`` does, in process."""

    def __init__(self, uart: Transport, radio: Transport, board: object) -> None:
        self.uart, self.radio, self.board = uart, radio, board
        self.t0 = 0.0
        self.tasks: list[asyncio.Task[None]] = []

    async def start(self) -> None:
        import time

        await self.uart.open()
        await self.radio.open()
        self.t0 = time.monotonic()
        self.board.ble_connected()  # type: ignore[attr-defined]  # the terminal's radio holds the connection
        self.tasks = [asyncio.create_task(self._read(self.uart, "uart_receive")),
                      asyncio.create_task(self._read(self.radio, "ble_receive")), asyncio.create_task(self._run())]

    def _advance(self) -> None:
        import time

        self.board.advance(int((time.monotonic() - self.t0) * 1e6))  # type: ignore[attr-defined]

    async def _read(self, t: Transport, method: str) -> None:
        while True:
            data = await t.read()
            self._advance()
            getattr(self.board, method)(data)

    async def _run(self) -> None:
        b = self.board
        while True:
            self._advance()
            out = b.uart_transmit()  # type: ignore[attr-defined]
            if out:
                await self.uart.write(out)
            for note in b.wireless.notifications():  # type: ignore[attr-defined]
                await self.radio.write(note)
            await asyncio.sleep(0.002)

    async def stop(self) -> None:
        for t in self.tasks:
            t.cancel()
        for t in self.tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t


# Each panel of the flight screen and the board figures it shows (independent of the widgets' own bookkeeping).
PANEL_FIELDS = {
    "#mode": ("mode",),
    "#heading": ("phi", "theta", "psi"),
    "#rates": ("sp", "sq", "sr"),
    "#motors": ("ae1", "ae2", "ae3", "ae4"),
    "#battery": ("battery",),
    "#pressure": ("pressure", "temperature", "height", "setpoint", "vz"),
    "#controls": ("trim_roll", "trim_pitch", "trim_yaw", "trim_lift", "yaw_p", "p1", "p2", "height_p", "height_d",
                  "flags", "cpu_load", "log_fill"),
}


async def test_no_stale_figure_goes_unmarked_through_a_handover() -> None:
    """TermApp over the cable and the radio to the real (sans-IO) board: on the cable, over BLE (key 8, MANUAL,
    lift trims) and back on the cable, every panel of the flight screen is checked many times: a figure older
    than its staleness limit is marked (its age, or "not over BLE"), the trims flown over BLE are shown from the
    board's Acks and Compact2, not a stale +0, and what Compact2 carries (motors, height, vz, flags, lift trim) is
    fresh over BLE."""
    import time

    from fcb_sim.board.board import Board, BoardConfig
    from fcb_sim.world.physics import World

    cable, radio = loopback_pair(), loopback_pair()
    radio.a.name = "BLE loopback"
    board = Board(BoardConfig(seed=2), world=World(2))
    peer = TwoLinkBoard(cable.b, radio.b, board)
    await peer.start()
    frozen: list[float] = []  # while a check runs, the app's clock stands still: render and check see one instant
    app = TermApp(cable.a, radio=radio.a, joystick=False, clock=lambda: frozen[0] if frozen else time.monotonic())
    stats = {"checks": 0, "stale": 0, "not carried": 0}

    def check() -> None:
        frozen.append(time.monotonic())
        try:
            app.render_now()
            now = frozen[0]
            for wid, names in PANEL_FIELDS.items():
                w = app.screen.query_one(wid)
                shown = f"{w.render()} {w.border_subtitle or ''}"
                for name in names:
                    r = app.model.reading(name, now)
                    if r.stale:
                        assert r.mark and r.mark in shown, (wid, r, shown)
                        stats["stale"] += 1
                        stats["not carried"] += not r.carried
            stats["checks"] += 1
        finally:
            frozen.clear()

    try:
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            async def until_checked(cond: Callable[[], bool], timeout: float = 30.0) -> None:
                """until, with every panel's figures checked at each step (what this test is about)."""
                await until(pilot, lambda: (check(), cond())[1], timeout, step=0.03)

            async def for_s(seconds: float) -> None:
                end = time.monotonic() + seconds
                await until_checked(lambda: time.monotonic() >= end)

            await until_checked(lambda: m.mode == Mode.SAFE and m.radio_up and m.status is not None)
            await for_s(0.3)
            assert not [r for n in PANEL_FIELDS["#motors"] if (r := m.reading(n, app.clock())).stale]
            app.simulate_key("8")
            await until_checked(lambda: m.over_ble)
            app.simulate_key("2")
            await until_checked(lambda: m.mode == Mode.MANUAL)
            for _ in range(5):  # lift trims over BLE: the Acks carry the new trim
                app.simulate_key("a")
                await for_s(0.1)
            await until_checked(lambda: m.reading("trim_lift", app.clock()).value == board.modes.trims.lift > 0)
            assert m.reading("trim_lift", app.clock()).source in ("Ack", "Compact2")
            await for_s(1.5)  # long enough for the cable's last telemetry to go stale
            now = app.clock()
            assert "not over BLE" in str(app.screen.query_one("#rates").border_subtitle)  # the cable's only
            assert not app.screen.query_one("#motors").border_subtitle
            assert m.reading("phi", now).fresh and m.reading("battery", now).fresh  # Compact
            flown = [m.reading(n, now) for n in ("ae1", "ae2", "ae3", "ae4", "height", "vz", "flags", "trim_lift")]
            assert all(r.fresh and r.source == "Compact2" for r in flown), flown  # Compact2
            assert m.reading("ae1", now).value > 0 and m.reading("trim_lift", now).value == board.modes.trims.lift
            app.send(Op.WIRELESS, 0)  # hand control back to the cable, still flying
            await until_checked(lambda: not m.over_ble and m.reading("ae1", app.clock()).fresh, 5.0)
            await until_checked(lambda: m.reading("trim_lift", app.clock()).source == "Status")
            await for_s(0.3)
            assert m.reading("trim_lift", app.clock()).value == board.modes.trims.lift
            assert not app.screen.query_one("#motors").border_subtitle
    finally:
        await peer.stop()
    assert stats["checks"] > 20 and stats["stale"] > 0 and stats["not carried"] > 0, stats


# --- the model's rules for two links (pure) -----------------------------------------------------------------


def test_the_model_follows_figure_12_and_names_the_expected_silence() -> None:
    from term.core.link import LinkLost
    from term.core.protocol import Compact, Event, EventCode, Status

    m = Model(start=0.0)
    m.radio_name, m.radio_up = "BLE test", True
    m.radio_event(LinkLost(1.0), 0.5)  # the board says nothing over BLE before the handover: no alarm
    assert not m.radio_lost and not any("LOST" in e.text for e in m.events)
    m.apply_packet(Event(EventCode.WIRELESS_STATE, int(S.STARTING), 10), 1.0)
    assert m.handed_over and not m.over_ble
    m.apply_packet(Compact(int(Mode.SAFE), int(S.STARTED), 0, 0, 0, 1200), 1.1)
    assert m.over_ble and m.battery_v == 12.0
    m.apply_packet(Status(0, 0, 0, 0, 0, 0, 0, int(S.STARTING)), 1.2)  # sent on the cable before the handover
    assert m.wireless == S.STARTED and m.over_ble  # stale: STARTED is left only for DISCONNECTED
    m.apply(LinkLost(1.0), 1.6)  # the cable's silence while flying over BLE
    assert m.link_lost and not m.control_lost and m.events[-1].severity == "info"
    assert "flying over BLE" in m.events[-1].text
    m.radio_event(LinkLost(1.0), 2.0)  # the radio silent while STARTED: that is the alarm
    assert m.radio_lost and m.control_lost and m.events[-1].severity == "error"
    m.apply_packet(Event(EventCode.WIRELESS_STATE, int(S.DISCONNECTED), 20), 2.5)
    assert not m.over_ble and m.control_lost == m.link_lost
