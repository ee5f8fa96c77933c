"""The station without a screen (term.session.station): two links to one board over real connections on loopback pairs,
each with the scripted board of conftest.py at the other end; routing, send guards, the fire button, reconnects
and their pauses (an injected sleep records them), fatal ends. The model is updated only through its events."""

from __future__ import annotations

import asyncio
import time

import pytest

from term.core.errors import EXIT_USAGE, EXIT_VERSION
from term.core.events import CABLE, RADIO, Fatal, LinkDown, LinkFailed, LinkUp, NotSent, Requested, StationEvent
from term.core.protocol import Button, Event, EventCode, Joystick, Mode, Op, WirelessState
from term.input.mapping import FULL
from term.session.model import Model
from term.session.station import BLE_BACKOFF_S, RECONNECT_S, Station
from term.transports.loopback import loopback_pair
from term.transports.serial import SerialTransport
from tests.support.app_rig import LoopBoard, sent
from tests.support.waits import until


class Recorder:
    """The front end's side: every event the station hands on, and the pauses it asked for."""

    def __init__(self) -> None:
        self.events: list[StationEvent] = []
        self.pauses: list[float] = []
        self.station: Station | None = None
        self.stop_after: int | None = None

    def __call__(self, ev: StationEvent) -> None:
        self.events.append(ev)

    async def sleep(self, s: float) -> None:
        self.pauses.append(s)
        if self.stop_after is not None and len(self.pauses) >= self.stop_after and self.station is not None:
            self.station.running = False  # the app quits: the loop ends after this pause
        await asyncio.sleep(0)

    def of(self, kind: type) -> list:
        return [e for e in self.events if type(e) is kind]


async def two_links(scripted_board, **station_kw):  # noqa: ANN001, ANN201
    cable, radio = loopback_pair(), loopback_pair()
    cable.a.name, radio.a.name = "cable", "ble"
    boards = []
    for pair in (cable, radio):
        board = scripted_board(start=time.monotonic())
        peer = LoopBoard(pair.b, board, time.monotonic)
        await peer.start()
        boards.append((board, peer))
    rec = Recorder()
    model = Model(start=time.monotonic(), link_name="cable", radio_name="ble")
    st = Station(model, cable=cable.a, radio=radio.a, cable_session={"link_timeout": 0.5},
                 radio_session={"link_timeout": 0.5}, on_event=rec, sleep=rec.sleep, **station_kw)
    rec.station = st
    await st.start()
    return st, rec, boards


async def stop(st: Station, boards) -> None:  # noqa: ANN001
    await st.shutdown()
    for _, peer in boards:
        await peer.stop()


async def test_commands_follow_control_and_sticks_go_to_both(scripted_board) -> None:  # noqa: ANN001
    st, rec, boards = await two_links(scripted_board)
    (cable_board, _), (radio_board, radio_peer) = boards
    try:
        await until(lambda: st.model.radio_up and cable_board.hellos and radio_board.hellos)
        assert [(e.link, e.again) for e in rec.of(LinkUp)] == [(CABLE, False), (RADIO, False)]
        assert st.control() is st.cable
        st.send(Op.MODE, Mode.CALIBRATION)
        await until(lambda: (Op.MODE, Mode.CALIBRATION) in sent(cable_board))
        # The board says STARTED over BLE: the radio carries control now.
        await radio_peer.send(Event(EventCode.WIRELESS_STATE, int(WirelessState.STARTED), 10))
        await until(lambda: st.model.over_ble)
        assert st.control() is st.radio
        st.send(Op.MODE, Mode.MANUAL)
        await until(lambda: (Op.MODE, Mode.MANUAL) in sent(radio_board))
        assert (Op.MODE, Mode.MANUAL) not in sent(cable_board)
        assert [(e.op, e.link) for e in rec.of(Requested)] == [(Op.MODE, CABLE), (Op.MODE, RADIO)]
        assert any(e.text == "request MANUAL over BLE" for e in st.model.events)
        # Sticks to both links, whichever carries control.
        st.set_axes(lift=1234)
        await until(lambda: cable_board.joysticks[-1].lift == 1234 and radio_board.joysticks[-1].lift == 1234)
        assert st.model.stick == Joystick(0, 0, 0, 1234, 0)
        st.set_axes(roll=-FULL)
        assert st.model.stick == Joystick(-FULL, 0, 0, 1234, 0)  # the other axes kept
    finally:
        await stop(st, boards)


async def test_guards_refuse_with_a_reason(scripted_board) -> None:  # noqa: ANN001
    st, rec, boards = await two_links(scripted_board)
    (cable_board, _), _ = boards
    try:
        await until(lambda: cable_board.hellos and st.model.radio_up)
        st.model.apply_packet(Event(EventCode.MODE_CHANGED, int(Mode.SAFE), 1), 0.0)
        st.set_stick(Joystick(0, 0, 0, FULL // 2, 0))
        assert st.send(Op.MODE, Mode.MANUAL) is None
        refused = rec.of(NotSent)[-1]
        assert "throttle is up" in refused.why and refused.title == "MANUAL refused"
        assert "not sent: MANUAL: throttle is up" in st.model.events[-1].text
        assert st.send(Op.MODE, Mode.PANIC) is not None  # PANIC always goes
        await until(lambda: (Op.MODE, Mode.PANIC) in sent(cable_board))
        assert (Op.MODE, Mode.MANUAL) not in sent(cable_board)
        # The fire button: its press is PANIC, once while held.
        st.set_stick(Joystick(0, 0, 0, 0, int(Button.FIRE)))
        st.set_stick(Joystick(5, 0, 0, 0, int(Button.FIRE)))
        await until(lambda: sent(cable_board).count((Op.MODE, Mode.PANIC)) == 2)
        await asyncio.sleep(0.05)
        assert sent(cable_board).count((Op.MODE, Mode.PANIC)) == 2
        assert any(e.text == "fire: PANIC" for e in st.model.events)
    finally:
        await stop(st, boards)


async def test_over_ble_alone_the_handover_is_refused_and_nothing_goes_to_a_dead_link() -> None:
    model = Model(start=0.0, primary_ble=True)
    rec = Recorder()
    st = Station(model, on_event=rec)
    assert st.send(Op.WIRELESS, 1) is None
    assert rec.of(NotSent)[-1].title == "wireless handover" and rec.of(NotSent)[-1].severity == "warning"
    assert st.send(Op.MODE, Mode.YAW) is None
    assert model.events[-1].text == "not sent: mode YAW: not connected"
    assert rec.of(NotSent)[-1].title is None  # no toast for this one: the link panel says it already


async def test_a_cable_that_will_not_open_is_fatal() -> None:
    rec = Recorder()
    st = Station(Model(), cable=SerialTransport("/nonexistent/ttyQ9"), on_event=rec, sleep=rec.sleep)
    await st.start()
    fatal = rec.of(Fatal)
    assert len(fatal) == 1 and fatal[0].code == EXIT_USAGE and "/nonexistent/ttyQ9" in fatal[0].message
    assert not rec.of(LinkFailed)  # the first connection's failure is the fatal one, not a "reconnecting"
    await st.shutdown()


async def test_an_unreachable_radio_is_tried_after_growing_pauses() -> None:
    rec = Recorder()
    rec.stop_after = 6
    model = Model(start=0.0, radio_name="ble")
    st = Station(model, radio=SerialTransport("/nonexistent/radio"), on_event=rec, sleep=rec.sleep)
    rec.station = st
    await st.start()
    await until(lambda: not st.running and len(rec.of(LinkFailed)) == 7)  # a try after each pause
    await st.shutdown()
    assert rec.pauses == [1.0, 2.0, 4.0, 8.0, 8.0, 8.0] and tuple(rec.pauses[:4]) == BLE_BACKOFF_S
    failed = rec.of(LinkFailed)
    assert not failed[0].repeated and all(f.repeated for f in failed[1:])
    said = [e.text for e in model.events if "radio not connected" in e.text]
    assert len(said) == 1  # the same reason is said once
    assert model.radio_note == "connecting…" or model.radio_note.startswith("down: ")


async def test_a_lost_cable_is_reopened_every_second(scripted_board) -> None:  # noqa: ANN001
    pair = loopback_pair()
    board = scripted_board(start=time.monotonic())
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    rec = Recorder()
    st = Station(Model(start=time.monotonic()), cable=pair.a, cable_session={"link_timeout": 0.5}, on_event=rec,
                 sleep=rec.sleep)
    try:
        await st.start()
        await until(lambda: board.hellos)
        await peer.stop()
        await pair.b.close()  # the cable is pulled out
        await until(lambda: rec.of(LinkDown))
        assert st.control() is None and st.model.link_lost
        assert any(e.text.startswith("LINK LOST: ") for e in st.model.events)
        await until(lambda: len(rec.pauses) >= 2)
        assert any(e.text.startswith("reconnecting: ") for e in st.model.events)
        await peer.start()  # plugged in again
        await until(lambda: any(e.again for e in rec.of(LinkUp)))
        assert set(rec.pauses) == {RECONNECT_S}
        assert any(e.text == "reconnected to loopback a" for e in st.model.events)
    finally:
        await st.shutdown()
        await peer.stop()


async def test_a_board_of_another_protocol_version_is_fatal(scripted_board) -> None:  # noqa: ANN001
    pair = loopback_pair()
    board = scripted_board(start=time.monotonic(), protocol=99)
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    rec = Recorder()
    st = Station(Model(start=time.monotonic()), cable=pair.a, on_event=rec)
    try:
        await st.start()
        await until(lambda: rec.of(Fatal))
        f = rec.of(Fatal)[0]
        assert f.code == EXIT_VERSION and f.message.startswith("board speaks protocol v99")
        assert st.model.version_mismatch is not None
    finally:
        await st.shutdown()
        await peer.stop()


async def test_a_lost_radio_hands_control_back_to_the_cable(scripted_board) -> None:  # noqa: ANN001
    st, rec, boards = await two_links(scripted_board)
    (cable_board, _), (radio_board, radio_peer) = boards
    try:
        await until(lambda: st.model.radio_up and radio_board.hellos)
        await radio_peer.send(Event(EventCode.WIRELESS_STATE, int(WirelessState.STARTED), 10),
                              Event(EventCode.MODE_CHANGED, int(Mode.MANUAL), 11))
        await until(lambda: st.model.over_ble and st.model.flying)
        rec.stop_after = 1  # one pause, then the test ends the loop
        await radio_peer.stop()
        await radio_peer.t.close()  # out of range
        await until(lambda: rec.of(LinkDown))
        m = st.model
        assert not m.radio_up and m.wireless == WirelessState.DISCONNECTED and st.control() is st.cable
        assert any("PANICs (it was flying over BLE)" in e.text for e in m.events)
        await until(lambda: rec.pauses)
        assert rec.pauses[0] == BLE_BACKOFF_S[0]  # lost just now: a pause before the first try
    finally:
        await stop(st, boards)


@pytest.mark.parametrize("kind", ["LinkUp", "LinkDown", "LinkWaiting", "LinkConnecting", "LinkFailed", "StatsSample",
                                  "Requested", "NotSent", "Note", "StickSet", "JoystickNamed", "EventsCleared",
                                  "FromLink"])
def test_every_station_event_changes_the_model_in_one_place(kind: str) -> None:
    """Each event type the station emits has the model's handler (Fatal is the front end's alone)."""
    from term.core import events
    from term.session.model import _HANDLERS

    assert getattr(events, kind) in _HANDLERS
    assert events.Fatal not in _HANDLERS


async def test_an_exception_in_the_link_path_is_link_lost_with_its_cause_and_the_link_comes_back(
        scripted_board) -> None:  # noqa: ANN001
    """Issue 21: a parameter file value that overflowed raised inside the reaction to the board's Hello, and the
    cable's read loop ended in silence (nothing received, no LINK LOST, no reconnect)."""
    pair = loopback_pair()
    board = scripted_board(start=time.monotonic())
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    rec = Recorder()
    blown = []

    def front_end(ev: StationEvent) -> None:
        rec(ev)
        if not blown and type(ev).__name__ == "FromLink" and type(ev.event.packet).__name__ == "Hello":
            blown.append(ev)
            raise OverflowError("cannot convert float infinity to integer")

    st = Station(Model(start=time.monotonic()), cable=pair.a, cable_session={"link_timeout": 0.5},
                 on_event=front_end, sleep=rec.sleep)
    try:
        await st.start()
        await until(lambda: rec.of(LinkDown))
        down = rec.of(LinkDown)[0]
        assert "OverflowError" in down.message and "cannot convert float infinity" in down.message
        assert any(e.text.startswith("LINK LOST: ") and "OverflowError" in e.text for e in st.model.events)
        await until(lambda: any(e.again for e in rec.of(LinkUp)))  # reconnected by itself
        n = len(board.hb_acks)
        await until(lambda: len(board.hb_acks) > n + 2)  # and the board is fed again
    finally:
        await st.shutdown()
        await peer.stop()
