"""Keyboard flying (issues 13 and 22): a scripted keyboard pilot hovers in FULL with the lift keys alone (a and z,
each a ``TRIM_LIFT`` command of one press: ``trim.lift_step`` stick units, 1 %, or a quarter of it near hover, in
40-60 % of lift: the protocol's ``lift_trim_after``) and holds 1 m; how far it strays over 30 s.

The pilot is a person at the keyboard: it looks five times a second and presses a or z once per look, three times
while far from the height it wants or still on the ground (a held key); it knows what a press does where the lift
is (0.4 m/s² of thrust, 0.1 in the fine band). What it looks at, ``--eyes``:

- ``room`` (the default): the craft, as ``term --sim``'s room view shows it (the height to 0.01 m; the vertical
  speed from two looks), as a pilot in the lab watches the quadcopter;
- ``screen``: the Height telemetry, the board's estimate and its vz, through term's own LinkSession and Model.

The board is fcb_sim's sans-IO Board on a simulated clock, so a seed flies the same every run. The hold is judged
on the simulator's true height, from 3 s after the craft first came within 0.1 m of 1 m, for 30 s; the goal is
±0.3 m (``GOAL_M``).

    python -m bench.keyboard [--seeds 8] [--first-seed 1] [--eyes room|screen] [--lift-step 328]
                             [--thrust-model on|off]

``--thrust-model off`` flies the height estimator without its thrust model (on on both boards: docs/height.md "The
thrust model"); ``--first-seed 101`` flies the seeds it was tuned on (101-108), not the ones it is scored on.

Prints per seed the worst deviation (m) and the presses, then one JSON object: ``keyboard_hold_worst_m`` (the worst
seed), ``keyboard_hold_mean_m`` (mean over seeds of each one's worst), ``seeds_within_goal`` (of ``seeds``) and
``keyboard_presses_mean``.

The figures behind the finer step and the room's eyes (seeds 1-8, this pilot; seeds within 0.3 m, the worst
seed's deviation, the mean of each seed's worst; the 1 % step everywhere is the board before issue 22):

| the pilot reads | 1 % everywhere | ¼ % near hover (now) |
|---|---|---|
| the craft, exactly (true height and vz) | 8 of 8, 0.253 m, 0.246 m | 8 of 8, 0.066 m, 0.054 m |
| the room view (0.01 m, vz from two looks) | 8 of 8, 0.166 m, 0.128 m | 8 of 8, 0.191 m, 0.110 m |
| the screen's height estimate | 1 of 8, 0.895 m, 0.465 m | 0 of 8, 2.50 m, 1.00 m |
| the screen, after issue 35's contact work | | 0 of 8, 1.05 m, 0.72 m |
| the screen, issue 35's first thrust model (an experiment, off on the boards then) | | 1 of 8, 1.30 m, 0.62 m |
| the same, seeds 101-108 (tuned on; off there: 0 of 8, 0.62 m, 0.48 m) | | 6 of 8, 0.44 m, 0.27 m |
| the screen, the thrust model with the legs (now, both boards; off: the contact row) | | 7 of 8, 0.353 m, 0.205 m |
| the same, seeds 101-108 (tuned on) | | 8 of 8, 0.280 m, 0.208 m |
| the same, seeds 109-116 (neither tuned nor scored on) | | 6 of 8, 0.487 m, 0.275 m |

What limits the hold is what the pilot reads, more than the step: a pilot who sees the craft holds 0.3 m with
either step, and the finer step takes the exact pilot's limit cycle from 0.25 m to 0.06 m (a 1 % press is 4 % of
the thrust at hover: the "climbs and accelerates" of issue 22). With the screen's eyes no step holds 0.3 m: the
estimate strays from the truth (its vz has a noise of 0.08-0.13 m/s at 5 Hz; seed 8's barometer drifts 0.25 m
below the truth for the whole flight) and the pilot follows it; one press per look of the finer step corrects too
slowly for that noise (1 of 8 -> 0 of 8). That is the height estimate's part of issue 22 ("the height estimate
right on the pad and in the climb"), not the keys'. The estimate's vz is what misleads: the screen's figures with
the vz error halved hold 7 of 8 of seeds 101-108, with the height error halved 0 of 8. The thrust model (the motors'
commands predict the acceleration, docs/height.md "The thrust model") takes vz at hover from 0.083 to 0.057 m/s rms
with less lag, which held 6 of the 8 seeds it was tuned on but only 1 of seeds 1-8. What did not generalise was
the take-off, not the hover: every seed flies the same craft, motors and pack (fcb_sim/world: only the sensors'
offsets, noise, drift and spikes differ per seed), and the pilot holds the key while the screen reads under 0.05 m.
With the motors running on the pad the first model integrated the accelerometer's vibration (the estimate wandered
to -0.1 m while the craft sat still) and, once off the floor, lagged the climb, so the lift overshot and the craft
climbed past 2 m before the hold began; whether it did was luck of the seed. Now (docs/height.md "The thrust model")
the legs carry the estimate at the floor until the modelled thrust, scaled by the pack's voltage, passes the weight,
the climb is integrated from the floor at once, the airframe's drag is in the model, and a force the model does not
know is the accelerometer's without resetting the gain: 7 of 8 on seeds 1-8 (seed 5: 0.35 m, its barometer
reading 0.15-0.2 m high after the take-off), issue 35's goal met.
"""

from __future__ import annotations

import argparse
import json
import statistics

import fcb_sim.estimation.height as height_module
from tests.support.keyboard_rig import EYES, GOAL_M, HOLD_S, hold_deviation, keyboard_hover


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--eyes", choices=EYES, default="room", help="what the pilot reads the height from")
    ap.add_argument("--lift-step", type=int, default=None, help="stick units per press (default: the board's)")
    ap.add_argument("--first-seed", type=int, default=1, help="the first seed (101: the thrust model's tuning set)")
    ap.add_argument("--thrust-model", choices=("on", "off"), default="on",
                    help="the height estimator's thrust model (on: the boards' default)")
    args = ap.parse_args()
    height_module.THRUST_MODEL = args.thrust_model == "on"
    worst, presses = [], []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        track, n = keyboard_hover(seed, lift_step=args.lift_step, eyes=args.eyes)
        worst.append(hold_deviation(track))
        presses.append(n)
        print(json.dumps({"seed": seed, "worst_m": _num(worst[-1]), "presses": n}))
    print(json.dumps({"keyboard_hold_worst_m": _num(max(worst)),
                      "keyboard_hold_mean_m": _num(statistics.fmean(worst)),
                      "seeds_within_goal": sum(w <= GOAL_M for w in worst),
                      "keyboard_presses_mean": round(statistics.fmean(presses), 1),
                      "goal_hold_m": GOAL_M, "hold_s": HOLD_S, "seeds": args.seeds, "eyes": args.eyes,
                      "lift_step": args.lift_step, "first_seed": args.first_seed,
                      "thrust_model": args.thrust_model}))


def _num(x: float) -> float | None:
    return round(x, 3) if x != float("inf") else None  # JSON has no infinity: null, the hold never came


if __name__ == "__main__":
    main()
