"""The autopilot and the instructor over the simulated board's TCP link (fcb-sim serve --tcp, opened as socket:// by
term's serial transport), as term --sim wires them where there are no pseudo-terminals: the real app (Pilot), the
board served in real time in this process with its instructor channel. The autopilot flies a script of the demo's
first keys (the demo itself opens with 6 s of captions to read; its start through the app is
tests/lessons/test_lesson_app.py's)."""

from __future__ import annotations

import asyncio

from fcb_sim.hosts.instructor import Instructor, InstructorServer
from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.core.protocol import Mode
from term.lessons.instructor import InstructorClient
from term.lessons.spec import maneuvers
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from term.ui.widgets.lesson import LessonBar
from tests.support.waits import until


async def test_the_autopilot_flies_over_the_tcp_link_with_the_instructor() -> None:
    board = make_board(seed=5)
    served = ThreadedServer(board, link="tcp")
    url = served.start()
    assert url.startswith("socket://127.0.0.1:")
    inst = Instructor(board)
    server = InstructorServer(inst)
    loop = served._loop
    assert loop is not None
    address = asyncio.run_coroutine_threadsafe(server.start("tcp-server:127.0.0.1:0"), loop).result(5)
    served.server.cable_open = lambda: inst.cable_open(board.now / 1e6)
    client = InstructorClient(address)
    await client.open()
    app = TermApp(SerialTransport(url), instructor=client, joystick=False)
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            bar = app.screen.query_one(LessonBar)
            await until(pilot, lambda: app.model.mode == Mode.SAFE)
            script = maneuvers([
                {"press": "log_start", "say": "F2: the flash log"},
                {"press": "mode_calibration", "say": "3: CALIBRATION"},
                {"wait": "calibrations >= 1 and mode == 'SAFE'", "timeout": 10},
                {"pause": 60}], "tcp")  # (still flying when the pilot's key takes over)
            app.lessons.driver.start_script("tcp", "the demo's first keys", script, app.clock())
            await until(pilot, lambda: bar.text.startswith("autopilot: 3: CALIBRATION"))
            await until(pilot, lambda: board.mode == Mode.CALIBRATION)  # the autopilot's key reached the board
            room = app.lessons.room
            assert room is not None and room.truth  # the instructor's truth arrives beside the TCP cable
            app.simulate_key("0")  # the pilot's own key takes over
            await until(pilot, lambda: any("you have control" in e.text for e in app.model.events))
            await until(pilot, lambda: board.mode == Mode.SAFE)
    finally:
        await client.close()
        asyncio.run_coroutine_threadsafe(server.close(), loop).result(5)
        served.stop()
