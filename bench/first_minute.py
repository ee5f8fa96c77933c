"""The first minute of a new user: a fresh clone, `make run`, the first screen.

Clones this repository's committed HEAD into a temporary folder and runs `make run` there in a pseudo-terminal
of 120x40 (as a user's terminal: the installer draws its progress, term its screen), timing from the start to

- the first screen: term switches to the alternate screen (Textual's first draw);
- flying: the link panel says ``cable OK`` (or ``link OK``): the simulated board answers over the pty;

then quits term with Ctrl+Q and runs `make run` a second time in the same clone (everything installed: the
goal is under 3 s to the first screen). The lines `make` printed for each step are shown with their times.
The installer's cache (uv's, or pip's with INSTALLER=pip) is used as on any machine that has installed these
wheels before (a first install ever also downloads them). Prints one JSON object on its last line.

    .venv/bin/python -m bench.first_minute [--timeout S]
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import re
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import termios
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ALT_SCREEN = b"\x1b[?1049h"
ANSI = re.compile(r"\x1b\[[0-9;?]*[a-zA-Z]")
FLYING = re.compile(r"(link|cable) OK")  # the link panel: the board answers


def run_make(clone: Path, timeout: float) -> dict[str, object]:
    """`make run` in ``clone`` under a pty; seconds to the first screen and to flying, and make's own lines."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VIRTUAL_ENV", "PYTHON", "MAKE"))}
    env.update(TERM="xterm-256color", PY=env.get("PY", "python3"))
    start = time.monotonic()
    proc = subprocess.Popen(["make", "--no-print-directory", "run"], cwd=clone, stdin=slave, stdout=slave,
                            stderr=slave, start_new_session=True, env=env)
    os.close(slave)
    out = b""
    first_screen = flying = None
    steps: list[tuple[float, str]] = []
    seen = 0
    try:
        while time.monotonic() - start < timeout and flying is None:
            if select.select([master], [], [], 0.05)[0]:
                try:
                    out += os.read(master, 65536)
                except OSError:
                    break
            now = round(time.monotonic() - start, 2)
            for line in out[seen:].split(b"\n")[:-1]:  # whole lines only
                seen += len(line) + 1
                text = ANSI.sub("", line.decode(errors="replace"))
                if "make: " in text:  # (pip's progress may leave cursor codes on the line)
                    steps.append((now, text[text.index("make: "):].strip()))
            if first_screen is None and ALT_SCREEN in out:
                first_screen = now
            if FLYING.search(ANSI.sub("", out[-20000:].decode(errors="replace"))):  # (text between styles)
                flying = now
        if flying is not None:
            os.write(master, b"\x11")  # Ctrl+Q: term quits in order and stops its board
            _drain_until_exit(master, proc, 20)
    finally:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            if proc.poll() is None:
                os.killpg(proc.pid, sig)
                _drain_until_exit(master, proc, 20)
        os.close(master)
    tail = re.sub(rb"\x1b\[[0-9;?]*[a-zA-Z]", b"", out[-2000:]).decode(errors="replace")
    return {"first_screen_s": first_screen, "flying_s": flying, "steps": steps, "exit": proc.returncode,
            "tail": tail if flying is None else ""}


def _drain_until_exit(master: int, proc: subprocess.Popen[bytes], timeout: float) -> None:
    """Read what term still draws while it exits: a terminal nobody reads blocks its writes, and its exit."""
    deadline = time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < deadline:
        if select.select([master], [], [], 0.05)[0]:
            try:
                os.read(master, 65536)
            except OSError:
                time.sleep(0.05)


# What `python -m venv` puts in every venv before we install anything (pip, and setuptools on Python < 3.12), and
# the installer make adds beside pip (uv, its programs in bin/).
VENV_SEEDS = ("pip", "setuptools", "pkg_resources", "_distutils_hack", "uv")
SEED_PROGRAMS = ("uv", "uvx")


def venv_size(clone: Path) -> dict[str, float | int]:
    """The installed environment's size (MiB, bytes on disk) and its distributions, quadrupel itself included; and
    the same without the venv's own seeds (pip, setuptools) and the installer (uv), which are not ours to trim."""
    venv = clone / ".venv"
    site = next(venv.glob("lib/python3*/site-packages"))
    seeds = [site / name for name in VENV_SEEDS] + [d for s in VENV_SEEDS for d in site.glob(f"{s}-*.dist-info")]
    seeds += [venv / "bin" / name for name in SEED_PROGRAMS]
    total = _disk_bytes(venv)
    seeds_bytes = sum(_disk_bytes(p) for p in seeds if p.exists())
    dists = [d.name.split("-")[0] for d in site.glob("*.dist-info")]
    ours = [d for d in dists if d not in VENV_SEEDS]
    return {"venv_mib": round(total / 2**20, 1), "distributions": len(dists),
            "install_mib": round((total - seeds_bytes) / 2**20, 1), "install_distributions": len(ours)}


def _disk_bytes(path: Path) -> int:
    """Bytes on disk (as du counts them: whole blocks) under a file or folder."""
    files = [path] if path.is_file() else [f for f in path.rglob("*") if f.is_file() and not f.is_symlink()]
    return sum(f.stat().st_blocks * 512 for f in files)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench.first_minute", description=__doc__.split("\n")[0])
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds to wait for each run (default 300)")
    args = ap.parse_args(argv)
    if shutil.which("make") is None or shutil.which("git") is None:
        print(json.dumps({"bench": "first_minute", "error": "needs make and git"}))
        return 1
    with tempfile.TemporaryDirectory(prefix="quadrupel-first-minute-") as tmp:
        clone = Path(tmp) / "quadrupel"
        t0 = time.monotonic()
        subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
        clone_s = round(time.monotonic() - t0, 2)
        first = run_make(clone, args.timeout)
        for t, line in first["steps"]:  # type: ignore[union-attr]
            print(f"{t:7.2f} s  {line}")
        size = venv_size(clone)
        second = run_make(clone, args.timeout)
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone, capture_output=True,
                              text=True).stdout.strip()
    for name, res in (("first", first), ("second", second)):
        if res["tail"]:
            print(f"{name} make run did not reach the screen; its last output:\n{res['tail']}", file=sys.stderr)
    result = {
        "bench": "first_minute", "commit": head, "clone_s": clone_s,
        "first_run_first_screen_s": first["first_screen_s"], "first_run_flying_s": first["flying_s"],
        "second_run_first_screen_s": second["first_screen_s"], "second_run_flying_s": second["flying_s"],
        "goal_first_screen_s": 60, "goal_second_s": 3,
        **size, "goal_install_mib": 120,
    }
    print(json.dumps(result))
    return 0 if first["flying_s"] is not None and second["flying_s"] is not None else 1


if __name__ == "__main__":
    sys.exit(main())
