"""A flight through term's own app and link (TermApp, LinkSession, Connection, SerialTransport) against the board
served in real time by `fcb-sim serve --pty` in a child process (the same path as `term --sim`): calibrate,
take off in FULL, hover, land, SAFE. The pilot here is a small height loop on the telemetry the screen shows, timed
by the board's clock (its heartbeats): on a busy machine the simulator slips behind the wall clock and the test's
own loop runs late, and a pilot on the wall clock then climbed for less of the board's time than it meant
(make test-busy: 'did not take off', 0.30 m)."""

from __future__ import annotations

from term.core.events import FromLink
from term.core.protocol import Heartbeat, Joystick, Mode, scaled
from term.session.sim import SimBoard
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from tests.support.waits import until


async def test_take_off_hover_in_full_and_land() -> None:
    sim = SimBoard(seed=3)
    port = sim.start()
    try:
        app = TermApp(SerialTransport(port), joystick=False)
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model
            board_s = [0.0]  # the board's time, from its last heartbeat
            inner = app.station.on_event

            def tap(ev: object) -> None:
                if isinstance(ev, FromLink) and type(packet := getattr(ev.event, "packet", None)) is Heartbeat:
                    board_s[0] = packet.board_ms / 1e3
                inner(ev)  # type: ignore[misc]

            app.station.on_event = tap

            await until(pilot, lambda: m.mode == Mode.SAFE and m.height is not None)
            # Keys through simulate_key (a real key event): pilot.press would wait for the app to go idle, which a
            # board streaming telemetry delays by seconds.
            app.simulate_key("5")  # not calibrated yet: the board refuses, and the screen says why
            await until(pilot, lambda: any(e.source == "nak" and "not calibrated" in e.text for e in m.events))
            app.simulate_key("3")
            await until(pilot, lambda: any("calibration done" in e.text for e in m.events))
            await until(pilot, lambda: m.mode == Mode.SAFE)
            app.simulate_key("5")
            await until(pilot, lambda: m.mode == Mode.FULL)

            base, target = 15000.0, 0.5
            heights: list[tuple[float, float]] = []
            worst_tilt = 0.0
            t0 = last = board_s[0]
            while (t := board_s[0] - t0) < 7.0:
                h, vz = scaled(m.height, "height"), scaled(m.height, "vz")
                if t > 4.8:
                    target = -0.3  # land: below the floor, so the loop keeps easing off
                base += 800 * (target - h) * (board_s[0] - last)  # the integrator on the board's time
                last = board_s[0]
                lift = int(base + 4000 * (target - h) - 3000 * vz)
                app.set_stick(Joystick(0, 0, 0, max(0, min(32767, lift)), 0))
                heights.append((t, h))
                worst_tilt = max(worst_tilt, abs(m.attitude.phi) / 100, abs(m.attitude.theta) / 100)
                assert m.mode == Mode.FULL, [e.text for e in m.events][-5:]
                await pilot.pause(0.05)

            hover = [h for t, h in heights if 2.0 < t < 4.8]
            assert max(hover) > 0.3, "did not take off"
            assert sum(hover) / len(hover) > 0.2 and max(hover) < 1.5, hover
            assert worst_tilt < 5.0
            app.set_stick(Joystick(0, 0, 0, 0, 0))
            await until(pilot, lambda: m.motion.ae1 <= 200 and m.height.height < 150)  # on the floor, at idle
            app.simulate_key("0")
            await until(pilot, lambda: m.mode == Mode.SAFE and m.motion.ae1 == 0)
            assert not [e for e in m.events if e.source == "link" and e.severity == "error"]
            assert m.link is not None and m.link.frames_bad <= 1  # at most the half frame met at connect
    finally:
        sim.stop()
