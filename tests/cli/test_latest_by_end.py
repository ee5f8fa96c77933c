"""--latest is the session that ended last, not the one that started last (issue 34: a 1 s demo started during a
long flight was exported instead of the flight)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from term.data.recording import SessionRecorder, latest


def record(directory: Path, wall_s: float) -> Path:
    now = time.monotonic()
    rec = SessionRecorder(directory, now, wall_ns=int(wall_s * 1e9))
    rec.received("cable", b"\x00" * 8, now)
    rec.close()
    assert rec.path is not None and rec.error is None
    return rec.path


def test_latest_is_the_session_that_ended_last(tmp_path: Path) -> None:
    t0 = 1_790_000_000.0
    flight = record(tmp_path, t0)  # started first ...
    demo = record(tmp_path, t0 + 60)  # ... a short demo started during it and ended at once
    os.utime(demo, (t0 + 61, t0 + 61))
    os.utime(flight, (t0 + 600, t0 + 600))  # the flight ended ten minutes in
    assert latest(tmp_path) == flight
    os.utime(demo, (t0 + 900, t0 + 900))
    assert latest(tmp_path) == demo
