"""Flight quality in the simulator: hover attitude RMS and height-hold RMS. Prints JSON; the last line is one
object.

- ``hover_attitude_rms_deg``: FULL mode (DMP path), still air, true tilt error over t >= 6 s (goal <= 1 deg);
  ``raw_hover_attitude_rms_deg``: the same in RAW mode on the on-board filter (estimation.BEST).
- ``height_hold_rms_m``: HEIGHT mode with the noisy, drifting, spiky barometer (params.py: 1.2 Pa rms, random
  walk 0.1 Pa/sqrt(s), spikes of 4-15 Pa at 0.1 per second), true height against the height HEIGHT was entered
  at, over t >= 6 s (goal <= 0.10 m), on the board's height estimator (estimation/height.py HEIGHT_BEST) and
  gains; ``height_hold_worst_seed_m`` the worst seed, ``height_hold_seeds_over_goal`` how many exceed 0.10 m.
  ``height_hold_no_spikes_rms_m`` is the same flight with the spikes switched off, to separate what the spikes
  cost; ``height_hold_complementary_rms_m`` (and its worst seed) the report's Figure 10 estimator on its own
  gains (P 120 / D 320, no integral), the baseline.
- ``height_flight_rms_m`` (mean over seeds), ``height_touchdown_err_m`` and ``height_ground_drift_m`` (worst
  seed): the height-profile scenario (climb, hold at 2, 10 and 30 m, land, 30 s on the ground), the estimate
  against the true height in flight, from 5 s after touch-down on, and its movement on the ground (goals 0.15,
  0.2, 0.05 m).
- ``throw_estimate_rms_deg`` / ``raw_throw_estimate_rms_deg`` (and ``_fixed``): the roll stick thrown side to side
  (+-20 deg every 0.6 s) in FULL and in RAW (float and fixed-point on-board filter): the attitude the control loop
  flies on against the simulator's truth (goal for RAW <= 1 deg; issue 12), with the worst seed.

- ``report_*``: the same flights on the report's board (the "report" preset, docs/parameters.md: Table 1's gains,
  the complementary filter with K_gyro 0.999, the Figure 10 height estimator on its PD gains): hover in FULL
  (``report_hover_attitude_rms_deg``), in RAW on the report's filter (``report_raw_hover_attitude_rms_deg``) and
  HEIGHT on the Figure 10 estimator (``report_height_hold_rms_m``), beside the default preset's figures above.

Each figure is the mean over ``--seeds`` seeds (1..N) of ``--seconds`` simulated seconds (the per-seed values are
printed too). Run: ``python -m bench.flight [--seconds S] [--seeds N]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from fcb_sim.board.flight import FlightCore
from fcb_sim.board.param_bindings import preset_core
from fcb_sim.estimation import BEST
from fcb_sim.estimation.height import HEIGHT_BEST, make_height_estimator
from fcb_sim.lab.scenarios import Sim, fly_core, height_profile, hover, raw_hover, raw_throw, throw
from fcb_sim.lab.scenarios import height_hold as height_hold_scenario
from fcb_sim.world import constants as P
from term.core.protocol import Mode

GOAL_HEIGHT_M = 0.10


def height_hold(seed: int, seconds: float, spikes: bool = True, estimator: str = HEIGHT_BEST) -> float:
    core = None
    if estimator != HEIGHT_BEST:
        # the baseline flies on the gains it was tuned for
        core = FlightCore(gains=P.Gains(height_p=120.0, height_d=320.0),
                          height_estimator=make_height_estimator(estimator))
        core.height_i = 0.0
    sim = Sim(seed, world_kw={"baro_spikes": spikes}, core=core)
    return height_hold_scenario(seed, seconds, sim)["height_rms_m"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated seconds per flight (default 30)")
    ap.add_argument("--seeds", type=int, default=8, help="number of seeds (default 8)")
    args = ap.parse_args()
    seeds = list(range(1, args.seeds + 1))
    t0 = time.perf_counter()
    runs = {
        "hover_attitude_rms_deg": [hover(s, args.seconds)["attitude_rms_deg"] for s in seeds],
        "raw_hover_attitude_rms_deg": [raw_hover(s, args.seconds)["attitude_rms_deg"] for s in seeds],
        "height_hold_rms_m": [height_hold(s, args.seconds) for s in seeds],
        "height_hold_no_spikes_rms_m": [height_hold(s, args.seconds, spikes=False) for s in seeds],
        "height_hold_complementary_rms_m": [height_hold(s, args.seconds, estimator="complementary")
                                            for s in seeds],
        "throw_estimate_rms_deg": [throw(s, args.seconds)["estimate_rms_deg"] for s in seeds],
        "raw_throw_estimate_rms_deg": [raw_throw(s, args.seconds)["estimate_rms_deg"] for s in seeds],
        "raw_throw_fixed_estimate_rms_deg": [raw_throw(s, args.seconds, fixed_point=True)["estimate_rms_deg"]
                                             for s in seeds],
        # the report's board (preset "report"), the same flights
        "report_hover_attitude_rms_deg": [fly_core(s, args.seconds, preset_core("report"))["attitude_rms_deg"]
                                          for s in seeds],
        "report_raw_hover_attitude_rms_deg": [
            fly_core(s, args.seconds, preset_core("report"), Mode.RAW)["attitude_rms_deg"] for s in seeds],
        "report_height_hold_rms_m": [
            height_hold_scenario(s, args.seconds, Sim(s, core=preset_core("report")))["height_rms_m"] for s in seeds],
    }
    for name, values in runs.items():
        print(json.dumps({"metric": name, "per_seed": [round(v, 4) for v in values]}))
    result: dict[str, object] = {name: statistics.mean(values) for name, values in runs.items()}
    height = runs["height_hold_rms_m"]
    # Issue 10.3: climb, hold at 2, 10 and 30 m, land, 30 s on the ground; the estimate against the truth.
    profiles = [height_profile(s) for s in seeds]
    for key in ("height_flight_rms_m", "height_touchdown_err_m", "height_ground_drift_m"):
        print(json.dumps({"metric": key, "per_seed": [round(p[key], 4) for p in profiles]}))
    result.update({
        "height_flight_rms_m": statistics.mean(p["height_flight_rms_m"] for p in profiles),
        "height_touchdown_err_m": max(p["height_touchdown_err_m"] for p in profiles),  # worst seed
        "height_ground_drift_m": max(p["height_ground_drift_m"] for p in profiles),  # worst seed
        "goal_height_flight_rms_m": 0.15, "goal_height_touchdown_err_m": 0.2, "goal_height_ground_drift_m": 0.05,
    })
    result.update({
        "hover_attitude_max_seed_deg": max(runs["hover_attitude_rms_deg"]),
        "height_hold_worst_seed_m": max(height),
        "height_hold_max_seed_m": max(height),  # the same, the name earlier runs printed
        "height_hold_seeds_over_goal": sum(v > GOAL_HEIGHT_M for v in height),
        "height_hold_complementary_worst_seed_m": max(runs["height_hold_complementary_rms_m"]),
        "goal_hover_attitude_rms_deg": 1.0,
        "raw_throw_estimate_worst_seed_deg": max(runs["raw_throw_estimate_rms_deg"]),
        "goal_raw_throw_estimate_rms_deg": 1.0,
        "goal_height_hold_rms_m": GOAL_HEIGHT_M,
        "report_height_hold_worst_seed_m": max(runs["report_height_hold_rms_m"]),
        "raw_filter": BEST,
        "height_estimator": HEIGHT_BEST,
        "seeds": seeds,
        "sim_seconds_per_flight": args.seconds,
        "wall_seconds": time.perf_counter() - t0,
    })
    print(json.dumps(result))


if __name__ == "__main__":
    main()
