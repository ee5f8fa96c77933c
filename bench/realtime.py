"""Real-time factor of the whole flight core on one core. Prints JSON; the last line is one object.

The loop is the board's RAW path: physics at 1 kHz (``World``), the MPU6050 read, the on-board attitude filter
and the height estimator and the controllers and mixing at 400 Hz (``FlightCore``), the DMP model at 100 Hz and
the barometer at 20 Hz, hovering at 1 m after a real take-off. The factor is simulated seconds per CPU second of
this process (``time.process_time``: what one core delivers), taken as the best of five equal pieces of the
flight (the least disturbed by other processes sharing the cores, as timeit's minimum); the median piece and the
wall-clock factor are printed beside it. Goal: >= 100x. The RAW filter ikf runs in C (firmware/board/ikf_f.c,
ikf_q.c through fcb_sim.estimation.native; the same bits as the Python classes) where a C compiler builds it, else in
Python: ``filter_impl`` says which ran, ``c_unavailable_because`` why not (QUADRUPEL_PURE_PYTHON=1 asks for it).

Also printed: the cost of each part in microseconds per call and its share of one simulated second.

The filter is the default board's: ikf in fixed point (the variant that fits the Cortex-M0, est.fixed_point on
in the default preset); ``--no-fixed-point`` times the float one.

Run: ``python -m bench.realtime [--seconds S] [--filter NAME] [--[no-]fixed-point] [--all-filters]``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time

from fcb_sim.board.flight import FlightCore
from fcb_sim.estimation import BEST, FILTERS, make_filter
from fcb_sim.estimation.native import why_not
from fcb_sim.lab.scenarios import Sim
from fcb_sim.world.physics import World
from term.core.protocol import PARAMS, Mode, Param

DEFAULT_FIXED_POINT = bool(PARAMS[Param.FIXED_POINT].default)  # the default board's RAW filter arithmetic


def flight_core_factor(seconds: float, filter_name: str, fixed_point: bool = False, chunks: int = 5) -> dict:
    """Hover in RAW mode and time ``chunks`` equal pieces of ``seconds``: the best piece is the least disturbed
    by other processes (as timeit's minimum), the median is printed beside it."""
    sim = Sim(1, core=FlightCore(filter_name=filter_name, fixed_point=fixed_point))
    sim.prologue(Mode.RAW)
    sim.run_until(5.0)  # calibrated and airborne
    piece = seconds / chunks
    cpu_f, wall_f = [], []
    for _ in range(chunks):
        c0, w0 = time.process_time(), time.perf_counter()
        sim.run_until(sim.t + piece)
        cpu_f.append(piece / max(1e-9, time.process_time() - c0))
        wall_f.append(piece / max(1e-9, time.perf_counter() - w0))
    return {
        "filter": filter_name + (" (fixed point)" if fixed_point else ""),
        "realtime_factor": max(cpu_f),
        "realtime_factor_median": statistics.median(cpu_f),
        "realtime_factor_wall": max(wall_f),
        "cpu_ms_per_sim_s": 1e3 / max(cpu_f),
        "airborne": not sim.world.on_ground,
    }


def _per_call(fn, n: int, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        fn(n)
        best = min(best, time.process_time() - c0)
    return 1e6 * best / n


def part_costs(filter_name: str, fixed_point: bool) -> dict:
    """Microseconds per call of each part, and milliseconds per simulated second at its rate."""
    w = World(1, height=1.0, airborne=True)
    fc = FlightCore(filter_name=filter_name, fixed_point=fixed_point)
    f = make_filter(filter_name, fixed_point=fixed_point)
    he = fc.height_est
    imu = w.imu()

    def physics(n: int) -> None:
        t0 = w.t
        for i in range(1, n + 1):
            w.advance_to(t0 + i * 0.001)

    def sensors(n: int) -> None:
        for _ in range(n):
            w.imu()

    def filt(n: int) -> None:
        for i in range(n):
            f.update(0.01 + 1e-5 * i, -0.02, 0.005, 0.3, -0.2, 9.7, 0.0025)

    def height(n: int) -> None:
        for _ in range(n):
            he.update_imu(0.3, -0.2, 9.7, 1.0, 0.0, 0.0, 0.0, 0.0025)

    def core(n: int) -> None:
        fc.run_filter = fc.run_height = False
        fc.enter_mode(Mode.RAW)
        for i in range(n):
            fc.imu_sample(*imu, 0.0025)
            fc.control(Mode.RAW, i & 1023, -(i & 511), 0, 16384)

    rates = {"physics_step": (physics, 1000.0), "imu_read": (sensors, 400.0), "attitude_filter": (filt, 400.0),
             "height_estimator": (height, 400.0), "imu_sample_and_control": (core, 400.0)}
    out = {}
    for name, (fn, hz) in rates.items():
        n = 4000
        us = _per_call(fn, n)
        out[name] = {"us_per_call": round(us, 2), "ms_per_sim_s": round(us * hz / 1e3, 3), "rate_hz": hz}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated seconds to time (default 30)")
    ap.add_argument("--filter", default=BEST, choices=FILTERS, help=f"RAW filter (default {BEST})")
    ap.add_argument("--fixed-point", action=argparse.BooleanOptionalAction, default=DEFAULT_FIXED_POINT,
                    help="the filter in fixed point (default: the default preset's est.fixed_point, "
                    f"{DEFAULT_FIXED_POINT}: ikf's variant that fits the Cortex-M0); --no-fixed-point for float")
    ap.add_argument("--all-filters", action="store_true", help="also time every filter, float and fixed")
    args = ap.parse_args()
    result = flight_core_factor(args.seconds, args.filter, args.fixed_point)
    result["parts"] = part_costs(args.filter, args.fixed_point)
    if args.all_filters:
        table = []
        for name in FILTERS:
            for fixed in (False, True):
                try:
                    r = flight_core_factor(min(args.seconds, 10.0), name, fixed, chunks=2)
                except ValueError:
                    continue
                table.append({k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()})
                print(json.dumps(table[-1]))
        result["filters"] = table
    impl = type(FlightCore(filter_name=args.filter, fixed_point=args.fixed_point).filter)
    result["filter_impl"] = "c" if getattr(impl, "native", False) else "python"
    result["filter_class"] = impl.__name__
    result["c_unavailable_because"] = why_not()  # None when the C of firmware/board built and ran
    result.update({"goal_realtime_factor": 100.0, "sim_seconds": args.seconds, "physics_hz": 1000,
                   "control_hz": 400, "python": platform.python_version(), "machine": platform.machine()})
    print(json.dumps(result))


if __name__ == "__main__":
    main()
