"""Real-time pacing of the served board on this machine: how regularly the control step runs against the wall
clock when `fcb-sim serve --pty` paces the board (RAW path, 400 Hz), with a client on the pty sending the
joystick at 100 Hz and answering heartbeats. Prints a summary and one JSON line.

``lateness``: wall time when a control step ran minus its board time (the board's clock is paced to the wall
clock, so this is the server's wake-up latency plus the board's own work). ``wall period``: time between
consecutive control steps on the wall clock (set point 2500 µs). ``slips``: times the server fell more than
0.5 s behind and re-based its clock instead of replaying.

Run: `python -m bench.pacing [--seconds S]` (default 5).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import serial

from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.core.protocol import Decoder, Encoder, Heartbeat, HeartbeatAck, Joystick


def pct(data: list[float], q: float) -> float:
    s = sorted(data)
    return s[min(len(s) - 1, int(q * len(s)))] if s else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args()
    board = make_board(seed=1, sensor_path="raw")
    srv = ThreadedServer(board)
    path = srv.start()
    port = serial.Serial(path, 115200, timeout=0)
    enc, dec = Encoder(), Decoder()
    frames = 0
    t_end = time.monotonic() + args.seconds
    try:
        while time.monotonic() < t_end:
            port.write(enc.encode(Joystick(0, 0, 0, 0, 0)))
            for pkt in dec.feed(port.read(8192)):
                frames += 1
                if type(pkt) is Heartbeat:
                    port.write(enc.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))
            time.sleep(0.01)
    finally:
        port.close()
        srv.stop()
    p = srv.server.pacing
    late = list(p.lateness_us)
    per = list(p.wall_periods_us)
    out = {
        "bench": "pacing",
        "seconds": args.seconds,
        "control_steps": len(late),
        "wall_period_mean_us": round(statistics.fmean(per), 1) if per else None,
        "wall_period_sd_us": round(statistics.pstdev(per), 1) if per else None,
        "wall_period_p99_us": round(pct(per, 0.99), 1),
        "wall_period_max_us": round(max(per), 1) if per else None,
        "lateness_mean_us": round(statistics.fmean(late), 1) if late else None,
        "lateness_p99_us": round(pct(late, 0.99), 1),
        "lateness_max_us": round(max(late), 1) if late else None,
        "periods_over_2987us_pct": round(100 * sum(x >= 2987 for x in per) / max(1, len(per)), 2),
        "slips": p.slips,
        "wakeups_per_s": round(p.wakeups / args.seconds),
        "frames_received": frames,
        "board_s": round(board.now / 1e6, 3),
    }
    print(f"control steps {out['control_steps']} in {args.seconds:g} s; wall period {out['wall_period_mean_us']}"
          f" ± {out['wall_period_sd_us']} µs (p99 {out['wall_period_p99_us']}, max {out['wall_period_max_us']});"
          f" lateness mean {out['lateness_mean_us']} µs, p99 {out['lateness_p99_us']}, max {out['lateness_max_us']};"
          f" {out['periods_over_2987us_pct']} % of wall periods >= 2987 µs; {p.slips} slips")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
