"""Flight quality in the simulator: hover attitude RMS and height-hold RMS. Prints JSON; the last line is one
object.

- ``hover_attitude_rms_deg``: FULL mode (DMP path), still air, true tilt error over t >= 6 s (goal <= 1 deg);
  ``raw_hover_attitude_rms_deg``: the same in RAW mode on the on-board filter (estimation.BEST).
- ``height_hold_rms_m``: HEIGHT mode with the noisy, drifting, spiky barometer (params.py: 1.2 Pa rms, random
  walk 0.1 Pa/sqrt(s), spikes of 4-15 Pa at 0.1 per second), true height against the held height over
  t >= 6 s (goal <= 0.10 m); ``height_hold_no_spikes_rms_m`` is the same flight with the spikes switched off,
  to separate what the spikes cost.

Each figure is the mean over ``--seeds`` seeds of ``--seconds`` simulated seconds (the per-seed values are
printed too). Run: ``python -m bench.flight [--seconds S] [--seeds N]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from fcb_sim.estimation import BEST
from fcb_sim.scenarios import ACTION_AT, Recorder, Sim, hover, raw_hover
from term.protocol import Mode


def height_hold(seed: int, seconds: float, spikes: bool) -> float:
    sim = Sim(seed, world_kw={"baro_spikes": spikes})
    rec = Recorder(ACTION_AT)
    sim.on_tick = rec
    sim.prologue()
    sim.run_until(5.0)
    sim.pilot_target = None
    rec.h_ref = -sim.world.d
    sim.set_mode(Mode.HEIGHT)
    sim.run_until(seconds)
    return rec.metrics()["height_rms_m"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated seconds per flight (default 30)")
    ap.add_argument("--seeds", type=int, default=3, help="number of seeds (default 3)")
    args = ap.parse_args()
    seeds = list(range(1, args.seeds + 1))
    t0 = time.perf_counter()
    runs = {
        "hover_attitude_rms_deg": [hover(s, args.seconds)["attitude_rms_deg"] for s in seeds],
        "raw_hover_attitude_rms_deg": [raw_hover(s, args.seconds)["attitude_rms_deg"] for s in seeds],
        "height_hold_rms_m": [height_hold(s, args.seconds, True) for s in seeds],
        "height_hold_no_spikes_rms_m": [height_hold(s, args.seconds, False) for s in seeds],
    }
    for name, values in runs.items():
        print(json.dumps({"metric": name, "per_seed": [round(v, 4) for v in values]}))
    result = {name: statistics.mean(values) for name, values in runs.items()}
    result.update({
        "hover_attitude_max_seed_deg": max(runs["hover_attitude_rms_deg"]),
        "height_hold_max_seed_m": max(runs["height_hold_rms_m"]),
        "goal_hover_attitude_rms_deg": 1.0,
        "goal_height_hold_rms_m": 0.10,
        "raw_filter": BEST,
        "seeds": seeds,
        "sim_seconds_per_flight": args.seconds,
        "wall_seconds": time.perf_counter() - t0,
    })
    print(json.dumps(result))


if __name__ == "__main__":
    main()
