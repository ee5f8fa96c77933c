"""The joystick screen (F12) with a real SDL virtual joystick: live axes and buttons, the mapping changed by its
buttons (invert, dead zone) and flown at once, and saved to the config file, which the terminal then reads back."""

from __future__ import annotations

import time
from pathlib import Path

from term.input.mapping import FULL
from term.session.config import Config, load_config
from term.transports.loopback import loopback_pair
from term.ui.app import TermApp
from term.ui.screens.joystick import JoystickScreen
from tests.support.app_rig import LoopBoard
from tests.support.joystick_rig import VirtualStick
from tests.support.waits import until


async def test_the_joystick_screen_edits_and_saves_the_mapping(scripted_board, tmp_path: Path) -> None:  # noqa: ANN001
    path = tmp_path / "term.toml"
    path.write_text('# my settings\n[plots]\nwindow = 20.0\n', encoding="utf-8")
    pair = loopback_pair()
    board = scripted_board(start=time.monotonic())
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    app = TermApp(pair.a, joystick=True, config=Config(source=path))
    stick = None
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            await until(pilot, lambda: app.poller is not None and board.hellos)
            stick = VirtualStick()
            await until(pilot, lambda: app.poller.connected)  # type: ignore[union-attr]
            await pilot.press("f12")
            assert isinstance(app.screen, JoystickScreen)
            stick.set(0.5, 0.0, 0.0, 0.5)  # roll half right; the lab's throttle lever a quarter up
            await until(pilot, lambda: app.model.stick.roll > FULL // 3)
            app.render_now()
            await pilot.pause(0.05)
            view = str(app.screen.query_one("#js-view").render())
            assert "Virtual Joystick" in view and "axis 0" in view and "+0.50" in view and "mapping: lab" in view
            lift_before = app.model.stick.lift
            await pilot.click("#js-lift-invert")  # the lever the other way round: flown at once
            await until(pilot, lambda: app.model.stick.lift != lift_before)
            assert app.poller.mapping.lift.invert is False  # type: ignore[union-attr]
            for _ in range(3):
                await pilot.click("#js-roll-dz-up")
                await pilot.pause(0.25)  # a Button takes no second press within its 0.2 s press effect
            assert abs(app.poller.mapping.roll.deadzone - 0.08) < 1e-9  # type: ignore[union-attr]
            await pilot.click("#js-save")
            await until(pilot, lambda: any("mapping saved" in e.text for e in app.model.events))
            assert app.model.joystick_mapping == "virtual_joystick"
    finally:
        if stick is not None:
            stick.unplug()
        await peer.stop()
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# my settings\n[plots]\nwindow = 20.0\n")  # the rest of the file kept as it was
    cfg = load_config(path, required=True)
    mine = next(m for m in cfg.joystick_mappings if m.name == "virtual_joystick")
    assert mine.match == ("Virtual Joystick",) and mine.lift.invert is False and abs(mine.roll.deadzone - 0.08) < 1e-9
    assert cfg.plot_window == 20.0
