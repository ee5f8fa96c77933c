"""Long work on a long recording: how soon a replay shows its first frame, how fast an export writes, how long a
plot takes; and how long `term params --sim list` and quitting the screens take (issue 22: "long work starts fast
and shows progress").

A session of ``--minutes`` (default 60) at full telemetry is written once with the real recorder on an injected
clock (Attitude and Motion 50 Hz, Height 20 Hz, Heartbeat 10 Hz, Status and Gains 5 Hz, the sticks out at 100 Hz
and the heartbeat answers: some 250 frames a second, as ``term --sim`` records) into a cache directory, then:

- ``replay_first_frame_s``: from ``Replay.load`` to the first events of the playback in hand (goal < 2 s for an
  hour); ``replay_seek_s``: a seek to the middle and its catch-up;
- ``export_mcap_rows_per_s`` and ``export_csv_rows_per_s``: frames and events written per second of wall time by
  ``term export`` with its progress callback (goal >= 100 k rows/s), with the whole time of each, and
  ``..._rows_per_cpu_s``: per second of this process's CPU (what a loaded machine does not blur);
- ``plot_s``: ``term plot`` of the attitude (``--signals phi,theta``) to a PNG;
- ``params_list_s``: ``term params --sim list`` from the command to its exit, the simulated board's start and
  stop included (goal < 1 s), the median of ``--runs`` (and ``_max``);
- ``quit_s``: ``term --sim`` in a 160x50 pseudo-terminal, once the link panel says the board answers and a second
  more: from Ctrl+Q to the process gone (goal < 1 s), median and max of ``--runs``.

``load`` is the load average (1 min) before and after: the machine is shared.

    python -m bench.long_work [--minutes 60] [--cache DIR] [--runs 3] [--no-cli]

Prints one JSON line.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import re
import select
import signal
import statistics
import struct
import subprocess
import sys
import tempfile
import termios
import time
from pathlib import Path

from tests.support.session_writer import write_session


def _session(cache: Path, minutes: float) -> Path:
    d = cache / f"session-{minutes:g}min"
    found = sorted(d.glob("*.mcap"))
    if found:
        return found[0]
    return write_session(d, minutes)


def _env(home: Path) -> dict[str, str]:
    """A user's environment with its own config, data and log directories (the recordings and logs land there)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("XDG_", "COLUMNS", "LINES"))}
    env.update(TERM="xterm-256color", XDG_CONFIG_HOME=str(home / "config"), XDG_DATA_HOME=str(home / "data"),
               XDG_STATE_HOME=str(home / "state"), XDG_CACHE_HOME=str(home / "cache"))
    return env


TERM_CMD = [sys.executable, "-m", "term"]
FLYING = re.compile(r"(link|cable) OK")  # the link panel: the board answers
ANSI = re.compile(r"\x1b\[[0-9;?]*[a-zA-Z]")


def params_list_s(home: Path) -> float:
    t = time.perf_counter()
    res = subprocess.run([*TERM_CMD, "params", "--sim", "list"], env=_env(home), capture_output=True, timeout=120)
    dt = time.perf_counter() - t
    assert res.returncode == 0 and b"ctrl.p1" in res.stdout, res.stderr.decode(errors="replace")
    return dt


def quit_s(home: Path, settle_s: float = 1.0, timeout: float = 120.0) -> float:
    """``term --sim`` in a 160x50 pty: seconds from Ctrl+Q (sent ``settle_s`` after the board answers) to exit."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 50, 160, 0, 0))
    proc = subprocess.Popen([*TERM_CMD, "--sim"], stdin=slave, stdout=slave, stderr=slave, env=_env(home),
                            start_new_session=True)
    os.close(slave)
    out = b""
    try:
        deadline = time.monotonic() + timeout
        flying = None
        while time.monotonic() < deadline and proc.poll() is None:
            out += _read(master, 0.05)
            if flying is None and FLYING.search(ANSI.sub("", out[-20000:].decode(errors="replace"))):
                flying = time.monotonic()
            out = out[-40000:]
            if flying is not None and time.monotonic() - flying >= settle_s:
                break
        assert flying is not None, f"term --sim never showed the link up: {ANSI.sub('', out[-2000:].decode())}"
        t = time.perf_counter()
        os.write(master, b"\x11")  # Ctrl+Q
        while proc.poll() is None and time.perf_counter() - t < timeout:
            _read(master, 0.005)  # (a terminal nobody reads blocks term's writes, and its exit)
        return time.perf_counter() - t
    finally:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            if proc.poll() is None:
                os.killpg(proc.pid, sig)
                with_deadline = time.monotonic() + 10
                while proc.poll() is None and time.monotonic() < with_deadline:
                    _read(master, 0.05)
        os.close(master)


def _read(fd: int, wait: float) -> bytes:
    if select.select([fd], [], [], wait)[0]:
        try:
            return os.read(fd, 65536)
        except OSError:
            return b""
    return b""


def _median_max(values: list[float]) -> tuple[float, float]:
    return round(statistics.median(values), 3), round(max(values), 3)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench.long_work", description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "quadrupel-bench-long-work")
    ap.add_argument("--runs", type=int, default=3, help="runs of params list and of quit (median and max)")
    ap.add_argument("--no-cli", action="store_true", help="skip params list and quit (the recording's work only)")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    t = time.perf_counter()
    src = _session(a.cache, a.minutes)
    made_s = time.perf_counter() - t
    out: dict[str, float | int | str | list[float]] = {
        "bench": "long_work", "minutes": a.minutes, "file_mb": round(src.stat().st_size / 1e6, 1),
        "made_s": round(made_s, 1)}

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
            calls: list[int] = []
            t, cpu = time.perf_counter(), time.process_time()
            res = export(src, Path(tmp) / f"out.{fmt}", progress=lambda done, total, c=calls: c.append(done))
            dt, dcpu = time.perf_counter() - t, time.process_time() - cpu
            assert len(calls) > 2, "the export said nothing of its progress"
            out[f"export_{fmt}_s"] = round(dt, 2)
            out[f"export_{fmt}_rows_per_s"] = round(res.rows / dt)
            out[f"export_{fmt}_rows_per_cpu_s"] = round(res.rows / dcpu)
        out["export_rows"] = res.rows

        from term.data.plot import plot_log

        t = time.perf_counter()
        plot_log(src, Path(tmp) / "plot.png", ["phi", "theta"])
        out["plot_s"] = round(time.perf_counter() - t, 2)

        if not a.no_cli:
            home = Path(tmp)
            out["params_list_s"], out["params_list_max_s"] = _median_max([params_list_s(home)
                                                                           for _ in range(a.runs)])
            out["quit_s"], out["quit_max_s"] = _median_max([quit_s(home) for _ in range(a.runs)])
    out["load"] = [round(load0, 2), round(os.getloadavg()[0], 2)]
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
