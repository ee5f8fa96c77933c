"""The height figure and the heading where the pilot reads them (issue 35): contact and rest, over seeds.

Each seed flies the flight core (fcb_sim.lab.scenarios.Sim: the World at 1 kHz, the FlightCore at 400 Hz, the
DMP path as FULL flies it) in four short flights, and compares the estimate with the simulator's truth:

- ``touchdown``: FULL, hover at 1 m, then the scripted pilot flies down to the floor; 0.2 s after the touch-down
  it puts the lift to zero. ``touchdown_err_m``: the largest |height - truth| from 1 s to 5 s after the touch-down
  (goal <= 0.10 m); ``touchdown_err_at_1s_m`` at 1 s.
- ``ceiling``: in the lab's room (3 m ceiling) the pilot asks for 3.6 m and stays pressed there 4 s.
  ``ceiling_err_m``: the largest |height - truth| from 0.5 s after the hit (goal <= 0.3 m, or the estimate marked
  unsure: ``ceiling_unmarked_m`` is the largest error while the estimate was NOT marked unsure); ``ceiling_vz_rms``.
- ``hover``: 20 s at 1 m: ``hover_vz_rms`` (the estimated vz against the true one, m/s) and ``hover_h_rms`` (height,
  m); ``hover_vz_look_rms`` and ``hover_h_look_rms``: the change of that error from one look of a keyboard pilot to
  the next (0.2 s apart, bench/keyboard.py), what a pilot who reads the screen is misled by; then a climb to 2 m:
  ``climb_vz_lag_s`` and ``climb_h_lag_s``, the delay of the estimated vz and height (each from its value when the
  climb began, so an offset does not count) behind the true ones that fits best (0-0.3 s).
- ``rest``: calibration, then ``--rest`` s (600) in SAFE: ``rest_heading_drift_deg``: |psi - truth| at the end on the
  DMP path (the one SAFE shows) and ``rest_heading_drift_raw_deg`` on the RAW filter's (goal <= 1°).
- ``flight``: calibration, 10 s on the pad, then ``--flight`` s (300) of FULL hover at 1 m:
  ``flight_heading_drift_deg`` at the end.

    python -m bench.height [--seeds 8] [--rest 600] [--flight 300] [--quick] [--only hover ...] [--thrust-model]

``--thrust-model`` flies the height estimator's thrust model (an experiment, off on the boards:
fcb_sim/estimation/height.py THRUST_MODEL, docs/height.md "The thrust model").

``--quick`` is 2 seeds, 120 s at rest and 60 s of flight (a run for development on shared cores). Prints a line per
seed and, last, one JSON object: each figure's worst seed and mean, and ``touchdown_within_goal`` (seeds).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from collections.abc import Callable

import fcb_sim.estimation.height as height_module
from fcb_sim.lab.scenarios import Sim
from term.core.protocol import Mode
from term.core.protocol.instructor import ROOM_CEILING_M, ROOM_HALF_M

TOUCHDOWN_GOAL_M = 0.10
CEILING_GOAL_M = 0.3
HEADING_GOAL_DEG = 1.0


def _wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def _watch(sim: Sim, fn: Callable[[Sim], None]) -> None:
    sim.on_tick = fn


def touchdown(seed: int) -> dict[str, float]:
    sim = Sim(seed)
    sim.prologue(Mode.FULL)
    sim.run_until(8.0)
    sim.pilot_target = -0.5  # down onto the floor, the motors running
    rows: list[tuple[float, float]] = []
    state = {"td": math.inf}

    def tick(s: Sim) -> None:
        w = s.world
        if state["td"] == math.inf and w.on_ground:
            state["td"] = s.t
        if s.t >= state["td"] + 0.2 and s.pilot_target is not None:
            s.pilot_target = None  # the pilot sees it down and takes the lift away
            s.sticks[3] = 0
        rows.append((s.t - state["td"], s.fc.height - w.truth.h))

    _watch(sim, tick)
    sim.run_until(20.0)
    after = [abs(e) for dt, e in rows if 1.0 <= dt <= 5.0]
    at1 = [abs(e) for dt, e in rows if 1.0 <= dt < 1.0 + 1.5 / 400.0]
    return {"touchdown_err_m": max(after) if after else math.nan, "touchdown_err_at_1s_m": at1[0] if at1 else math.nan}


def ceiling(seed: int) -> dict[str, float]:
    sim = Sim(seed, world_kw={"room": (ROOM_HALF_M, ROOM_CEILING_M)})
    sim.prologue(Mode.FULL)
    sim.run_until(6.0)
    sim.pilot_target = ROOM_CEILING_M + 0.6
    rows: list[tuple[float, float, float, bool]] = []

    def tick(s: Sim) -> None:
        w = s.world
        hits = [c.t for c in w.contacts if c.where == "ceiling"]
        if hits and w.contact == "ceiling" and s.t >= hits[0] + 0.5:
            rows.append((s.t, s.fc.height - w.truth.h, s.fc.vz, s.fc.height_unsure))

    _watch(sim, tick)
    sim.run_until(14.0)
    if not rows:
        return {"ceiling_err_m": math.nan, "ceiling_unmarked_m": math.nan, "ceiling_vz_rms": math.nan}
    return {"ceiling_err_m": max(abs(e) for _t, e, _v, _u in rows),
            "ceiling_unmarked_m": max((abs(e) for _t, e, _v, u in rows if not u), default=0.0),
            "ceiling_vz_rms": math.sqrt(sum(v * v for _t, _e, v, _u in rows) / len(rows))}


def _lag_s(est: list[float], tru: list[float], rate_hz: float = 400.0) -> float:
    """The delay (s, 0 to 0.3) of ``est`` behind ``tru`` that leaves the least squared difference."""
    best_k, best = 0, math.inf
    n = len(est)
    for k in range(0, int(0.3 * rate_hz) + 1, 2):
        c = sum((est[i + k] - tru[i]) ** 2 for i in range(n - k)) / (n - k)
        if c < best:
            best_k, best = k, c
    return best_k / rate_hz


def hover(seed: int) -> dict[str, float]:
    sim = Sim(seed)
    sim.prologue(Mode.FULL)
    sim.run_until(6.0)
    est: list[float] = []
    tru: list[float] = []
    herr: list[float] = []
    climb_est: list[float] = []
    climb_tru: list[float] = []
    climb_h: list[float] = []
    climb_h_tru: list[float] = []

    def tick(s: Sim) -> None:
        w = s.world
        if s.t < 26.0:
            est.append(s.fc.vz)
            tru.append(-w.vd)
            herr.append(s.fc.height - w.truth.h)
        else:  # the climb to 2 m: the estimated vz against the true one
            climb_est.append(s.fc.vz)
            climb_tru.append(-w.vd)
            climb_h.append(s.fc.height)
            climb_h_tru.append(w.truth.h)

    _watch(sim, tick)
    sim.run_until(26.0)
    sim.pilot_target = 2.0
    sim.run_until(31.0)
    n = len(est)
    vz_rms = math.sqrt(sum((a - b) ** 2 for a, b in zip(est, tru, strict=True)) / n)
    h_rms = math.sqrt(sum(e * e for e in herr) / n)
    verr = [a - b for a, b in zip(est, tru, strict=True)]
    return {"hover_vz_rms": vz_rms, "hover_h_rms": h_rms,
            "hover_vz_look_rms": _look_rms(verr), "hover_h_look_rms": _look_rms(herr),
            "climb_vz_lag_s": _lag_s(climb_est, climb_tru),
            "climb_h_lag_s": _lag_s([h - climb_h[0] for h in climb_h], [h - climb_h_tru[0] for h in climb_h_tru])}


def _look_rms(err: list[float], rate_hz: float = 400.0, look_s: float = 0.2) -> float:
    """The rms change of an error between two looks ``look_s`` apart (samples at ``rate_hz``)."""
    k = round(look_s * rate_hz)
    d = [err[i + k] - err[i] for i in range(0, len(err) - k, k)]
    return math.sqrt(sum(x * x for x in d) / len(d)) if d else math.nan


def rest(seed: int, seconds: float) -> dict[str, float]:
    sim = Sim(seed)
    sim.set_mode(Mode.CALIBRATION)
    sim.run_until(1.0)
    sim.set_mode(Mode.SAFE)
    sim.run_until(1.0 + seconds)
    truth = math.degrees(sim.world.truth.psi)
    return {"rest_heading_drift_deg": abs(_wrap_deg(math.degrees(sim.fc.psi_dmp) - truth)),
            "rest_heading_drift_raw_deg": abs(_wrap_deg(math.degrees(sim.fc.psi_raw) - truth))}


def flight(seed: int, seconds: float) -> dict[str, float]:
    sim = Sim(seed)
    sim.set_mode(Mode.CALIBRATION)
    sim.run_until(1.0)
    sim.set_mode(Mode.SAFE)
    sim.run_until(11.0)  # on the pad after calibration: the drift rate is learnt
    sim.set_mode(Mode.FULL)
    sim.pilot_target = 1.0
    sim.run_until(11.0 + seconds)
    truth = math.degrees(sim.world.truth.psi)
    return {"flight_heading_drift_deg": abs(_wrap_deg(math.degrees(sim.fc.psi) - truth))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=1, help="the first seed (101: the tuning seeds)")
    ap.add_argument("--rest", type=float, default=600.0, help="s in SAFE after calibration")
    ap.add_argument("--flight", type=float, default=300.0, help="s of hover for the flight's heading drift")
    ap.add_argument("--quick", action="store_true", help="2 seeds, 120 s at rest, 60 s of flight")
    ap.add_argument("--only", choices=("touchdown", "ceiling", "hover", "rest", "flight"), action="append",
                    help="run only these parts (repeatable)")
    ap.add_argument("--thrust-model", choices=("on", "off"), default="on",
                    help="the height estimator's thrust model (on: the boards' default)")
    args = ap.parse_args()
    height_module.THRUST_MODEL = args.thrust_model == "on"
    if args.quick:
        args.seeds, args.rest, args.flight = 2, 120.0, 60.0
    per_seed: list[dict[str, float]] = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        r: dict[str, float] = {}
        parts: dict[str, Callable[[int], dict[str, float]]] = {
            "touchdown": touchdown, "ceiling": ceiling, "hover": hover,
            "rest": lambda s: rest(s, args.rest), "flight": lambda s: flight(s, args.flight)}
        for name, part in parts.items():
            if not args.only or name in args.only:
                r.update(part(seed))
        per_seed.append(r)
        print(f"seed {seed}: " + "  ".join(f"{k} {v:.3f}" for k, v in r.items()), flush=True)
    out: dict[str, float | int | str] = {"seeds": args.seeds, "first_seed": args.first_seed, "rest_s": args.rest,
                                         "flight_s": args.flight,
                                   "thrust_model": args.thrust_model}
    for key in per_seed[0]:
        vals = [r[key] for r in per_seed]
        out[f"{key}_worst"] = round(max(vals), 4)
        out[f"{key}_mean"] = round(statistics.fmean(vals), 4)
    for key, goal, name in (("touchdown_err_m", TOUCHDOWN_GOAL_M, "touchdown_within_goal"),
                            ("ceiling_unmarked_m", CEILING_GOAL_M, "ceiling_within_goal"),
                            ("rest_heading_drift_deg", HEADING_GOAL_DEG, "rest_heading_within_goal")):
        if key in per_seed[0]:
            out[name] = sum(r[key] <= goal for r in per_seed)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
