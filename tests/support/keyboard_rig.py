"""A keyboard pilot hovering in FULL on the simulated board (bench/keyboard.py describes it and gives the figures;
tests/ui/test_keyboard_flight.py uses it)."""

from __future__ import annotations

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.world.physics import World
from term.core.link import LinkSession
from term.core.protocol import LIFT_FINE_DIVISOR, LIFT_FINE_FROM, LIFT_FINE_TO, Joystick, Mode, Op, scaled
from term.session.model import Model

TARGET_M = 1.0
LOOK_HZ = 5.0  # how often the pilot looks and may press
# What one press does, as a pilot learns it: 1 % of lift near a hover at about half lift is 4 % of the thrust; in the
# fine band near hover (the protocol's LIFT_FINE_*) a press is a quarter of that.
PRESS_ACCEL = 0.4  # m/s² per press of trim.lift_step
HOLD_S = 30.0
GOAL_M = 0.3  # issue 22: within ±0.3 m of 1 m for the 30 s
EYES = ("room", "screen")  # what the pilot reads the height from (keyboard_hover)


def keyboard_hover(seed: int, seconds: float = 60.0, lift_step: int | None = None,
                   eyes: str = "room") -> tuple[list[tuple[float, float]], int]:
    """Fly; returns (time, true height) at every look while in FULL, and the number of key presses.

    ``eyes`` "room": the pilot watches the craft, as the room view of ``term --sim`` shows it (its height to 0.01 m;
    its vertical speed from two looks); "screen": the Height telemetry (the board's estimate and its vz)."""
    board = Board(BoardConfig(seed=seed), world=World(seed))
    if lift_step is not None:
        board.modes.config.lift_step = lift_step
    session = LinkSession(0.0)
    model = Model(start=0.0)
    board.uart_receive(session.hello())
    session.set_joystick(Joystick(0, 0, 0, 0, 0))  # no stick: the keyboard alone
    track: list[tuple[float, float]] = []
    presses = 0
    vz_before = h_before = 0.0
    airborne = False
    t_us, next_look = 0, 0.0
    script = [(0.3, Mode.CALIBRATION), (2.0, Mode.FULL)]
    while t_us < seconds * 1e6:
        t_us += 1000
        t = t_us / 1e6
        if script and t >= script[0][0]:
            session.send_command(Op.MODE, script.pop(0)[1], t)
        if model.mode == Mode.FULL and model.height is not None and t >= next_look:
            next_look = t + 1 / LOOK_HZ
            if eyes == "room":
                h = round(board.world.truth.h, 2)
                vz, h_before = (h - h_before) * LOOK_HZ, h
            else:
                h, vz = scaled(model.height, "height"), scaled(model.height, "vz")
            accel, vz_before = (vz - vz_before) * LOOK_HZ, vz
            want_vz = max(-0.3, min(0.3, 0.6 * (TARGET_M - h)))
            lift = model.status.trim_lift if model.status is not None else 0  # the lift the screen shows
            press = PRESS_ACCEL / LIFT_FINE_DIVISOR if LIFT_FINE_FROM <= lift < LIFT_FINE_TO else PRESS_ACCEL
            n = round((1.2 * (want_vz - vz) - accel) / press)
            if not airborne and h < 0.05:
                n = 3  # on the ground: the key held until it lifts
            airborne = airborne or h > 0.3
            most = 3 if abs(TARGET_M - h) > 0.5 else 1
            for _ in range(min(most, abs(n))):
                session.send_command(Op.TRIM_LIFT, 1 if n > 0 else -1, t)
                presses += 1
            track.append((t, board.world.truth.h))
        board.advance(t_us)
        for ev in session.receive(board.uart_transmit(), t) + session.poll(t):
            model.apply(ev, t)
        board.uart_receive(session.data_to_send(t))
    if model.mode != Mode.FULL:
        raise RuntimeError(f"seed {seed}: left FULL: {[e.text for e in model.events][-5:]}")
    return track, presses


def hold_deviation(track: list[tuple[float, float]]) -> float:
    """The worst |true height - 1 m| over the 30 s hold (inf if the flight never got there or ended too early)."""
    reached = next((t for t, h in track if abs(h - TARGET_M) < 0.1), None)
    if reached is None or track[-1][0] < reached + 3.0 + HOLD_S:
        return float("inf")
    return max(abs(h - TARGET_M) for t, h in track if reached + 3.0 <= t <= reached + 3.0 + HOLD_S)
