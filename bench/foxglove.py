"""Serving a flight live to Foxglove: what it costs the terminal, and how old a message is when a client has it.

The board is served in real time by `fcb-sim serve --pty` in a child (as `term --sim` does) and asked for telemetry
at 100 Hz (its most); the terminal is the real TermApp over the SerialTransport, headless, with the recording and
the live server (term/data/foxglove_server.py) tapped at the transport as `term --foxglove` wires them. A client of
Foxglove's WebSocket protocol (tests/support/foxglove_client.py) runs in another process, as Foxglove itself would, and
subscribes to every channel. Over ``--seconds``:

- ``serve_cpu_pct``: the CPU of the thread the live server started (the SDK's sender, read from /proc per thread)
  plus the time inside its calls on the terminal's threads (converting the link's packets, decoding what was
  written, handing each step's messages to the SDK), over wall time, in % of one core (goal <= 3 %);
  ``serve_tap_cpu_pct``: that second part alone; ``term_cpu_pct``: the whole terminal process's, beside it, and
  ``serve_share_of_term_pct``: the serving's share of it (steadier than either when the machine's speed varies);
- ``age_p50_ms``, ``age_p99_ms``: a message's age at the client, from the time its bytes were read off the link
  (the recording's stamp, which the live message carries) to the client reading it (goal p99 <= 20 ms); the
  client's and the terminal's clocks are the same machine's wall clock; ``handoff_p99_ms``: its age when the
  live server hands it to the SDK (the terminal's share; the rest is the SDK's sending and the client's
  waking); ``client_cpu_pct``: the client process's CPU; ``load_avg_1min``: the machine's, as it ran;
- ``messages_per_s`` at the client, and the topics it had.

    python -m bench.foxglove [--seconds 8]

Linux (the per-thread CPU is read from /proc). Prints one JSON line.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

TICK = os.sysconf("SC_CLK_TCK")


def _threads() -> set[int]:
    return {int(t) for t in os.listdir("/proc/self/task")}


def _thread_cpu(tids: set[int]) -> float:
    total = 0
    for tid in tids:
        try:
            fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # ended
        total += int(fields[11]) + int(fields[12])  # utime, stime (clock ticks)
    return total / TICK


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _clock_pair() -> tuple[float, int]:
    """The monotonic clock and the wall clock read together: the closest of a few tries (a thread preempted
    between the two readings on a busy machine would shift every age by the gap)."""
    best = (float("inf"), 0.0, 0)
    for _ in range(50):
        a = time.monotonic()
        wall = time.time_ns()
        b = time.monotonic()
        best = min(best, (b - a, (a + b) / 2, wall))
    return best[1], best[2]


def _handoffs(live: Any, ages: list[float]) -> None:
    """The age of each message (ms) when the live server hands it to the SDK: the terminal's share of the age."""
    publish = live._publish

    def timed(messages: Any, *args: Any, **kwargs: Any) -> None:
        messages = list(messages)
        now = time.time_ns()
        ages.extend([(now - t) / 1e6 for _, t, _ in messages])
        publish(messages, *args, **kwargs)

    live._publish = timed


def _pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, max(0, round(q / 100 * (len(s) - 1))))] if s else float("nan")


def _timed_taps(live: Any, spent: list[float]) -> None:
    for name in ("received", "link_packet", "sent", "_flush", "event", "station_event", "truth"):
        fn = getattr(live, name)

        def timed(*a: Any, _fn: Any = fn, **k: Any) -> Any:
            t = time.thread_time()
            try:
                return _fn(*a, **k)
            finally:
                spent[0] += time.thread_time() - t

        setattr(live, name, timed)


async def run(seconds: float, seed: int) -> dict[str, Any]:
    import tempfile

    from term.core.events import CABLE
    from term.core.protocol import PARAMS, Op, Param, param_arg
    from term.data.foxglove_server import LiveServer
    from term.data.recording import RecordingTransport, SessionRecorder
    from term.session.sim import SimBoard
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp

    sim = SimBoard(seed=seed)
    port = sim.start()
    out: dict[str, Any] = {}
    try:
        now, wall_ns = _clock_pair()
        rec = SessionRecorder(Path(tempfile.mkdtemp(prefix="bench-foxglove-")), now, wall_ns=wall_ns)
        before = _threads()
        live = LiveServer("127.0.0.1", 0, t0=rec.t0, start_ns=rec.start_ns)
        serving = _threads() - before  # the SDK's runtime (a client adds tasks there, no thread;
        # threads started later are the terminal's: the link's, the serial reader's)
        spent, handoff = [0.0], []
        _timed_taps(live, spent)
        _handoffs(live, handoff)
        transport = RecordingTransport(SerialTransport(port), (rec, live), CABLE, time.monotonic)
        app = TermApp(transport, joystick=False, recorder=rec, live=live)
        async with app.run_test(size=(120, 44), headless=True):
            async def until(cond: Any, timeout: float = 10.0) -> None:
                async with asyncio.timeout(timeout):
                    while not cond():
                        await asyncio.sleep(0.02)

            await until(lambda: app.model.attitude is not None)
            full = PARAMS[Param.TELEMETRY_HZ].to_raw(100.0)  # (a float parameter: raw is value / scale)
            app.send(Op.SET_PARAM, param_arg(Param.TELEMETRY_HZ, full))  # telemetry at the board's full rate
            client = subprocess.Popen([sys.executable, "-m", "bench.foxglove", "--client", live.url,
                                       "--seconds", str(seconds + 2.0)], stdout=subprocess.PIPE, text=True)
            await asyncio.sleep(2.0)  # connected, every channel advertised and subscribed
            c0, w0, s0, t0, h0 = _cpu(), time.perf_counter(), _thread_cpu(serving), spent[0], len(handoff)
            await asyncio.sleep(seconds)
            c1, w1, s1, t1, h1 = _cpu(), time.perf_counter(), _thread_cpu(serving), spent[0], len(handoff)
            got, _ = await asyncio.to_thread(client.communicate)
            wall = w1 - w0
            out["serve_cpu_pct"] = round(100 * (s1 - s0 + t1 - t0) / wall, 2)
            out["serve_tap_cpu_pct"] = round(100 * (t1 - t0) / wall, 2)  # ours, in the taps (the rest: the SDK's)
            out["serve_share_of_term_pct"] = round(100 * (s1 - s0 + t1 - t0) / max(1e-9, c1 - c0), 1)
            out["handoff_p99_ms"] = round(_pct(handoff[h0:h1], 99), 2)  # read off the link -> in the SDK's hands
            out["load_avg_1min"] = round(os.getloadavg()[0], 2)
            out["serve_errors"] = live.errors  # items the server could not convert (0, or the figures are wrong)
            out["term_cpu_pct"] = round(100 * (c1 - c0) / wall, 1)
            out.update(json.loads(got.strip().splitlines()[-1]))
        live.close()
        rec.close()
        for p in rec.paths:
            p.unlink(missing_ok=True)
    finally:
        sim.stop()
    return out


async def client(url: str, seconds: float) -> dict[str, Any]:
    """The other process: subscribe to everything for ``seconds``; the ages of what arrived in the last part."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.support.foxglove_client import Client

    c = Client(url)
    stop = asyncio.Event()
    task = asyncio.create_task(c.run(stop))
    await asyncio.sleep(2.0)
    n0, c0, w0 = len(c.received), _cpu(), time.perf_counter()
    await asyncio.sleep(max(0.5, seconds - 2.0))
    c1, w1 = _cpu(), time.perf_counter()
    stop.set()
    await task
    got = c.received[n0:]
    ages = [(r.arrived - r.log_time) / 1e6 for r in got]
    return {"client_cpu_pct": round(100 * (c1 - c0) / (w1 - w0), 1),
            "age_p50_ms": round(_pct(ages, 50), 2), "age_p99_ms": round(_pct(ages, 99), 2),
            "age_max_ms": round(max(ages), 2) if ages else None,
            "messages_per_s": round(len(got) / max(0.5, seconds - 2.0), 1),
            "topics": sorted({r.topic for r in got})}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.foxglove", description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0, help="measuring time (default 8)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--client", metavar="URL", help=argparse.SUPPRESS)  # the client process
    a = ap.parse_args(argv)
    if a.client:
        print(json.dumps(asyncio.run(client(a.client, a.seconds))))
        return 0
    res = asyncio.run(run(a.seconds, a.seed))
    print(json.dumps({"bench": "foxglove", **res, "goal_serve_cpu_pct": 3, "goal_age_p99_ms": 20}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
