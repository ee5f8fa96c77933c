"""The joystick through pygame-ce with SDL's dummy video driver, and a real SDL virtual joystick (SDL 2.0.14+, the
library pygame-ce ships) plugged in and out while the poller and the app run: hot-plug, the lab's mapping, the
fire button, the throttle guard, and a stick lost in flight; a virtual game pad read through SDL's
GameController API."""

from __future__ import annotations

import asyncio
import time

import pytest

from term.core.protocol import Button, Mode, Op
from term.input.joystick import GAMEPAD, JoystickPoller
from term.input.mapping import FULL, LAB, mapping_from_dict
from tests.support.joystick_rig import VirtualStick


@pytest.fixture
def poller():  # noqa: ANN201
    p = JoystickPoller()
    p.start()
    yield p
    p.close()


def test_hot_plug_mapping_and_unplug(poller: JoystickPoller) -> None:
    assert not poller.connected and poller.poll().packet is None
    stick = VirtualStick()
    res = poller.poll()
    assert poller.connected and "Virtual Joystick" in res.messages[0] and "mapping lab" in res.messages[0]
    stick.set(0.5, -1.0, 0.0, -1.0, fire=True)
    js = poller.poll().packet
    assert js is not None and js.pitch == -FULL and js.lift == FULL and js.buttons == Button.FIRE
    assert 0 < js.roll < FULL
    assert poller.poll().packet is None  # nothing moved: nothing to send
    stick.unplug()
    res = poller.poll()
    assert res.disconnected and res.packet is not None and res.packet.lift == 0 and not poller.connected


def test_a_game_pad_is_read_through_the_game_controller_api(poller: JoystickPoller) -> None:
    pad = VirtualStick(pad=True)
    try:
        res = poller.poll()
        assert poller.connected and poller.gamepad, res.messages
        assert "game controller" in res.messages[0] and f"mapping {GAMEPAD.name}" in res.messages[0]
        # SDL's layout: left x yaw, left y lift (pushed up), right x roll, right y pitch, A fire
        pad.axes(0.0, -1.0, 0.5, 1.0, 0.0, 0.0, button=0)
        js = poller.poll().packet
        assert js is not None and js.lift == FULL and js.pitch == FULL and js.yaw == 0
        assert 0 < js.roll < FULL and js.buttons == Button.FIRE
    finally:
        pad.unplug()
    assert poller.poll().disconnected and not poller.gamepad


def test_a_mapping_from_the_config_reads_a_pad_raw() -> None:
    mine = mapping_from_dict("mine", {"match": ["Virtual"], "lift": {"axis": 5, "kind": "throttle"}})
    poller = JoystickPoller([mine])
    poller.start()
    pad = VirtualStick(pad=True)
    try:
        poller.poll()
        assert poller.connected and not poller.gamepad and poller.mapping is mine
    finally:
        pad.unplug()
        poller.close()


def test_a_flight_stick_is_read_raw(poller: JoystickPoller) -> None:
    stick = VirtualStick()
    try:
        poller.poll()
        assert poller.connected and not poller.gamepad and poller.mapping is LAB
    finally:
        stick.unplug()


async def test_the_app_flies_the_stick(scripted_board) -> None:  # noqa: ANN001
    from term.transports.loopback import loopback_pair
    from term.ui.app import TermApp
    from tests.support.app_rig import LoopBoard, sent_before_marker
    from tests.support.waits import until

    pair = loopback_pair()
    board = scripted_board(start=time.monotonic())
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    app = TermApp(pair.a, joystick=True)
    stick = None
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            await until(pilot, lambda: app.poller is not None and board.hellos)
            stick = VirtualStick()
            await until(pilot, lambda: app.model.joystick_name == "Virtual Joystick")
            stick.set(0.0, 0.0, 0.0, 0.0)  # throttle lever half way
            await until(pilot, lambda: board.joysticks and board.joysticks[-1].lift > FULL // 3)
            await pilot.press("2")
            await until(pilot, lambda: "throttle is up" in app.model.events[-1].text)
            before = await sent_before_marker(pilot, app, board)
            assert (Op.MODE, Mode.MANUAL) not in before, before
            stick.set(0.0, 0.0, 0.0, 1.0, fire=True)
            await until(pilot, lambda: any(c.op == Op.MODE and c.arg == Mode.PANIC for c in board.executed))
            app.model.mode = Mode.FULL  # as if flying: pulling the stick out is PANIC
            stick.unplug()
            stick = None
            await until(pilot, lambda: "joystick lost in flight" in " ".join(e.text for e in app.model.events))
            await until(pilot, lambda: sum(c.op == Op.MODE and c.arg == Mode.PANIC for c in board.executed) == 2)
            assert app.model.joystick_name is None
            await asyncio.sleep(0)
    finally:
        if stick is not None:
            stick.unplug()
        await peer.stop()
