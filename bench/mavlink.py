"""Sending a flight to a MAVLink ground station: what it costs the terminal, and how old a message is when the
ground station has it (term/data/mavlink.py, ``term --mavlink``).

The board is served in real time by `fcb-sim serve --pty` in a child (as `term --sim` does) and asked for telemetry
at 100 Hz (its most); the terminal is the real TermApp over the SerialTransport, headless, with the endpoint wired
as `term --mavlink` wires it. The ground station is pymavlink (``udpin``, as QGroundControl listens) in another
process: it sends its heartbeat once a second and reads everything. Over ``--seconds``:

- ``serve_cpu_pct``: the CPU of the endpoint's thread (``term mavlink``: the once-a-second messages, reading the
  ground station) plus the time inside its calls on the terminal's threads (``link_packet`` on the link's thread:
  converting each packet and writing its messages; ``station_event`` and ``tick`` on the display's), over wall
  time, in % of one core (goal <= 3 %); ``serve_tap_cpu_pct``: that second part alone; ``term_cpu_pct``: the
  whole terminal process's, and ``serve_share_of_term_pct``: the serving's share of it;
- ``age_p50_ms``, ``age_p99_ms``, ``age_max_ms``: a message's age at the ground station, from the time the link's
  thread handed the endpoint the packet (the message's ``time_boot_ms``/``time_usec``, the session's clock, whole
  ms: an age reads up to 1 ms high) to the ground station reading it (goal p99 <= 20 ms); ``handoff_p99_ms``: the
  terminal's share (packet handed over -> bytes written to the socket);
- ``rates_hz``: each message's rate at the ground station; ``client_cpu_pct``; ``load_avg_1min``;
  ``dropped``, ``errors``: messages the socket did not take, or that failed (0, or the figures are wrong).

    python -m bench.mavlink [--seconds 8]

Beside it, ``python -m bench.foxglove`` gives the Foxglove server's figures on the same flight. Linux (per-thread
CPU from /proc). Prints one JSON line.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import resource
import socket
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

TICK = os.sysconf("SC_CLK_TCK")


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _thread_cpu(name: str) -> float:
    """CPU seconds of this process's threads called ``name`` (from /proc: comm is the name's first 15 chars)."""
    total = 0
    for tid in os.listdir("/proc/self/task"):
        try:
            if Path(f"/proc/self/task/{tid}/comm").read_text().strip() != name[:15]:
                continue
            fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])
    return total / TICK


def _clock_pair() -> tuple[float, int]:
    """The monotonic clock and the wall clock read together (the closest of a few tries)."""
    best = (float("inf"), 0.0, 0)
    for _ in range(50):
        a = time.monotonic()
        wall = time.time_ns()
        b = time.monotonic()
        best = min(best, (b - a, (a + b) / 2, wall))
    return best[1], best[2]


def _pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, max(0, round(q / 100 * (len(s) - 1))))] if s else float("nan")


def _timed(ep: Any, spent: list[float], handoff: list[float]) -> None:
    """The endpoint's calls on the terminal's threads, timed (thread CPU); each packet's handoff time (wall)."""
    for name in ("link_packet", "station_event", "tick"):
        fn = getattr(ep, name)

        def timed(*a: Any, _fn: Any = fn, _name: str = name, **k: Any) -> Any:
            t, w = time.thread_time(), time.perf_counter()
            try:
                return _fn(*a, **k)
            finally:
                spent[0] += time.thread_time() - t
                if _name == "link_packet":
                    handoff.append((time.perf_counter() - w) * 1000)

        setattr(ep, name, timed)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def run(seconds: float, seed: int) -> dict[str, Any]:
    from term.core.protocol import PARAMS, Op, Param, param_arg
    from term.data.mavlink import MavlinkEndpoint
    from term.session.sim import SimBoard
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp

    sim = SimBoard(seed=seed)
    port = sim.start()
    out: dict[str, Any] = {}
    try:
        t0, wall_ns = _clock_pair()
        gcs_port = _free_udp_port()
        client = subprocess.Popen([sys.executable, "-m", "bench.mavlink", "--client", str(gcs_port), "--wall-ns",
                                   str(wall_ns), "--seconds", str(seconds + 2.0)], stdout=subprocess.PIPE, text=True)
        await asyncio.sleep(1.0)  # (pymavlink imported and listening)
        ep = MavlinkEndpoint(f"udp:127.0.0.1:{gcs_port}", t0=t0)
        spent, handoff = [0.0], []
        _timed(ep, spent, handoff)
        app = TermApp(SerialTransport(port), joystick=False, mavlink=ep)
        async with app.run_test(size=(120, 44), headless=True):
            async def until(cond: Any, timeout: float = 10.0) -> None:
                async with asyncio.timeout(timeout):
                    while not cond():
                        await asyncio.sleep(0.02)

            await until(lambda: app.model.attitude is not None)
            full = PARAMS[Param.TELEMETRY_HZ].to_raw(100.0)
            app.send(Op.SET_PARAM, param_arg(Param.TELEMETRY_HZ, full))  # telemetry at the board's full rate
            await asyncio.sleep(2.0)
            c0, w0, s0, t_0, h0 = _cpu(), time.perf_counter(), _thread_cpu("term mavlink"), spent[0], len(handoff)
            await asyncio.sleep(seconds)
            c1, w1, s1, t_1, h1 = _cpu(), time.perf_counter(), _thread_cpu("term mavlink"), spent[0], len(handoff)
            got, _ = await asyncio.to_thread(client.communicate)
            wall = w1 - w0
            out["serve_cpu_pct"] = round(100 * (s1 - s0 + t_1 - t_0) / wall, 2)
            out["serve_tap_cpu_pct"] = round(100 * (t_1 - t_0) / wall, 2)
            out["serve_share_of_term_pct"] = round(100 * (s1 - s0 + t_1 - t_0) / max(1e-9, c1 - c0), 1)
            out["handoff_p99_ms"] = round(_pct(handoff[h0:h1], 99), 3)
            out["term_cpu_pct"] = round(100 * (c1 - c0) / wall, 1)
            out["load_avg_1min"] = round(os.getloadavg()[0], 2)
            out["dropped"], out["errors"] = ep.dropped, ep.errors
            out.update(json.loads(got.strip().splitlines()[-1]))
        ep.close()
    finally:
        sim.stop()
    return out


def client(port: int, wall_ns: int, seconds: float) -> dict[str, Any]:
    """The other process: a pymavlink ground station for ``seconds``; the rates and ages of what arrived after the
    first two seconds."""
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255, dialect="common")
    got: list[tuple[int, Any]] = []
    stop = time.monotonic() + seconds
    start = time.monotonic() + 2.0

    def beat() -> None:
        while time.monotonic() < stop:
            try:
                conn.mav.heartbeat_send(6, 8, 0, 0, 0)  # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID (to the last sender)
            except Exception:  # (no peer yet)
                pass
            time.sleep(1.0)

    threading.Thread(target=beat, daemon=True).start()
    c0 = w0 = None
    while (now := time.monotonic()) < stop:
        msg = conn.recv_match(blocking=True, timeout=0.1)
        arrived = time.time_ns()
        if now >= start:
            if c0 is None:
                c0, w0 = _cpu(), time.perf_counter()
            if msg is not None and msg.get_type() != "BAD_DATA":
                got.append((arrived, msg))
    c1, w1 = _cpu(), time.perf_counter()
    span = max(1e-3, w1 - (w0 or w1))
    ages = []
    for arrived, m in got:
        ms = getattr(m, "time_boot_ms", None)
        if ms is None and hasattr(m, "time_usec"):
            ms = m.time_usec / 1000
        if ms is not None:
            ages.append((arrived - wall_ns) / 1e6 - ms)
    rates = Counter(m.get_type() for _, m in got)
    return {"client_cpu_pct": round(100 * (c1 - (c0 or c1)) / span, 1),
            "age_p50_ms": round(_pct(ages, 50), 2), "age_p99_ms": round(_pct(ages, 99), 2),
            "age_max_ms": round(max(ages), 2) if ages else None,
            "rates_hz": {k: round(v / span, 1) for k, v in sorted(rates.items())},
            "messages_per_s": round(len(got) / span, 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.mavlink", description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0, help="measuring time (default 8)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--client", type=int, metavar="PORT", help=argparse.SUPPRESS)  # the ground station's process
    ap.add_argument("--wall-ns", type=int, default=0, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.client:
        print(json.dumps(client(a.client, a.wall_ns, a.seconds)))
        return 0
    res = asyncio.run(run(a.seconds, a.seed))
    print(json.dumps({"bench": "mavlink", **res, "goal_serve_cpu_pct": 3, "goal_age_p99_ms": 20}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
