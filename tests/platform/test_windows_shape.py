"""A Windows-shaped run (tests/platform/shapes/win32: fcntl, termios, tty, pty and resource unimportable by the
project's code, no os.openpty and no SIGHUP, sys.platform "win32" where the project's code reads it): every command
reaches its work or its one-line refusal, and lesson 1 flies headless over the simulated board's TCP link (the
platform's choice there: no pseudo-terminals), its radio beside the cable, the session recorded.

What this cannot show (tests/platform/shapes/win32/sitecustomize.py says more): Windows' kernel, console, sockets,
paths and file locking, and the Windows branches of pyserial, Textual, asyncio and bumble, which run Linux's here."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.platform_shape import ROOT, shaped_env

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="shapes another platform on Linux")

IMU = ROOT / "tests" / "data" / "broad_07_fast_rotation_excerpt.csv.gz"


def shaped(home: Path, *argv: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True, timeout=timeout, cwd=home,
                          env=shaped_env("win32"), stdin=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object]]:
    """Lesson 1 flown in the shape (tests/support/shaped_lesson.py); its home, with the recording in rec/."""
    home = tmp_path_factory.mktemp("win32")
    out = shaped(home, "-m", "tests.support.shaped_lesson", str(home / "rec"), timeout=170)
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr[-2000:]
    return home, json.loads(out.stdout.strip().splitlines()[-1])


def test_a_lesson_flies_headless_over_the_tcp_link_with_the_radio_beside_it(flown: tuple[Path, dict]) -> None:
    _home, seen = flown
    assert seen["platform"] == "win32" and seen["link"] == "tcp"
    assert str(seen["port"]).startswith("socket://127.0.0.1:")
    assert seen["score"] == 100 and seen["radio"] is True
    assert Path(str(seen["recording"])).stat().st_size > 0


@pytest.mark.parametrize("argv, work", [
    (["-m", "fcb_sim", "run", "--scenario", "hover"], "attitude_rms_deg"),
    (["-m", "fcb_sim", "run", "--scenario", "hover", "--board", "python"], ""),
    (["-m", "fcb_sim", "replay-imu", str(IMU), "--out", "-"], "t,roll,pitch,yaw"),
    (["-m", "fcb_sim", "profile", "--seconds", "2"], "control periods"),
    (["-m", "fcb_sim", "serve", "--pty"], "fcb-sim: serve --pty needs pseudo-terminals, which win32 has not"),
    (["-m", "term.cli.main", "params", "--sim", "get", "ctrl.p1"], "ctrl.p1"),
    (["-m", "term.cli.main", "--sim"], "term: no terminal: the screen needs one"),
    (["-m", "term.cli.main", "--sim", "--sim-link", "pty"], "term: --sim-link pty: Windows has no pseudo-terminals"),
    (["-m", "term.cli.main", "recordings", "--dir", "rec"], "start"),
    (["-m", "term.cli.main", "export", "--latest", "--dir", "rec", "-o", "out.csv"], "wrote out.csv"),
    (["-m", "term.cli.main", "export", "--latest", "--dir", "rec", "-o", "out.mcap"], "wrote out.mcap"),
    (["-m", "term.cli.main", "plot", "--latest", "--dir", "rec", "-o", "p.png"], "p.png"),
    (["-m", "term.cli.main", "replay", "--latest", "--dir", "rec"], "term: no terminal: the screen needs one"),
], ids=lambda v: " ".join(a for a in v if not a.startswith(("-m", "/"))) if isinstance(v, list) else None)
def test_every_command_reaches_its_work_or_its_one_line_refusal(flown: tuple[Path, dict], argv: list[str],
                                                               work: str) -> None:
    home, _ = flown
    out = shaped(home, *argv)
    assert "Traceback" not in out.stderr and "ModuleNotFoundError" not in out.stderr, out.stderr[-2000:]
    if out.returncode == 0:
        assert work in out.stdout, out.stdout[-1000:]
    else:  # a refusal: exit 2 and exactly one line, the expected one where the test names it
        assert out.returncode == 2 and out.stderr.count("\n") == 1, out.stderr
        assert out.stderr.startswith(("term: ", "fcb-sim: ")) and (work in out.stderr or not work.endswith(":")), \
            out.stderr
