"""Lesson 1 flown headless (Textual's Pilot) by the pilot's keys over the simulated board's own link, wired as
`term --sim` wires it: the board a child (`fcb-sim serve`, its link the platform's choice: a loopback TCP port
where there are no pseudo-terminals), its BLE radio beside the cable and its instructor channel, the session
recorded. Run as a child process by tests/platform/test_windows_shape.py:

    python -m tests.support.shaped_lesson RECORD_DIR

and prints one JSON line: the link, the lesson's score, whether the radio came up, the platform it saw."""

from __future__ import annotations

import asyncio
import json
import sys
import time
from pathlib import Path

from tests.support.waits import until


async def fly(record_dir: Path) -> dict[str, object]:
    from term.session.sim import SimBoard

    sim = SimBoard(seed=4, radio=True, instructor=True, log=True)
    sim.launch()  # the board boots while the screens are imported (as term --sim does)
    from term.core.events import CABLE, RADIO
    from term.data.recording import RecordingTransport, SessionRecorder
    from term.lessons.instructor import InstructorClient
    from term.transports.ble import BleTransport
    from term.ui.app import TermApp
    from term.ui.widgets.lesson import LessonBar, SummaryScreen

    sim.start()
    client = InstructorClient(sim.instructor_address)
    try:
        await client.open()
        rec = SessionRecorder(record_dir, time.monotonic(), meta={"cable": sim.port, "radio": sim.ble_address})
        cable = RecordingTransport(sim.transport(115200), (rec,), CABLE, time.monotonic)
        radio = RecordingTransport(BleTransport(sim.ble_address, hci=sim.ble_hci, timeout=10), (rec,), RADIO,
                                   time.monotonic)
        app = TermApp(cable, radio=radio, instructor=client, lesson=1, joystick=False, recorder=rec)
        async with app.run_test(size=(120, 44)) as pilot:

            await until(pilot, lambda: app.lessons.driver.run is not None and app.lessons.driver.run.state == "running")
            bar = app.screen.query_one(LessonBar)
            app.simulate_key("3")
            await until(pilot, lambda: "2/3 Arm in MANUAL" in bar.text)
            app.simulate_key("2")
            await until(pilot, lambda: "3/3 Disarm" in bar.text)
            app.simulate_key("0")
            await until(pilot, lambda: isinstance(app.screen, SummaryScreen)
                        and bool(app.screen.query("#summary-head")))
            score = app.screen.result.score
            await until(pilot, lambda: app.model.radio_up)
        rec.close()
        return {"link": sim.link, "port": sim.port, "score": score, "radio": app.model.radio_up,
                "platform": sys.platform, "recording": str(rec.path)}
    finally:
        await client.close()
        sim.stop()


if __name__ == "__main__":
    print(json.dumps(asyncio.run(fly(Path(sys.argv[1])))), flush=True)
