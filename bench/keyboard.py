"""Keyboard flying (issue 13): a scripted keyboard pilot hovers in FULL with the lift keys alone (a and z, each a
``TRIM_LIFT`` command of ±1 step, ``trim.lift_step`` stick units) and holds 1 m; how far it strays over 30 s.

The pilot is a person at the keyboard: it reads the height and the vertical speed the screen shows (the Height
telemetry through term's own LinkSession and Model), at most five times a second, and presses a or z once per look,
three times while far from the height it wants or still on the ground (a held key). The board is fcb_sim's sans-IO
Board on a simulated clock, so a seed flies the same every run. The hold is judged on the simulator's true height,
from 3 s after the craft first came within 0.1 m of 1 m, for 30 s.

    python -m bench.keyboard [--seeds 8] [--lift-step 328]

Prints per seed the worst deviation (m) and the presses, then one JSON object: ``keyboard_hold_worst_m`` (the worst
seed), ``keyboard_hold_mean_m`` (mean over seeds of each one's worst) and ``keyboard_presses_mean``.
"""

from __future__ import annotations

import argparse
import json
import statistics

from fcb_sim.board import Board, BoardConfig
from fcb_sim.physics import World
from term.core.link import LinkSession
from term.core.protocol import Joystick, Mode, Op, scaled
from term.session.model import Model

TARGET_M = 1.0
LOOK_HZ = 5.0  # how often the pilot reads the screen and may press
# What one press does, as a pilot learns it: 1 % of lift near a hover at about half lift is 4 % of the thrust.
PRESS_ACCEL = 0.4  # m/s² per press
HOLD_S = 30.0


def keyboard_hover(seed: int, seconds: float = 60.0, lift_step: int | None = None) -> tuple[list[tuple[float, float]],
                                                                                         int]:
    """Fly; returns (time, true height) at every look while in FULL, and the number of key presses."""
    board = Board(BoardConfig(seed=seed), world=World(seed))
    if lift_step is not None:
        board.modes.config.lift_step = lift_step
    session = LinkSession(0.0)
    model = Model(start=0.0)
    board.uart_receive(session.hello())
    session.set_joystick(Joystick(0, 0, 0, 0, 0))  # no stick: the keyboard alone
    track: list[tuple[float, float]] = []
    presses = 0
    vz_before = 0.0
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
            h, vz = scaled(model.height, "height"), scaled(model.height, "vz")
            accel, vz_before = (vz - vz_before) * LOOK_HZ, vz
            want_vz = max(-0.3, min(0.3, 0.6 * (TARGET_M - h)))
            n = round((1.2 * (want_vz - vz) - accel) / PRESS_ACCEL)
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--lift-step", type=int, default=None, help="stick units per press (default: the board's)")
    args = ap.parse_args()
    worst, presses = [], []
    for seed in range(1, args.seeds + 1):
        track, n = keyboard_hover(seed, lift_step=args.lift_step)
        worst.append(hold_deviation(track))
        presses.append(n)
        print(json.dumps({"seed": seed, "worst_m": _num(worst[-1]), "presses": n}))
    print(json.dumps({"keyboard_hold_worst_m": _num(max(worst)),
                      "keyboard_hold_mean_m": _num(statistics.fmean(worst)),
                      "seeds_within_goal": sum(w <= 0.5 for w in worst),
                      "keyboard_presses_mean": round(statistics.fmean(presses), 1),
                      "goal_hold_m": 0.5, "hold_s": HOLD_S, "seeds": args.seeds, "lift_step": args.lift_step}))


def _num(x: float) -> float | None:
    return round(x, 3) if x != float("inf") else None  # JSON has no infinity: null, the hold never came


if __name__ == "__main__":
    main()
