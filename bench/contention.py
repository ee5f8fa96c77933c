"""The link on a busy machine: flights through term's app, over the cable and over BLE, with the cores kept busy
and with the whole terminal frozen, and what the board saw.

Three processes, so that freezing or starving one is not freezing the measurement: the board (``fcb-sim serve
--pty``, with its BLE radio for the BLE flights, in a child: ``--board``), the terminal (``TermApp`` headless over
the real SerialTransport / BleTransport, in a child: ``--term``), and this one, which starts them, keeps ``--busy``
processes per core busy (bursts of 5-50 ms of work with short sleeps, as ``shared/tools/busy`` does) and freezes
the terminal with SIGSTOP/SIGCONT. Every flight: calibrate, FULL (over BLE after the handover, key 8), then the
lift stick between two levels at random moments for ``--seconds``. Both children read CLOCK_MONOTONIC.

Per flight it prints:
- ``false_link_losses``: LINK LOST said by the terminal (its link's silence or a dead transport) with no freeze;
- ``stage1`` / ``stage2``: the board's link failsafe: stage 1 holds level (EventCode.LINK_LOST, once the board
  has the two-stage failsafe), stage 2 is the PANIC descent (EventCode.LINK_TIMEOUT);
- ``hb_gap_p99_ms`` / ``hb_gap_max_ms``: the gaps between valid frames from the terminal, as the board's link
  timer counts them (its own clock, at its parse task, less the time its own process was starved: fcb_sim/
  linktimer.py; heartbeat answers, sticks and commands all count);
- ``stick_p99_ms``: from the app's ``set_stick`` to the board's parse task decoding that lift (it recomputes the
  motors in the same task: docs/board.md, "Sticks to motors"), p99 over the flight;
- ``panic_named``: after a freeze that ended in the PANIC descent, whether the terminal's screen says so.

    python -m bench.contention [--seconds 12] [--links cable,ble] [--busy 0,2,4] [--freezes 0.3,0.8,2.5]
    python -m bench.contention --seconds 120          # the issue's 2-minute flights

Prints one JSON line last. Goals (issue 21): no false link loss and no PANIC with up to 4 busy processes per
core; a 0.8 s freeze costs a stage 1 and no PANIC; a 2.5 s freeze ends in the PANIC descent, named on screen;
heartbeat gap p99 <= 150 ms.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from typing import Any

LIFTS = (7000, 9000)  # two lift levels in FULL, around the hover


def _pct(xs: list[float], q: float) -> float | None:
    s = sorted(xs)
    return round(s[min(len(s) - 1, max(0, round(q / 100 * (len(s) - 1))))], 1) if s else None


# --- the board (child) ----------------------------------------------------------------------------------------


def board_main(seed: int, radio: bool) -> int:
    """``fcb-sim serve --pty`` with reports: each new lift it decodes (``js T LIFT``), each failsafe event (``ev T
    NAME ARG``), and at its end the gaps between valid frames (``gaps JSON``, ms on the board's clock)."""
    from fcb_sim.board.board import Board
    from fcb_sim.hosts import serve
    from term.core.protocol import EventCode, Joystick

    gaps: list[float] = []
    board_of: list[Board] = []
    make_board = serve.make_board

    def reporting_board(*a: Any, **k: Any) -> Board:
        board = make_board(*a, **k)
        board_of.append(board)
        handle, emit, heard = board._handle, board.modes.emit, board.link.heard
        last = {"lift": None}

        def _heard(now: int) -> None:  # the silence the board's link timer counts (less its own starved time)
            if board.link.last_frame_us is not None:
                gaps.append(board.link.silent_us(now) / 1e3)
            heard(now)

        def _handle(pkt: Any) -> None:
            if type(pkt) is Joystick and pkt.lift != last["lift"]:
                last["lift"] = pkt.lift
                print(f"js {time.monotonic():.6f} {pkt.lift}", flush=True)
            handle(pkt)

        def _emit(code: EventCode, arg: int, now: float) -> None:
            mode = board.modes.mode.name  # the mode it was said in (a timeout in SAFE is no PANIC)
            print(f"ev {time.monotonic():.6f} {EventCode(code).name} {int(arg)} {mode}", flush=True)
            emit(code, arg, now)

        board._handle = _handle  # type: ignore[method-assign]
        board.link.heard = _heard  # type: ignore[method-assign]
        board.modes.emit = _emit  # type: ignore[method-assign]
        return board

    serve.make_board = reporting_board  # type: ignore[assignment]
    ns = argparse.Namespace(seed=seed, scenario="bench", link_timeout=0.5, preset="default",
                            ble_hci="tcp-server:127.0.0.1:0" if radio else None, instructor=None)
    with asyncio.Runner(loop_factory=serve.event_loop) as runner:
        runner.run(serve._serve_main(ns))
    print("gaps " + json.dumps([round(g, 2) for g in gaps]), flush=True)
    return 0


class BoardChild:
    def __init__(self, seed: int, radio: bool) -> None:
        cmd = [sys.executable, "-m", "bench.contention", "--board", "--seed", str(seed)]
        cmd += ["--radio"] if radio else []
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, bufsize=1, start_new_session=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line.startswith("pty: "):
            raise SystemExit(f"bench.contention: the board did not start ({line.strip() or 'no output'})")
        self.path = line[5:].strip()
        self.ble = ""
        if radio:
            words = self.proc.stdout.readline().split()  # ble: Quadrupel 1 ADDRESS hci SPEC (term/session/sim.py)
            self.ble = f"{words[-3]} {words[-1]}" if len(words) >= 5 and words[-2] == "hci" else ""
        self.js: list[tuple[float, int]] = []
        self.events: list[tuple[float, str, int, str]] = []
        self.gaps: list[float] = []
        self._done = threading.Event()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            parts = line.split(maxsplit=1 if line.startswith("gaps") else 4)
            if parts[0] == "js":
                self.js.append((float(parts[1]), int(parts[2])))
            elif parts[0] == "ev":
                self.events.append((float(parts[1]), parts[2], int(parts[3]), parts[4].strip()))
            elif parts[0] == "gaps":
                self.gaps = json.loads(parts[1])
        self._done.set()

    def stop(self) -> None:
        self.proc.send_signal(signal.SIGTERM)
        self._done.wait(10)
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()


# --- the terminal (child) -------------------------------------------------------------------------------------


async def term_main(port: str, ble: str, seconds: float, seed: int) -> int:
    """The app flies: calibrate, FULL (over BLE after the handover if ``ble``), the lift between two levels."""
    from term.core.protocol import EventCode, Joystick, Mode, Op
    from term.session.texts import mode_name
    from term.transports.ble import BleTransport
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp

    radio = None
    if ble:
        address, hci = ble.split()
        radio = BleTransport(address, hci=hci, timeout=10.0)
    app = TermApp(SerialTransport(port), joystick=False, radio=radio)
    rng = random.Random(seed)
    async with app.run_test(size=(120, 44), headless=True):
        m = app.model

        async def until(cond: Any, what: str, timeout: float = 60.0) -> None:
            try:
                async with asyncio.timeout(timeout):
                    while not cond():
                        await asyncio.sleep(0.02)
            except TimeoutError:
                print(f"fail {what}", flush=True)
                raise SystemExit(1) from None

        await until(lambda: m.mode == Mode.SAFE and (radio is None or m.radio_up), "the app never connected")
        if radio is not None:
            app.send(Op.WIRELESS, 1)
            await until(lambda: m.over_ble, "no handover")
        app.send(Op.MODE, Mode.CALIBRATION)
        await until(lambda: EventCode.CALIBRATION_DONE in m.event_times and m.mode == Mode.SAFE, "no calibration")
        app.send(Op.MODE, Mode.FULL)
        await until(lambda: m.mode == Mode.FULL, "FULL refused")
        print(f"ready {time.monotonic():.6f}", flush=True)
        end = time.monotonic() + seconds
        level = 0
        while time.monotonic() < end:
            await asyncio.sleep(rng.uniform(0.06, 0.2))
            level ^= 1
            t = time.monotonic()
            app.set_stick(Joystick(0, 0, 0, LIFTS[level], 0))
            print(f"stick {t:.6f} {LIFTS[level]}", flush=True)
        print(f"done {time.monotonic():.6f}", flush=True)  # the board's silence after we quit is no failsafe
        screen = " ".join(str(w.render()) for w in app.screen.query("#mode, #events"))
        losses = [e.text for e in m.events  # the terminal's own (the board's stage 1 says LINK LOST too)
                  if e.source != "board" and e.text.startswith(("LINK LOST", "BLE LINK LOST"))]
        print("result " + json.dumps({"losses": losses, "mode": mode_name(m.mode),
                                      "panic_named": "board saw link timeout" in screen}),
              flush=True)
        app.exit()
    return 0


class TermChild:
    def __init__(self, port: str, ble: str, seconds: float, seed: int) -> None:
        cmd = [sys.executable, "-m", "bench.contention", "--term", port, "--ble-spec", ble, "--seconds",
               str(seconds), "--seed", str(seed)]
        self.log = open(os.devnull, "w") if not os.environ.get("BENCH_CONTENTION_DEBUG") else None  # noqa: SIM115
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=self.log, text=True, bufsize=1)
        self.ready = threading.Event()
        self.sticks: list[tuple[float, int]] = []
        self.result: dict[str, Any] = {}
        self.failed = ""
        self.done = float("inf")
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            parts = line.split(maxsplit=2)
            if not parts:
                continue
            if parts[0] == "ready":
                self.ready.set()
            elif parts[0] == "stick":
                self.sticks.append((float(parts[1]), int(parts[2])))
            elif parts[0] == "done":
                self.done = float(parts[1])
            elif parts[0] == "result":
                self.result = json.loads(line[len("result "):])
            elif parts[0] == "fail":
                self.failed = line[5:].strip()
                self.ready.set()

    def wait(self, timeout: float) -> None:
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.failed = self.failed or "the terminal did not finish"


# --- the machine kept busy ------------------------------------------------------------------------------------

_BUSY = """
import random, time
while True:
    end = time.perf_counter() + random.uniform(0.005, 0.05)
    while time.perf_counter() < end:
        pass
    time.sleep(random.uniform(0.0005, 0.003))
"""


def busy(per_core: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", _BUSY]) for _ in range(per_core * (os.cpu_count() or 1))]


# --- one flight -----------------------------------------------------------------------------------------------


def flight(link: str, per_core: int, freezes: tuple[float, ...], seconds: float, seed: int) -> dict[str, Any]:
    board = BoardChild(seed, radio=link == "ble")
    hogs = busy(per_core)
    term = None
    try:
        term = TermChild(board.path, board.ble, seconds, seed)
        if not term.ready.wait(120) or term.failed:
            return {"link": link, "busy_per_core": per_core, "failed": term.failed or "never ready"}
        t_ready = time.monotonic()
        frozen: list[tuple[float, float]] = []
        if freezes:
            spacing = seconds / (len(freezes) + 1)
            for i, s in enumerate(freezes):
                time.sleep(max(0.0, t_ready + spacing * (i + 1) - time.monotonic()))
                t0 = time.monotonic()
                term.proc.send_signal(signal.SIGSTOP)  # the whole terminal: display, link thread, serial reader
                time.sleep(s)
                term.proc.send_signal(signal.SIGCONT)
                frozen.append((t0, time.monotonic()))
        term.wait(seconds + 120)
    finally:
        for h in hogs:
            h.kill()
        for h in hogs:
            h.wait()
        board.stop()
    flown = [e for e in board.events if e[0] <= term.done]  # (after the pilot's SAFE the terminal quits)
    stage1 = [e for e in flown if e[1] == "LINK_LOST"]
    stage2 = [e for e in flown if e[1] == "LINK_TIMEOUT" and e[3] not in ("SAFE", "PANIC", "CALIBRATION")]
    lat = []
    for t, lift in term.sticks:
        got = next((r for r, v in board.js if r >= t and v == lift), None)
        if got is not None and not any(a - 0.5 <= t <= b + 0.5 for a, b in frozen):
            lat.append((got - t) * 1e3)
    out: dict[str, Any] = {
        "link": link, "busy_per_core": per_core, "freezes_s": list(freezes),
        "false_link_losses": 0 if freezes else len(term.result.get("losses", [])),
        "term_link_losses": len(term.result.get("losses", [])),
        "stage1": len(stage1), "stage2": len(stage2),
        "hb_gap_p99_ms": _pct(board.gaps, 99), "hb_gap_max_ms": round(max(board.gaps), 1) if board.gaps else None,
        "stick_p99_ms": _pct(lat, 99), "stick_p50_ms": _pct(lat, 50), "sticks": len(lat),
        "end_mode": term.result.get("mode"),
    }
    if freezes:
        out["panic_named"] = term.result.get("panic_named")
    if term.failed:
        out["failed"] = term.failed
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.contention", description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=12.0, help="flying time per flight (default 12; the issue: 120)")
    ap.add_argument("--links", default="cable,ble", help="cable, ble or both (default cable,ble)")
    ap.add_argument("--busy", default="0,2,4", help="busy processes per core, one flight each (default 0,2,4)")
    ap.add_argument("--freezes", default="0.3,0.8,2.5", help="seconds the terminal is frozen in one more flight "
                    "(default 0.3,0.8,2.5; '' for none)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--board", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--radio", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--term", default="", help=argparse.SUPPRESS)
    ap.add_argument("--ble-spec", default="", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.board:
        return board_main(args.seed, args.radio)
    if args.term:
        return asyncio.run(term_main(args.term, args.ble_spec, args.seconds, args.seed))
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # the busy processes and children stop with us
    links = [x for x in args.links.split(",") if x]
    freezes = tuple(float(x) for x in args.freezes.split(",") if x)
    flights = []
    for link in links:
        for n in (int(x) for x in args.busy.split(",") if x):
            flights.append(flight(link, n, (), args.seconds, args.seed))
            print(json.dumps(flights[-1]), flush=True)
        if freezes:
            for s in freezes:  # one freeze a flight: a stage 1 (or the PANIC) each, counted apart
                flights.append(flight(link, 0, (s,), max(args.seconds, 3 * s + 6), args.seed))
                print(json.dumps(flights[-1]), flush=True)
    busy_flights = [f for f in flights if not f.get("freezes_s") and "failed" not in f]
    print(json.dumps({
        "bench": "contention", "seconds": args.seconds,
        "false_link_losses": sum(f["false_link_losses"] for f in busy_flights),
        "panics_busy": sum(f["stage2"] for f in busy_flights),
        "stage1_busy": sum(f["stage1"] for f in busy_flights),
        "hb_gap_p99_ms": max((f["hb_gap_p99_ms"] or 0 for f in busy_flights), default=None),
        "hb_gap_max_ms": max((f["hb_gap_max_ms"] or 0 for f in busy_flights), default=None),
        "stick_p99_ms": max((f["stick_p99_ms"] or 0 for f in busy_flights), default=None),
        "freezes": {f"{f['link']} {f['freezes_s'][0]} s": {k: f.get(k) for k in ("stage1", "stage2", "panic_named",
                                                                                  "term_link_losses", "failed")}
                    for f in flights if f.get("freezes_s")},
        "failed": [f"{f['link']} busy {f['busy_per_core']}: {f['failed']}" for f in flights if "failed" in f],
        "flights": flights,
        "goals": {"false_link_losses": 0, "panics_busy": 0, "hb_gap_p99_ms": 150},
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
