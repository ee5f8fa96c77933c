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

from tests.support.keyboard_rig import HOLD_S, hold_deviation, keyboard_hover


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
