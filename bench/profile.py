"""The board's task profile with the Cortex-M0 cycle-cost model (report Figure 14 and section 4.2), both
schedulers, beside the report's figures. Prints a table and one JSON line.

RAW path at 400 Hz is the case the report found wanting: a control period of at least WCET99 = 2987 µs in about
2.1 % of the periods under round robin. The priority scheduler (control first at the tick, telemetry only in
the slack) is the report's proposed fix. DMP at 200 Hz is shown for comparison (the report: far fewer misses).

Run: `python -m bench.profile [--seconds S] [--seed N]` (default 20 simulated seconds per run).
"""

from __future__ import annotations

import argparse
import json
import time

from fcb_sim.board import run_profile


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    runs = {}
    t0 = time.perf_counter()
    for path in ("raw", "dmp"):
        for sched in ("round-robin", "priority"):
            out = run_profile(path, sched, args.seconds, args.seed)
            runs[f"{path}/{sched}"] = out
            ctl = out["tasks"]["control"]
            rep = out["report_deadline_miss_rate"]
            print(f"{path.upper():3s} {sched:12s} control period {ctl['period_us']:7.1f}"
                  f" ± {ctl['period_sd_us']:5.1f} µs, >= {out['deadline_us']} µs:"
                  f" {100 * out['deadline_miss_rate']:5.2f} %"
                  f" (>= WCET99.9: {100 * out['deadline_miss_rate_999']:.3f} %), CPU {out['cpu_load_pct']:.0f} %"
                  + (f"   report: {100 * rep:.1f} %" if rep is not None and sched == "round-robin" else ""))
    rr = runs["raw/round-robin"]["tasks"]
    print("\nRAW, round robin: model vs report (Figure 14, FULL rows)")
    report = runs["raw/round-robin"]["report"]
    pairs = {"parse": "parse", "sensor": "sensor_raw", "control": "control_raw", "baro": "baro",
             "telemetry": "telemetry", "heartbeat": "heartbeat", "logging": "logging"}
    for task, key in pairs.items():
        m, r = rr[task], report[key]
        print(f"  {task:10s} mean {m['mean_us']:6.0f} ({r['mean_us']:5.0f})"
              f"  sd {m['sd_us']:5.0f} ({r['sd_us']:4.0f})  p99 {m['p99_us']:6.0f} ({r['p99_us']:6.0f})"
              f"  p99.9 {m['p999_us']:6.0f} ({r['p999_us']:6.0f})"
              f"  period {m['period_us']:8.0f}")
    summary = {
        "bench": "profile",
        "seconds": args.seconds,
        "seed": args.seed,
        "wall_s": round(time.perf_counter() - t0, 2),
        "report_raw_round_robin_miss_rate": 0.021,
        "raw_round_robin_miss_rate": runs["raw/round-robin"]["deadline_miss_rate"],
        "raw_priority_miss_rate": runs["raw/priority"]["deadline_miss_rate"],
        "dmp_round_robin_miss_rate": runs["dmp/round-robin"]["deadline_miss_rate"],
        "dmp_priority_miss_rate": runs["dmp/priority"]["deadline_miss_rate"],
        "raw_round_robin_miss_rate_999": runs["raw/round-robin"]["deadline_miss_rate_999"],
        "raw_priority_miss_rate_999": runs["raw/priority"]["deadline_miss_rate_999"],
        "runs": {k: {"deadline_miss_rate": v["deadline_miss_rate"], "control_period_us": v["tasks"]["control"]
                     ["period_us"], "control_period_sd_us": v["tasks"]["control"]["period_sd_us"],
                     "cpu_load_pct": v["cpu_load_pct"],
                     "tasks": v["tasks"]} for k, v in runs.items()},
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
