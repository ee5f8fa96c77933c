"""A long session written as term records one, at full telemetry: the long-work tests and bench.long_work."""

from __future__ import annotations

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
