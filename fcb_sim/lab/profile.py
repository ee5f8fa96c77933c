"""The profiling bench: the board's task profile as the report measured it (section 4.2, Figure 14).

``run_profile`` calibrates the board, enters FULL (DMP path) or RAW, sends random sticks from a scripted PC at
100 Hz with logging on, and returns ``Board.profile()`` (per task: duration mean, sigma, p99, p99.9 and period
beside the report's row; the share of control periods at least WCET99 and WCET99.9). ``BytePilot`` is that PC:
the least that flies the board through its UART bytes. ``cmd_profile`` is ``fcb-sim profile``.

What the model gives and what it does not explain: docs/board.md ("The timing model") and bench/profile.py.
"""

from __future__ import annotations

import json
import math
import random
from typing import Any

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.flash_log import FLASH_BYTES
from fcb_sim.board.flight import FlightCore
from fcb_sim.board.timing import REPORT_RAW_FILTER
from fcb_sim.errors import UsageError
from fcb_sim.world.physics import World
from term.core.protocol import (
    FLIGHT_MODES,
    STICK_MAX,
    Ack,
    Command,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Joystick,
    Mode,
    Op,
)


class BytePilot:
    """The least PC that flies the board through its UART: joystick at 100 Hz, heartbeat answers, commands.
    Used by ``fcb-sim profile`` (the report profiled with a PC sending random sticks) and by tests."""

    def __init__(self, board: Board, seed: int = 1) -> None:
        self.board = board
        self.encoder = Encoder()
        self.decoder = Decoder()
        self.rng = random.Random(seed)
        self.received: list[Any] = []
        self.acks: dict[int, Ack] = {}
        self.cmd_id = 0
        self.sticks = Joystick(0, 0, 0, 0, 0)
        self.random_sticks = False

    def command(self, op: Op, arg: int = 0) -> int:
        self.cmd_id = (self.cmd_id + 1) & 0xFF
        self.board.uart_receive(self.encoder.encode(Command(self.cmd_id, int(op), arg)))
        return self.cmd_id

    def run(self, seconds: float, joystick_hz: float = 100.0) -> None:
        b = self.board
        step = int(1e6 / joystick_hz)
        end = b.now + int(seconds * 1e6)
        while b.now < end:
            # the PC's clock is not the board's: its frames arrive at an unrelated phase, with some jitter
            b.advance(b.now + self.rng.randrange(0, step // 2))
            if self.random_sticks:
                r, full = self.rng.randint, STICK_MAX
                self.sticks = Joystick(r(-full, full), r(-full, full), r(-full, full), r(0, full), 0)
            b.uart_receive(self.encoder.encode(self.sticks))
            b.advance(b.now + step // 2)
            self._read()

    def _read(self) -> None:
        for pkt in self.decoder.feed(self.board.uart_transmit()):
            self.received.append(pkt)
            if type(pkt) is Heartbeat:
                self.board.uart_receive(self.encoder.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))
            elif type(pkt) is Ack:
                self.acks[pkt.cmd_id] = pkt
        if len(self.received) > 5000:
            del self.received[:2500]


def run_profile(path: str = "raw", scheduler: str = "round-robin", seconds: float = 30.0, seed: int = 1,
                logging: bool = True, log_scheme: str = "delta8", telemetry_hz: float = 50.0,
                softdevice: bool = True, residual_jitter_us: float = 0.0,
                stick_reaction: bool = True, filter_name: str = REPORT_RAW_FILTER,
                fixed_point: bool = False) -> dict[str, Any]:
    """Profile as the report did (4.2): calibrate, enter FULL (DMP path) or RAW, random sticks from the PC,
    logging on; the props are off (motors held at zero in the world, so random sticks cannot crash it). The RAW
    path runs ``filter_name`` (default the report's, whose cost is in Figure 14's rows; another is priced by
    fcb_sim.board.timing.RAW_FILTER_EXTRA_US), in fixed point with ``fixed_point``."""
    world = World(seed)
    for i in range(1, 5):
        world.stick_motor(i, 0)  # on the bench without propellers, as a profiling run is done
    # Logging stays on for the whole run (the report logged its profile): a flash large enough to hold it, the
    # same 15 µs per byte.
    log_bytes = max(FLASH_BYTES, int(seconds * 400 * 40) + 4096)
    board = Board(BoardConfig(seed=seed, scheduler=scheduler, sensor_path=path, log_scheme=log_scheme,
                              log_bytes=log_bytes, telemetry_hz=telemetry_hz, softdevice=softdevice,
                              residual_jitter_us=residual_jitter_us, stick_reaction=stick_reaction,
                              fixed_point=fixed_point),
                  world=world, core=FlightCore(filter_name=filter_name, fixed_point=fixed_point))
    board.modes.config.tilt_limit_cdeg = 18000
    pilot = BytePilot(board, seed)
    pilot.command(Op.MODE, Mode.CALIBRATION)
    pilot.run(1.3)
    pilot.command(Op.MODE, Mode.RAW if path == "raw" else Mode.FULL)
    pilot.run(0.2)
    if board.mode not in FLIGHT_MODES:
        raise RuntimeError(f"profile: the board did not arm (mode {board.mode.name})")
    if logging:
        pilot.command(Op.LOG_START)
        pilot.run(0.1)
    board.reset_profile()
    pilot.random_sticks = True
    pilot.run(seconds)
    out = board.profile()
    out.update(seconds=seconds, seed=seed, mode=board.mode.name, log_bytes=board.log.used, log_scheme=log_scheme,
               telemetry_hz=telemetry_hz, softdevice=softdevice, residual_jitter_us=residual_jitter_us,
               stick_reaction=stick_reaction, filter=filter_name, fixed_point=fixed_point)
    return out


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.2f} %"


def cmd_profile(args: Any) -> int:
    """``fcb-sim profile --mode raw|dmp --scheduler round-robin|priority [--seconds S] [--seed N] [--json]``."""
    if not (math.isfinite(args.seconds) and 1.0 <= args.seconds <= 3600.0):
        raise UsageError(f"--seconds must be between 1 and 3600, got {args.seconds:g}")
    out = run_profile(args.mode, args.scheduler, args.seconds, args.seed,
                      log_scheme=getattr(args, "log_scheme", "delta8"))
    print(f"profile: {args.mode.upper()} path at {out['control_hz']} Hz, {args.scheduler}, "
          f"{args.seconds:g} s simulated, logging on ({out['log_scheme']}); (report, Figure 14) beside")
    print(f"{'task':10s} {'n':>7s} {'mean':>12s} {'sd':>10s} {'p99':>12s} {'p99.9':>12s} "
          f"{'period':>16s} {'period sd':>14s}  (µs)")
    for name, s in out["tasks"].items():
        r = out["report"][name]
        rsd = "?" if r["period_sd_us"] is None else f"{r['period_sd_us']:.0f}"
        print(f"{name:10s} {s['n']:7d} {s['mean_us']:5.0f} ({r['mean_us']:4.0f}) {s['sd_us']:4.0f} ({r['sd_us']:3.0f})"
              f" {s['p99_us']:5.0f} ({r['p99_us']:4.0f}) {s['p999_us']:5.0f} ({r['p999_us']:4.0f})"
              f" {s['period_us']:7.0f} ({r['period_us']:6.0f}) {s['period_sd_us']:6.0f} ({rsd:>5s})")
    print(f"control periods >= {out['deadline_us']} µs (WCET99): {_pct(out['deadline_miss_rate'])}"
          f" (report, round robin: {_pct(out['report_deadline_miss_rate'])}); >= {out['deadline_999_us']} µs"
          f" (WCET99.9): {_pct(out['deadline_miss_rate_999'])} (report: {_pct(out['report_deadline_miss_rate_999'])})")
    r = out["stick_reactions"]
    print(f"stick changes: {r['n']} motor recomputes in the parse task, {r['mean_us']:.0f} µs mean,"
          f" p99 {r['p99_us']:.0f}"
          " (in parse's durations above; the report's firmware waited for the control step)")
    if args.json:
        print(json.dumps(out))
    return 0
