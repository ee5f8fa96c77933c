"""Stick-to-motor latency: from a joystick event in term to the board's motor command changing.

The board runs in real time in a child process (fcb_sim.hosts.serve's PtyServer behind a real pseudo-terminal, paced
to the wall clock, 115200 baud on its UART model both ways); the terminal side is term's own link (LinkSession and
Connection over the SerialTransport) in this process. The board is calibrated and put in MANUAL (motors follow
the lift stick directly, so every motor change is caused by a stick change), then the lift stick alternates
between two levels at random moments. For each change, latency = (the wall time at which the board's motor
command changed, as the child reports it) - (the moment term got the stick value). Both sides read
CLOCK_MONOTONIC, which the two processes share. The board changes the motors in the parse task that decodes a
new stick value (fcb_sim/board/board.py, "Sticks to motors"); ``by_parse_pct`` says how often it did.

    python -m bench.latency [--events 120] [--policy stream|on-change|fixed-rate] [--raw] [--seed 1]
                            [--no-report-board] [--link pty|tcp]

``--link tcp`` serves the board on a loopback TCP port instead (fcb-sim serve --tcp: term opens it as socket://,
the link term --sim takes where there are no pseudo-terminals); ``to_board`` is then the TCP hop.

Prints one JSON line: mean_ms, p50_ms, p99_ms (and n, the report's 23.4 ms mean and the 3 ms goal), and where the
time goes: term_mean_ms (to the frame handed to the serial port), to_board_mean_ms (to the board's server reading
it from the pty) and board_mean_ms (the frame's 1.3 ms on the board's UART, waiting for the loop, parse and the
recompute).

In the same run, measured the same way, the report's board (``report_board_*``): the board with the "report"
preset (docs/parameters.md: no stick reaction, so only the next control step moves the motors; the report's
queue rule) and a PC that samples the joystick every 10 ms as in the report's section 4.3 (a stick moved between
two samples waits for the next one; the random moments of the stick events give every phase).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import statistics
import subprocess
import sys
import threading
import time
from typing import Any

LIFTS = (8000, 12000)  # two lift levels, both above idle in MANUAL


# --- the board side (child process) ---------------------------------------------------------------------------


def board_main(seed: int, preset: str = "default", link: str = "pty") -> int:
    from fcb_sim.hosts.serve import PtyServer, TcpServer, event_loop, make_board
    from term.core.protocol import Decoder, Joystick

    class Reporting(TcpServer if link == "tcp" else PtyServer):  # type: ignore[misc]
        """Reports every change of the motor commands with the wall time it took effect and the task that made
        it, and the wall time each new stick value was read from the pty."""

        last: tuple[int, ...] = ()
        lift: int | None = None
        decoder = Decoder()

        def _on_readable(self) -> None:
            t = time.monotonic()
            before = self.bytes_in
            super()._on_readable()
            n = self.bytes_in - before
            if n:  # decode a copy after the board has the bytes (the board is not held up by this)
                for pkt in self.decoder.feed(bytes(self.board.uart.rx[-n:])):
                    if type(pkt) is Joystick and pkt.lift != self.lift:
                        self.lift = pkt.lift
                        print(f"rx {t:.6f} {pkt.lift}", flush=True)

        def _on_task(self, name: str, start: int, dur: int) -> None:
            super()._on_task(name, start, dur)
            ae = tuple(self.board.ae)
            if ae != self.last:
                self.last = ae
                # The task ran now (the server runs a task once the wall clock reaches its start); the motors
                # changed that much board time after its start (at the start for the control step, after the
                # decode and the recompute for a stick change in the parse task).
                t = time.monotonic() + (self.board.motors_at_us - start) / 1e6
                print(f"ae {t:.6f} {name} {' '.join(map(str, ae))}", flush=True)

    async def main() -> None:
        server = Reporting(make_board(seed, preset=preset))
        print(f"pty: {server.path}", flush=True)
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        import signal

        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, stop.set)
        try:
            await server.serve(stop)
        finally:
            server.close()

    with asyncio.Runner(loop_factory=event_loop) as runner:
        runner.run(main())
    return 0


# --- the terminal side ----------------------------------------------------------------------------------------


class BoardChild:
    def __init__(self, seed: int, preset: str = "default", link: str = "pty") -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "bench.latency", "--board", "--seed", str(seed),
                                      "--preset", preset, "--link", link], stdout=subprocess.PIPE, text=True,
                                     bufsize=1)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line.startswith("pty: "):
            raise SystemExit(f"bench.latency: the board did not start ({line.strip() or 'no output'})")
        self.path = line[5:].strip()
        self.changes: list[tuple[float, str, tuple[int, ...]]] = []  # (wall time, task, ae)
        self.rx: list[tuple[float, int]] = []  # (wall time the board read a new lift from the pty, lift)
        self._lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            parts = line.split()
            if parts and parts[0] == "ae":
                with self._lock:
                    self.changes.append((float(parts[1]), parts[2], tuple(int(p) for p in parts[3:])))
            elif parts and parts[0] == "rx":
                with self._lock:
                    self.rx.append((float(parts[1]), int(parts[2])))

    def changes_after(self, t: float) -> list[tuple[float, str, tuple[int, ...]]]:
        with self._lock:
            return [c for c in self.changes if c[0] >= t]

    def rx_after(self, t: float, lift: int) -> float | None:
        with self._lock:
            return next((r for r, v in self.rx if r >= t and v == lift), None)

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()


term_part: list[float] = []  # per event: from the stick event to the frame handed to the serial port
pty_part: list[float] = []  # per event: from the stick event to the board's server reading it from the pty
by_task: list[str] = []  # per event: the board task that changed the motors (parse: at once; control: next step)


async def measure(path: str, board: BoardChild, events: int, policy: str, seed: int,
                  raw: bool = False, pc_sample_s: float = 0.0) -> list[float]:
    """The latencies (ms) of ``events`` stick changes; ``pc_sample_s``: the PC reads the stick only every this
    many seconds (0: at once, as term does), so a change waits for the next sample."""
    from term.core.link import CommandAcked, PacketReceived
    from term.core.protocol import SENSOR_PATHS, Decoder, Event, EventCode, Joystick, Mode, Op, Param, param_arg
    from term.session.connection import Connection
    from term.transports.serial import SerialTransport

    class TimedSerial(SerialTransport):
        """Records when term's link hands each joystick frame to the serial port (term's share of the latency)."""

        writes: list[tuple[float, int]] = []  # (time, lift) per Joystick frame written

        async def write(self, data: bytes) -> None:
            t = time.monotonic()
            for pkt in Decoder().feed(data):
                if type(pkt) is Joystick:
                    self.writes.append((t, pkt.lift))
            await super().write(data)

    got: list[Any] = []
    transport = TimedSerial(path)
    conn = Connection(transport, _session(policy), on_event=got.append)
    await conn.start()

    async def until(cond: Any, timeout: float = 10.0) -> None:
        async with asyncio.timeout(timeout):
            while not cond():
                await asyncio.sleep(0.005)

    def board_event(code: int) -> bool:
        return any(type(e) is PacketReceived and type(e.packet) is Event and e.packet.code == code for e in got)

    def acked(op: int, arg: int) -> bool:
        return any(type(e) is CommandAcked and e.op == op and e.arg == arg for e in got)

    try:
        conn.set_joystick(Joystick(0, 0, 0, 0, 0))
        await until(lambda: conn.stats.frames_ok > 5)
        if raw:  # the RAW sensor path: control at 400 Hz instead of the DMP's 200 Hz
            raw_path = param_arg(Param.SENSOR_PATH, SENSOR_PATHS.index("raw"))
            conn.send_command(Op.SET_PARAM, raw_path)
            await until(lambda: acked(Op.SET_PARAM, raw_path))
        conn.send_command(Op.MODE, Mode.CALIBRATION)
        await asyncio.sleep(1.2)  # ours returns to SAFE by itself after 1 s; the report's averages until 0 is pressed
        conn.send_command(Op.MODE, Mode.SAFE)
        await until(lambda: board_event(EventCode.CALIBRATION_DONE))
        await asyncio.sleep(0.1)
        conn.send_command(Op.MODE, Mode.MANUAL)
        await until(lambda: acked(Op.MODE, Mode.MANUAL))
        rng = random.Random(seed)
        t_start = time.monotonic()  # the phase of the PC's sampling ticks
        latencies: list[float] = []
        level = 0
        term_part.clear()
        pty_part.clear()
        by_task.clear()
        for _ in range(events):
            await asyncio.sleep(rng.uniform(0.06, 0.14))  # a random phase against every timer on both sides
            level ^= 1
            js = Joystick(0, 0, 0, LIFTS[level], 0)
            t_event = time.monotonic()
            if pc_sample_s:  # the report's PC: the stick is read at the next sampling tick
                await asyncio.sleep(pc_sample_s - (t_event - t_start) % pc_sample_s)
            conn.set_joystick(js)  # the joystick event in term: from here on it is term's link and the board
            try:
                await until(lambda t=t_event: bool(board.changes_after(t)), timeout=1.0)
            except TimeoutError:
                continue
            t_motor, task, _ae = board.changes_after(t_event)[0]
            latencies.append((t_motor - t_event) * 1e3)
            by_task.append(task)
            sent = [t for t, lift in transport.writes if t >= t_event and lift == LIFTS[level]]
            if sent:
                term_part.append((sent[0] - t_event) * 1e3)
            t_rx = board.rx_after(t_event, LIFTS[level])
            if t_rx is not None:
                pty_part.append((t_rx - t_event) * 1e3)
        conn.set_joystick(Joystick(0, 0, 0, 0, 0))
        conn.send_command(Op.MODE, Mode.SAFE)
        await asyncio.sleep(0.1)
        return latencies
    finally:
        await conn.stop()


def _session(policy: str) -> Any:
    """The LinkSession the app builds for this joystick policy (term.session.config.JOYSTICK_POLICIES)."""
    from term.core.link import LinkSession
    from term.session.config import JOYSTICK_POLICIES

    return LinkSession(time.monotonic(), **JOYSTICK_POLICIES[policy])  # type: ignore[arg-type]


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, max(0, round(q / 100 * (len(s) - 1))))]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.latency", description=__doc__.splitlines()[0])
    ap.add_argument("--events", type=int, default=120, help="stick changes to time (default 120)")
    ap.add_argument("--policy", default="stream", choices=["stream", "on-change", "fixed-rate"],
                    help="term's joystick send policy ([connection] joystick in term.toml; default stream)")
    ap.add_argument("--raw", action="store_true", help="board on the RAW sensor path (control at 400 Hz)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-report-board", action="store_true", help="skip the report's board (measured second)")
    ap.add_argument("--board", action="store_true", help=argparse.SUPPRESS)  # the child process
    ap.add_argument("--preset", default="default", help=argparse.SUPPRESS)  # the child's parameters
    ap.add_argument("--link", default="pty", choices=["pty", "tcp"],
                    help="the board's UART on a pseudo-terminal (default) or a loopback TCP port (socket://)")
    args = ap.parse_args(argv)
    if args.board:
        return board_main(args.seed, args.preset, args.link)
    lat = _run(args, "default", 0.0)
    report_lat = [] if args.no_report_board else _run(args, "report", REPORT_PC_SAMPLE_S)
    report_by_parse = by_task.count("parse") / len(by_task) if by_task and report_lat else 0.0
    if report_lat:
        _restore()  # the first run's parts for the main keys below
    if not lat:
        print(json.dumps({"error": "no motor change observed"}))
        return 1
    out = {
        "mean_ms": round(statistics.fmean(lat), 2),
        "p50_ms": round(pct(lat, 50), 2),
        "p99_ms": round(pct(lat, 99), 2),
        "min_ms": round(min(lat), 2),
        "max_ms": round(max(lat), 2),
        "n": len(lat),
        # where the time goes: term (event -> frame handed to the serial port: the joystick send policy) and
        # the rest (the wire at 115200 baud, the pty, the board's parse and control tasks)
        "term_mean_ms": round(statistics.fmean(term_part), 2) if term_part else None,
        # to the board's server reading the frame from the pty (term, the write thread, the pty, a wake-up)
        "to_board_mean_ms": round(statistics.fmean(pty_part), 2) if pty_part else None,
        # the rest: the frame on the board's UART at 115200 baud (15 bytes, 1.30 ms), waiting for the loop, the
        # parse task, the motors' recompute (or the next control step)
        "board_mean_ms": round(statistics.fmean(lat) - statistics.fmean(pty_part), 2) if pty_part else None,
        "by_parse_pct": round(100 * by_task.count("parse") / len(by_task), 1),
        "events": args.events,
        "policy": args.policy,
        "control_hz": 400 if args.raw else 200,
        "baud": 115200,
        "report_mean_ms": 23.4,
        "goal_mean_ms": 3.0,
        "cpus": os.cpu_count(),
    }
    if report_lat:
        out.update({
            "report_board_mean_ms": round(statistics.fmean(report_lat), 2),
            "report_board_p50_ms": round(pct(report_lat, 50), 2),
            "report_board_p99_ms": round(pct(report_lat, 99), 2),
            "report_board_n": len(report_lat),
            "report_board_by_parse_pct": round(100 * report_by_parse, 1),
            "report_board_pc_sample_ms": REPORT_PC_SAMPLE_S * 1e3,
        })
    print(json.dumps(out))
    return 0


REPORT_PC_SAMPLE_S = 0.010  # the report's PC read the joystick every 10 ms (section 4.3)
_saved: dict[str, list[Any]] = {}


def _run(args: argparse.Namespace, preset: str, pc_sample_s: float) -> list[float]:
    """One board (with ``preset``) measured; the per-event parts of the first run are kept for the main keys."""
    board = BoardChild(args.seed, preset, args.link)
    try:
        lat = asyncio.run(measure(board.path, board, args.events, args.policy, args.seed, args.raw, pc_sample_s))
    finally:
        board.stop()
    if not _saved:
        _saved.update(term=list(term_part), pty=list(pty_part), task=list(by_task))
    return lat


def _restore() -> None:
    term_part[:], pty_part[:], by_task[:] = _saved["term"], _saved["pty"], _saved["task"]


if __name__ == "__main__":
    sys.exit(main())
