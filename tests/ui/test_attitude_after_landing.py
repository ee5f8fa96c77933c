"""The attitude on screen follows the craft in SAFE (issue 22): a flight that ends tilted (a dead motor flips the
craft, it crashes, the board goes to SAFE) leaves it standing level on its legs, and the Attitude telemetry must
say so within the filter's accuracy, not keep the last flight angles. The flight core kept the angles of its last
flight-mode step in SAFE (the Python board and the C board alike); only the lesson reset put them back.

Both boards fly fcb_sim's World on a simulated clock; the telemetry goes through term's LinkSession and Model."""

from __future__ import annotations

import math
import shutil

import pytest

from fcb_sim.board.board import Board
from fcb_sim.board.parts import BoardConfig
from fcb_sim.world.physics import World
from term.core.link import LinkSession
from term.core.protocol import Joystick, Mode, Op, scaled
from term.session.model import Model

ACCURACY_CDEG = 200  # 2°: the DMP's error on a still craft is a fraction of that


def _board(kind: str, seed: int) -> Board:
    if kind == "c":
        if shutil.which("cc") is None or shutil.which("make") is None:
            pytest.skip("no C compiler (cc) or make")
        from fcb_sim.hosts.cboard import CBoard

        return CBoard(BoardConfig(seed=seed), world=World(seed))  # type: ignore[return-value]
    return Board(BoardConfig(seed=seed), world=World(seed))


@pytest.mark.parametrize("kind", ["python", "c"])
def test_after_a_tilted_crash_the_attitude_in_safe_follows_the_craft_on_the_pad(kind: str) -> None:
    board = _board(kind, seed=3)
    s, model = LinkSession(0.0), Model(start=0.0)
    board.uart_receive(s.hello())
    base, t, k = 15000.0, 0.0, 0
    seen_tilt = 0.0

    def step() -> None:
        nonlocal t, k
        k += 1
        t = k * 0.002
        board.advance(k * 2000)
        for ev in s.receive(board.uart_transmit(), t) + s.poll(t):
            model.apply(ev, t)
        board.uart_receive(s.data_to_send(t))

    while t < 6.0:  # calibrate, then hover in FULL at about 1 m (the lift stick on the true height)
        if k == 100:
            s.send_command(Op.MODE, Mode.CALIBRATION, t)
        elif k == 700:
            s.send_command(Op.MODE, Mode.FULL, t)
        if k > 800 and k % 10 == 0:
            tr = board.world.truth
            base += 20 * (1.0 - tr.h)
            s.set_joystick(Joystick(0, 0, 0, max(0, min(32767, int(base + 4000 * (1.0 - tr.h) + 3000 * tr.vd))), 0))
        step()
    assert board.mode == Mode.FULL and board.world.truth.h > 0.5
    board.world.stick_motor(2, 0)  # a dead motor: the craft rolls over and hits the floor
    while t < 12.0 and not (board.mode == Mode.SAFE and board.world.on_ground):
        step()
        if model.attitude is not None:
            seen_tilt = max(seen_tilt, abs(scaled(model.attitude, "phi")), abs(scaled(model.attitude, "theta")))
    assert board.world.crashes and board.mode == Mode.SAFE
    assert seen_tilt > 20.0  # the screen saw the flight end tilted
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    end = t + 2.0
    while t < end:
        step()
    tr = board.world.truth
    assert board.mode == Mode.SAFE and board.world.on_ground
    assert model.attitude is not None
    for field, true in (("phi", tr.phi), ("theta", tr.theta)):
        shown = scaled(model.attitude, field)
        assert abs(shown - math.degrees(true)) < ACCURACY_CDEG / 100, (field, shown, math.degrees(true))
