"""A macOS-shaped run (tests/platform/shapes/darwin: sys.platform "darwin", poll() answering POLLNVAL for
terminals, as macOS's does): `term --sim` in a real pseudo-terminal stays up while its hang-up watcher looks at the
terminal again and again, and still ends (exit 129, as for SIGHUP) when the terminal really goes away.

What this cannot show: macOS's own kernel (its pty driver's answer to a hung-up line is taken from dirge-code/dirge
#731: the ioctl fails with EIO, as Linux's does here), kqueue, CoreBluetooth, Terminal.app's signals."""

from __future__ import annotations

import os
import select
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.support.platform_shape import shaped_env

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="shapes another platform on Linux")

LOOKS = 4  # the watcher's looks at the terminal (0.5 s apart) term must outlive


def test_term_stays_up_on_a_macos_shaped_terminal_and_still_ends_with_it(tmp_path: Path) -> None:
    import fcntl
    import termios

    probes = tmp_path / "probes"
    probes.touch()
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    env = shaped_env("darwin", tmp_path, SHAPE_PROBES=str(probes), TERM="xterm-256color")
    proc = subprocess.Popen([sys.executable, "-m", "term.cli.main", "--sim", "--no-joystick", "--no-radio",
                             "--no-record"], stdin=slave, stdout=slave, stderr=slave, start_new_session=True, env=env)
    os.close(slave)
    drawn = b""
    try:
        deadline = time.monotonic() + 40
        while time.monotonic() < deadline and proc.poll() is None:
            if select.select([master], [], [], 0.1)[0]:
                try:
                    drawn = (drawn + os.read(master, 65536))[-200_000:]  # keep draining: term must never block
                except OSError:  # the terminal's other side is gone: term has ended, or is ending
                    proc.wait(10)
                    break
            if b"link" in drawn and len(probes.read_text()) >= LOOKS:
                break
        assert proc.poll() is None, f"term ended with {proc.returncode} on a macOS-shaped terminal"
        assert b"link" in drawn and len(probes.read_text()) >= LOOKS, "term --sim did not come up"
    finally:
        os.close(master)  # the terminal goes away
    try:
        assert proc.wait(timeout=20) == 128 + 1  # as SIGHUP: the hang-up is still seen there
    finally:
        if proc.poll() is None:
            proc.kill()
