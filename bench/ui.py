"""UI cost with telemetry at full rate: CPU of the term process and event-loop lag.

The board is served in real time by `fcb-sim serve --pty` in a child process (as `term --sim` does) and asked
for telemetry at 100 Hz (SET_PARAM TELEMETRY_HZ, the most it sends; Attitude and Motion at 100 Hz, the rest at their
rates); the terminal is the real TermApp over the SerialTransport, run headless (the full widget tree is laid
out and rendered at the app's render rate; only the bytes to a real terminal are not written). For each screen
(flight, plots, parameters) the bench measures, over ``--seconds``:

- ``cpu_pct``: CPU time of this process (all threads: Textual, the link's thread, the serial reader) over wall time,
  in % of one core;
- ``lag_p99_ms``: the event loop's lag, from a probe that asks to wake every 10 ms and records how late it is;
- ``record_cpu_pct``: the session recording's share (term/data/recording.py, on as in ``term``): time spent inside the
  recorder's calls (every byte both ways, the station's events, the flushes) over wall time, in % of one core,
  with the bytes it wrote per second (``record_bytes_per_s``). ``--no-record`` measures without it;
- ``plot_redraw_ms`` (plots screen): CPU time of one redraw of a live plot (term/ui/widgets/plots.py, the native
  braille widget: ``python -m bench.plots`` compares it with textual-plotext), with ``plot_redraws_per_s`` and
  their share of a core, ``plot_cpu_pct``;
- ``screen_change_ms``: the display thread's CPU for one change of screen by its F-key (F8, F9, F10, F11, F7 in
  turn, each until the new screen is up and drawn; the same window's CPU with no key pressed taken off), with the
  key bar at the foot of each screen (term/ui/widgets/keybar.py) and, in the same run, with Textual's own
  ``Footer`` in its place (``screen_change_ms_textual_footer``, and the ratio).

    python -m bench.ui [--seconds 6] [--render-hz 20] [--no-record] [--no-link-thread]

Prints one JSON line; goals: cpu under 20 % of a core (issue 21), lag p99 under 16 ms, recording under 2 % of a core.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import resource
import sys
import time
from collections.abc import Iterator
from typing import Any


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


async def _probe(lags: list[float], stop: asyncio.Event, period: float = 0.01) -> None:
    while not stop.is_set():
        t = time.perf_counter()
        await asyncio.sleep(period)
        lags.append((time.perf_counter() - t - period) * 1e3)


def _pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, max(0, round(q / 100 * (len(s) - 1))))] if s else float("nan")


def _timed(recorder: Any, spent: list[float]) -> None:
    """Count the wall time spent inside the recorder's calls (all synchronous, on the event loop's thread)."""
    def wrap(fn: Any) -> Any:
        def timed(*a: Any, **k: Any) -> Any:
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[0] += time.perf_counter() - t
        return timed

    for name in ("received", "sent", "event", "station_event", "poll"):
        setattr(recorder, name, wrap(getattr(recorder, name)))


def _timed_plots(drawn: list[float]) -> Any:
    """Count the CPU time and the calls of the live plots' redraws (on the event loop's thread); returns the undo."""
    from term.ui.widgets.plots import LivePlot

    draw = LivePlot.draw

    def timed(self: Any, *a: Any, **k: Any) -> Any:
        t = time.thread_time()
        try:
            return draw(self, *a, **k)
        finally:
            drawn[0] += time.thread_time() - t
            drawn[1] += 1

    LivePlot.draw = timed  # type: ignore[method-assign]
    return lambda: setattr(LivePlot, "draw", draw)


async def run(seconds: float, render_hz: float | None, seed: int, policy: str = "stream",
              record: bool = True, link_thread: bool = True) -> dict[str, Any]:
    from term.core.protocol import PARAMS, Op, Param, param_arg
    from term.session.sim import SimBoard
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp

    sim = SimBoard(seed=seed)
    port = sim.start()
    out: dict[str, Any] = {}
    drawn = [0.0, 0]
    untime_plots = _timed_plots(drawn)
    render_hz_used = render_hz
    try:
        import tempfile
        from pathlib import Path

        from term.core.events import CABLE
        from term.data.recording import RecordingTransport, SessionRecorder
        from term.session.config import Config

        transport: Any = SerialTransport(port)
        recorder = None
        spent = [0.0]
        if record:
            recorder = SessionRecorder(Path(tempfile.mkdtemp(prefix="bench-ui-")), time.monotonic())
            _timed(recorder, spent)
            transport = RecordingTransport(transport, recorder, CABLE, time.monotonic)
        app = TermApp(transport, joystick=False, config=Config(joystick_policy=policy), recorder=recorder,
                      link_thread=link_thread, **({"render_hz": render_hz} if render_hz else {}))
        render_hz_used = app.render_hz
        async with app.run_test(size=(120, 44), headless=True) as pilot:
            async def until(cond: Any, timeout: float = 10.0) -> None:
                async with asyncio.timeout(timeout):
                    while not cond():
                        await asyncio.sleep(0.02)

            await until(lambda: app.model.attitude is not None)
            full = PARAMS[Param.TELEMETRY_HZ].to_raw(100.0)  # a float parameter: raw is value / scale
            app.send(Op.SET_PARAM, param_arg(Param.TELEMETRY_HZ, full))  # telemetry at the board's full rate
            await asyncio.sleep(1.0)
            for screen, key in (("flight", None), ("plots", "f8"), ("params", "f11")):
                if key:
                    app.simulate_key(key)
                    await asyncio.sleep(0.5)
                lags: list[float] = []
                stop = asyncio.Event()
                probe = asyncio.create_task(_probe(lags, stop))
                frames0 = app.model.link.frames_ok if app.model.link else 0
                rx0 = app.model.link.rx_bytes if app.model.link else 0
                s0, b0 = spent[0], _size(recorder)
                d0, n0 = drawn
                c0, w0 = _cpu(), time.perf_counter()
                await asyncio.sleep(seconds)
                c1, w1 = _cpu(), time.perf_counter()
                s1, b1 = spent[0], _size(recorder)
                d1, n1 = drawn
                stop.set()
                await probe
                link = app.model.link
                out[screen] = {
                    "cpu_pct": round(100 * (c1 - c0) / (w1 - w0), 1),
                    "lag_p50_ms": round(_pct(lags, 50), 2),
                    "lag_p99_ms": round(_pct(lags, 99), 2),
                    "lag_max_ms": round(max(lags), 2),
                    "frames_per_s": round(((link.frames_ok if link else 0) - frames0) / (w1 - w0), 1),
                    "rx_bytes_per_s": round(((link.rx_bytes if link else 0) - rx0) / (w1 - w0)),
                    **({"record_cpu_pct": round(100 * (s1 - s0) / (w1 - w0), 2),
                        "record_bytes_per_s": round((b1 - b0) / (w1 - w0))} if recorder is not None else {}),
                    **({"plot_redraw_ms": round(1e3 * (d1 - d0) / (n1 - n0), 2),
                        "plot_redraws_per_s": round((n1 - n0) / (w1 - w0), 1),
                        "plot_cpu_pct": round(100 * (d1 - d0) / (w1 - w0), 2)} if n1 > n0 else {}),
                }
            _ = pilot
        if recorder is not None:
            recorder.close()
            for p in recorder.paths:
                p.unlink(missing_ok=True)
        for footer in (False, True):  # a fresh app each: a screen is built once and kept
            app = TermApp(SerialTransport(port), joystick=False, config=Config(joystick_policy=policy))
            with _textual_footer(footer):
                async with app.run_test(size=(120, 44), headless=True):
                    async with asyncio.timeout(10):
                        while app.model.attitude is None:
                            await asyncio.sleep(0.02)
                    key = "screen_change_ms_textual_footer" if footer else "screen_change_ms"
                    out[key] = await _screen_changes(app)
    finally:
        untime_plots()
        sim.stop()
    out["render_hz"] = render_hz_used
    return out


SCREEN_KEYS = (("f8", "PlotsScreen"), ("f9", "ProfileScreen"), ("f10", "WirelessScreen"), ("f11", "ParamsScreen"),
               ("f7", "FlightScreen"))


@contextlib.contextmanager
def _textual_footer(on: bool) -> Iterator[None]:
    """Textual's ``Footer`` at the foot of every screen in place of the key bar, for the screens built meanwhile."""
    import importlib

    from textual.widgets import Footer

    from term.ui.widgets.keybar import KeyBar

    modules = [importlib.import_module(f"term.ui.screens.{m}") for m in
               ("flight", "plots", "profile", "wireless", "params", "joystick", "console", "motortest")]
    for m in modules:
        m.KeyBar = Footer if on else KeyBar  # type: ignore[attr-defined]
    try:
        yield
    finally:
        for m in modules:
            m.KeyBar = KeyBar  # type: ignore[attr-defined]


async def _screen_changes(app: Any, rounds: int = 6) -> float:
    """The display thread's CPU (ms) for one screen change by its F-key, less the same window with no change."""
    async def window(key: str | None, name: str) -> float:
        t = time.thread_time()
        if key is not None:
            app.simulate_key(key)
            async with asyncio.timeout(10):
                while type(app.screen).__name__ != name:
                    await asyncio.sleep(0.005)
        await asyncio.sleep(0.2)  # (drawn: the render tick is 12 Hz)
        return time.thread_time() - t

    for key, name in SCREEN_KEYS:  # (each screen built first: a screen is made once and kept)
        await window(key, name)
    changes = [await window(key, name) for _ in range(rounds) for key, name in SCREEN_KEYS]
    still = [await window(None, "FlightScreen") for _ in range(len(SCREEN_KEYS))]
    return round(1e3 * (sum(changes) / len(changes) - sum(still) / len(still)), 1)


def _size(recorder: Any) -> int:
    """Bytes the recording has handed to the OS so far (its current file)."""
    if recorder is None or recorder.path is None:
        return 0
    return sum(p.stat().st_size for p in recorder.paths if p.exists())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.ui", description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=6.0, help="measuring time per screen (default 6)")
    ap.add_argument("--render-hz", type=float, default=None, help="the app's render rate (default: the app's)")
    ap.add_argument("--policy", default="stream", choices=["stream", "on-change", "fixed-rate"],
                    help="the joystick send policy (default stream, the app's)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-record", action="store_true", help="without the session recording")
    ap.add_argument("--no-link-thread", action="store_true",
                    help="the link on the display's loop, as before issue 21 (term/session/link_thread.py)")
    args = ap.parse_args(argv)
    res = asyncio.run(run(args.seconds, args.render_hz, args.seed, args.policy, record=not args.no_record,
                          link_thread=not args.no_link_thread))
    hz = res.pop("render_hz")
    change, change_footer = res.pop("screen_change_ms"), res.pop("screen_change_ms_textual_footer")
    worst_cpu = max(r["cpu_pct"] for r in res.values())
    worst_lag = max(r["lag_p99_ms"] for r in res.values())
    print(json.dumps({
        "cpu_pct": worst_cpu, "lag_p99_ms": worst_lag, "render_hz": hz, "policy": args.policy,
        "link_thread": not args.no_link_thread, **res,
        "goal_cpu_pct": 20, "goal_lag_p99_ms": 16,
        **({"record_cpu_pct": max(r["record_cpu_pct"] for r in res.values()), "goal_record_cpu_pct": 2}
           if not args.no_record else {}),
        "plot_redraw_ms": res["plots"].get("plot_redraw_ms"),
        "plot_widget": "native braille (term/ui/widgets/plots.py)",
        "screen_change_ms": change, "screen_change_ms_textual_footer": change_footer,
        "screen_change_ratio_to_textual_footer": round(change / change_footer, 2) if change_footer > 0 else None,
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
