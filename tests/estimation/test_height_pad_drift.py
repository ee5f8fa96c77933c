"""The height estimate in the interactive flight (issue 22: on the pad -0.33 m; in a climb -0.07 m at a true 0.45 m)
against bench.flight's: the difference is the wait. bench.flight calibrates and takes off within two seconds; a
pilot at term --sim calibrates and then sits on the pad for minutes. The barometer drifts (a random walk of
BARO_DRIFT_PA = 0.1 Pa/sqrt(s): about 2.5 Pa, 0.2 m, in ten minutes), the reference pressure is the calibration's,
and on the ground the estimator holds its height instead of following the drift; at lift-off the barometer's
drifted reading pulls the estimate off by the whole drift. Measured with the keyboard rig's pilot (seed 1, the
estimate against the truth in FULL above 0.3 m): calibrate and take off after 2 s, mean error +0.03 m; after 600 s
on the pad, -0.51 m.

Here the drift of a long wait is put into the barometer at once (6 Pa, what ten minutes give at 2.5 sigma), so the
test runs in seconds. The fix (fcb_sim/estimation/height.py): while the craft stands anchored the estimator follows
the barometer's drift slowly, and at lift-off the reference pressure takes it out. (The C board's twin does not
yet: firmware/ is not this change's.)"""

from __future__ import annotations

import statistics

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.world.physics import World
from term.core.link import LinkSession
from term.core.protocol import Joystick, Mode, Op, scaled
from term.session.model import Model

DRIFT_PA = 6.0


def climb_error(drift_pa: float, seed: int = 1) -> float:
    """Calibrate, let the barometer drift ``drift_pa`` while on the pad in SAFE, then FULL and climb to about
    0.5 m with the stick; the mean (estimate - truth) above 0.3 m."""
    board = Board(BoardConfig(seed=seed), world=World(seed))
    session = LinkSession(0.0)
    model = Model(start=0.0)
    board.uart_receive(session.hello())
    session.set_joystick(Joystick(0, 0, 0, 0, 0))
    script = [(0.3, lambda t: session.send_command(Op.MODE, Mode.CALIBRATION, t)),
              (4.0, lambda t: setattr(board.world.baro_model, "drift", board.world.baro_model.drift + drift_pa)),
              (15.0, lambda t: session.send_command(Op.MODE, Mode.FULL, t))]
    base, errs, next_pilot = 15000.0, [], 15.5
    t_us = 0
    while t_us < 32e6:
        t_us += 1000
        t = t_us / 1e6
        while script and script[0][0] <= t:
            script.pop(0)[1](t)
        if t >= next_pilot and model.height is not None and model.mode == Mode.FULL:
            next_pilot += 0.05
            h, vz = board.world.truth.h, -board.world.truth.vd  # flown by the truth: only the estimate is judged
            base += 40 * (0.5 - h)
            session.set_joystick(Joystick(0, 0, 0, max(0, min(32767, int(base + 4000 * (0.5 - h) - 3000 * vz))), 0))
            if board.world.truth.h > 0.3:
                errs.append(board.core.height - board.world.truth.h)
        board.advance(t_us)
        for ev in session.receive(board.uart_transmit(), t) + session.poll(t):
            model.apply(ev, t)
        board.uart_receive(session.data_to_send(t))
    assert len(errs) > 50, "never climbed"
    assert scaled(model.height, "height") is not None
    return statistics.fmean(errs)


def test_without_a_wait_the_climb_reads_true() -> None:
    assert abs(climb_error(0.0)) < 0.15


def test_after_a_long_wait_on_the_pad_the_climb_still_reads_true() -> None:
    assert abs(climb_error(DRIFT_PA)) < 0.15
