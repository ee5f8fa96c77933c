"""Snapshot tests (pytest-textual-snapshot) of the screens, fed by a seeded board: fcb_sim's sans-IO Board and
term's own LinkSession exchange bytes on a simulated clock (no wall clock anywhere), so the same seed always gives
the same screen. Update after a deliberate change with `pytest tests/test_app_snapshot.py --snapshot-update`
and look at the SVGs in tests/__snapshots__/."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from term.core.link import LinkSession
from term.core.protocol import Joystick, Mode, Op, scaled
from term.session.model import Model
from term.ui.app import TermApp

SIZE = (120, 44)


def seeded_flight(seed: int = 1, seconds: float = 5.0) -> tuple[Model, float]:
    """Fly the seeded board through a LinkSession on a simulated clock: calibrate, FULL, lift off with some
    roll, one refused command; returns the model the screen renders and the end time."""
    from fcb_sim.board.board import Board, BoardConfig
    from fcb_sim.world.physics import World

    board = Board(BoardConfig(seed=seed), world=World(seed))
    session = LinkSession(0.0)
    model = Model(start=0.0)
    model.link_name = "seeded board (simulated clock)"
    board.uart_receive(session.hello())
    script: list[tuple[float, Callable[[float], None]]] = [
        (0.3, lambda t: session.send_command(Op.MODE, Mode.FULL, t)),  # refused: not calibrated
        (0.5, lambda t: session.send_command(Op.MODE, Mode.CALIBRATION, t)),
        (2.0, lambda t: session.send_command(Op.MODE, Mode.FULL, t)),
        (2.2, lambda t: session.send_command(Op.LOG_START, 0, t)),
        (4.2, lambda t: session.send_command(Op.GAIN_P2, 1, t)),
        (4.6, lambda t: session.send_command(Op.PROFILE, 0, t)),
    ]
    # From 2.5 s the pilot holds 0.5 m with the lift stick (as tests/test_app_flight.py does), 20 times a second,
    # with a little right roll and nose down from 4 s.
    base = 15000.0
    next_pilot = 2.5
    session.set_joystick(Joystick(0, 0, 0, 0, 0))
    step_us = 1000
    t_us = 0
    while t_us < seconds * 1e6:
        t_us += step_us
        t = t_us / 1e6
        while script and script[0][0] <= t:
            script.pop(0)[1](t)
        if t >= next_pilot and model.height is not None:
            next_pilot += 0.05
            h, vz = scaled(model.height, "height"), scaled(model.height, "vz")
            base += 40 * (0.5 - h)
            lift = max(0, min(32767, int(base + 4000 * (0.5 - h) - 3000 * vz)))
            session.set_joystick(Joystick(2500, -1500, 0, lift, 0) if t >= 4.0 else Joystick(0, 0, 0, lift, 0))
        board.advance(t_us)
        for ev in session.receive(board.uart_transmit(), t) + session.poll(t):
            model.apply(ev, t)
        board.uart_receive(session.data_to_send(t))
    model.set_stick(session._js or Joystick(0, 0, 0, 0, 0))
    model.set_link_stats(session.stats_at(t_us / 1e6), t_us / 1e6)
    return model, t_us / 1e6


@pytest.fixture(scope="module")
def flight() -> tuple[Model, float]:
    return seeded_flight()


def app_for(flight: tuple[Model, float]) -> TermApp:
    model, end = flight
    app = TermApp(joystick=False, clock=lambda: end)
    app.model = model
    return app


def test_the_seeded_flight_is_what_the_screen_claims(flight: tuple[Model, float]) -> None:
    model, _ = flight
    assert model.mode == Mode.FULL
    assert model.motion is not None and model.motion.ae1 > 300
    assert any(e.source == "nak" and "not calibrated" in e.text for e in model.events)
    assert model.link is not None and model.link.frames_bad == 0 and model.link.rtt_mean_ms is not None


def test_profile_task_names_match_the_board() -> None:
    from fcb_sim.board.scheduler import TASKS
    from term.ui.widgets.profile import TASK_NAMES

    assert tuple(TASK_NAMES[i] for i in range(len(TASK_NAMES))) == TASKS


def test_snapshot_main_screen(snap_compare, flight) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flight), terminal_size=SIZE)


def test_snapshot_help(snap_compare, flight) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flight), press=["f1"], terminal_size=SIZE)


def test_snapshot_profile(snap_compare, flight) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flight), press=["f9"], terminal_size=SIZE)


def test_snapshot_panic_is_unmistakable(snap_compare, flight) -> None:  # noqa: ANN001
    from term.core.protocol import Attitude

    model, end = flight
    app = app_for(flight)

    def panic(pilot) -> None:  # noqa: ANN001
        a = model.attitude
        app.model.apply_packet(Attitude(Mode.PANIC, a.phi, a.theta, a.psi, a.sp, a.sq, a.sr), end)
        app.render_now()

    assert snap_compare(app, terminal_size=SIZE, run_before=panic)
    model.apply_packet(Attitude(Mode.FULL, *model.attitude[1:]), end)  # the shared flight back as it was
