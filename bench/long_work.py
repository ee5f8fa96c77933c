"""Long work on a long recording: how soon a replay shows its first frame, how fast an export writes, how long a
plot takes (issue 22: "long work starts fast and shows progress").

A session of ``--minutes`` (default 60) at full telemetry is written once with the real recorder on an injected
clock (Attitude and Motion 50 Hz, Height 20 Hz, Heartbeat 10 Hz, Status and Gains 5 Hz, the sticks out at 100 Hz
and the heartbeat answers: some 250 frames a second, as ``term --sim`` records) into a cache directory, then:

- ``replay_first_frame_s``: from ``Replay.load`` to the first events of the playback in hand (goal < 2 s for an
  hour); ``replay_seek_s``: a seek to the middle and its catch-up;
- ``export_mcap_rows_per_s`` and ``export_csv_rows_per_s``: frames and events written per second of wall time by
  ``term export`` (goal >= 100 k rows/s), with the whole time of each;
- ``plot_s``: ``term plot`` of the attitude (``--signals phi,theta``) to a PNG.

    python -m bench.long_work [--minutes 60] [--cache DIR]

Prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from term.core.protocol import (
    Attitude,
    Encoder,
    Gains,
    Heartbeat,
    HeartbeatAck,
    Height,
    Joystick,
    Mode,
    Motion,
    Status,
)
from term.data.recording import SessionRecorder

WALL = 1_700_000_000_000_000_000
TICK_HZ = 100  # the sticks' rate: every other telemetry runs on a divisor of it


def write_session(directory: Path, minutes: float) -> Path:
    """A session of ``minutes`` at full telemetry, recorded as ``term`` records one (frames as whole reads)."""
    rec = SessionRecorder(directory, 0.0, wall_ns=WALL, flush_period=1.0, max_file_bytes=1 << 40,
                          max_total_bytes=1 << 42, meta={"cable": "bench", "radio": "", "primary_ble": "0"})
    rx, tx = Encoder(), Encoder()
    ticks = int(minutes * 60 * TICK_HZ)
    for i in range(ticks):
        now = i / TICK_HZ
        k = i % 1000
        pkts = []
        if i % 2 == 0:
            pkts += [Attitude(int(Mode.FULL), 1000 - k, k - 500, 9000 + k, 16 * k % 400, -k % 300, 5),
                     Motion(k, -k, -16384 + k, 400 + k % 50, 410, 390, 405)]
        if i % 5 == 0:
            pkts.append(Height(101325 - k, 150 + k % 30, 150, k % 7 - 3, 1168, 2150))
        if i % 10 == 0:
            pkts.append(Heartbeat(i // 10 % 65536, i * 10, 250))
        if i % 20 == 0:
            pkts += [Status(0, 0, 0, 0, 0, 40, k // 10, 0), Gains(0.9, 0.4, 1.1, 0.5, 0.2)]
        rec.received("cable", b"".join(rx.encode(p) for p in pkts), now)
        out = tx.encode(Joystick(k % 200 - 100, 0, 0, 300, 0))
        if i % 10 == 0:
            out += tx.encode(HeartbeatAck(i // 10 % 65536, i * 10))
        rec.sent("cable", out, now + 0.0002)
        if i % 3000 == 0:
            rec.event(now, "info", "term", f"bench note {i // 3000}")
        rec.poll(now)
    rec.close()
    assert rec.path is not None
    return rec.path


def _session(cache: Path, minutes: float) -> Path:
    d = cache / f"session-{minutes:g}min"
    found = sorted(d.glob("*.mcap"))
    if found:
        return found[0]
    return write_session(d, minutes)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench.long_work", description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "quadrupel-bench-long-work")
    a = ap.parse_args(argv)
    t = time.perf_counter()
    src = _session(a.cache, a.minutes)
    made_s = time.perf_counter() - t
    out: dict[str, float | int | str] = {"bench": "long_work", "minutes": a.minutes,
                                         "file_mb": round(src.stat().st_size / 1e6, 1), "made_s": round(made_s, 1)}

    from term.data.replay import Replay

    t = time.perf_counter()
    replay = Replay.load(src)
    first = next(iter(replay.advance(0.5)), None)
    out["replay_first_frame_s"] = round(time.perf_counter() - t, 3)
    assert first is not None, "the replay played nothing"
    t = time.perf_counter()
    if replay.seek(replay.duration / 2):
        pass
    n = sum(1 for _ in replay.catch_up())
    out["replay_seek_s"] = round(time.perf_counter() - t, 3)
    out["replay_seek_events"] = n

    from term.data.export import export

    with tempfile.TemporaryDirectory() as tmp:
        for fmt in ("mcap", "csv"):
            t = time.perf_counter()
            res = export(src, Path(tmp) / f"out.{fmt}")
            dt = time.perf_counter() - t
            out[f"export_{fmt}_s"] = round(dt, 2)
            out[f"export_{fmt}_rows_per_s"] = round(res.rows / dt)
        out["export_rows"] = res.rows

        from term.data.plot import plot_log

        t = time.perf_counter()
        plot_log(src, Path(tmp) / "plot.png", ["phi", "theta"])
        out["plot_s"] = round(time.perf_counter() - t, 2)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
