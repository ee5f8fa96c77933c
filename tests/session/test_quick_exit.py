"""Quitting does not wait on the interpreter's teardown (issue 22: Ctrl+Q took 3-4 s, once 22 s): the `term`
command, `python -m term` and the simulated board's child end with term.session.quick_exit.exit_now once the
work is done, which keeps what an orderly exit promises (atexit handlers, stdout and stderr flushed, the exit
code) and skips freeing every object one by one. A process with a non-daemon thread still running exits as
usual."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

from tests.support.paths import ROOT

# An object whose finaliser runs only in the interpreter's teardown, and an atexit handler, around the entry point.
PROBE = """
import atexit, sys
class Teardown:
    def __del__(self):
        sys.stderr.write("teardown ran\\n")
probe = Teardown()
atexit.register(lambda: sys.stderr.write("atexit ran\\n"))
sys.stdout.write("buffered, not yet flushed")
"""


def _run(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", PROBE + code, *args], capture_output=True, text=True, timeout=60,
                          cwd=ROOT)


def test_the_term_command_ends_without_the_interpreters_teardown(tmp_path: Path) -> None:
    res = _run("sys.argv = ['term', '--config-path', '--config', sys.argv[1]]\n"
               "from term.cli.main import run\nrun()", str(tmp_path / "my.toml"))
    assert res.returncode == 0, res.stderr
    assert res.stdout == f"buffered, not yet flushed{tmp_path / 'my.toml'}\n"
    assert "atexit ran" in res.stderr and "teardown ran" not in res.stderr


def test_the_exit_code_is_kept_and_a_usage_error_still_says_its_line(tmp_path: Path) -> None:
    res = _run("sys.argv = ['term', 'export', sys.argv[1], '-o', sys.argv[1] + '.csv']\n"
               "from term.cli.main import run\nrun()", str(tmp_path / "missing.mcap"))
    assert res.returncode == 2 and "not found" in res.stderr
    assert "atexit ran" in res.stderr and "teardown ran" not in res.stderr


def test_a_running_non_daemon_thread_gets_the_normal_exit() -> None:
    res = _run("import threading, time\n"
               "t = threading.Thread(target=lambda: (time.sleep(0.2), sys.stderr.write('thread done\\n')))\n"
               "t.start()\n"
               "from term.session.quick_exit import exit_now\nexit_now(5)")
    assert res.returncode == 5
    assert "thread done" in res.stderr and "atexit ran" in res.stderr and "teardown ran" in res.stderr


def test_every_entry_point_uses_it() -> None:
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["term"] == "term.cli.main:run"
    assert "run()" in (ROOT / "term" / "__main__.py").read_text()
    from term.session.sim import SimBoard

    assert SimBoard().cmd[1:3] == ["-m", "fcb_sim"]  # the simulated board's child: fcb-sim's own entry ...
    assert "os._exit(code)" in (ROOT / "fcb_sim" / "__main__.py").read_text()  # ... which ends without teardown
