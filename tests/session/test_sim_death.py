"""When the simulated board's child dies, term says so: its exit status and the last line of its log, never "check
the cable" (issue 36). A real `fcb-sim serve` child over each link (pty, TCP), term's transport to it, a real kill;
then the same through the app, where the words reach LINK LOST's event line."""

from __future__ import annotations

import asyncio
import os
import signal
import sys

import pytest

from term.core.protocol import Mode
from term.session.sim import SimBoard, pty_missing
from term.transports.base import TransportError

LINKS = ["tcp"] + ([] if pty_missing() else ["pty"])


@pytest.mark.skipif(sys.platform == "win32", reason="kills with SIGKILL")
@pytest.mark.parametrize("link", LINKS)
async def test_a_dead_child_is_named_with_its_status_and_its_last_words(link: str) -> None:
    sim = SimBoard(link=link, extra=["-v"])  # -v: the child logs, so its log has a last line
    sim.start()
    transport = sim.transport(115200)
    try:
        await transport.open()
        assert await asyncio.wait_for(transport.read(), 10)  # the board speaks
        assert sim.proc is not None
        os.kill(sim.proc.pid, signal.SIGKILL)
        with pytest.raises(TransportError) as err:
            async with asyncio.timeout(10):
                while True:
                    await transport.read()
        text = str(err.value)
        assert text.startswith("the simulated board stopped (killed by SIGKILL); its log"), text
        if link == "tcp":  # (-v logs the client's arrival; over a pty the log has nothing to say)
            assert "its log's last line: " in text and "TCP client" in text, text
        assert "check the cable" not in text and "\n" not in text
        await transport.close()
        with pytest.raises(TransportError, match="the simulated board stopped"):  # a reconnect says it again
            await transport.open()
    finally:
        await transport.close()
        sim.stop()


async def test_the_app_says_link_lost_because_the_simulator_stopped() -> None:
    from term.ui.app import TermApp

    sim = SimBoard(link="tcp")
    sim.start()
    app = TermApp(sim.transport(115200), joystick=False)
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            async with asyncio.timeout(20):
                while app.model.mode != Mode.SAFE:
                    await pilot.pause(0.05)
            assert sim.proc is not None
            sim.proc.terminate()  # (SIGTERM: a clean exit, status 0)
            async with asyncio.timeout(20):
                while not any("the simulated board stopped" in e.text for e in app.model.events):
                    await pilot.pause(0.05)
            line = next(e.text for e in app.model.events if "the simulated board stopped" in e.text)
            assert "exit status 0" in line and "check the cable" not in line
    finally:
        sim.stop()
