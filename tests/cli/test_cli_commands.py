"""`term`'s commands as one argparse parser (term/cli/parser.py, issue 25): every command is listed in --help,
-v and --version are taken before and after a command, options shared with a command may stand on either side,
a flying option before another command is refused, the choices completion offers; the screens refuse to start
without a terminal; TERM=dumb gets no 24-bit colour."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from term.cli.main import main
from term.cli.parser import COMMANDS, build_parser, builtin_lessons, check_command, version_text
from term.core.protocol import PRESETS, SIM_SCENARIOS

TERM = str(Path(sys.executable).with_name("term"))


def parse(*argv: str) -> argparse.Namespace:
    p = build_parser()
    args = p.parse_args(list(argv))
    check_command(p, args)
    return args


def test_help_lists_every_command_with_a_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    out = capsys.readouterr().out
    for name in ("plot", "scan", "export", "recordings", "replay", "params"):
        assert re.search(rf"^    {name} +\S", out, re.M), (name, out)
    for option in ("--serial", "--ble", "--sim", "-v, --verbose", "--version"):
        assert option in out
    assert set(COMMANDS) == {"plot", "scan", "export", "recordings", "replay", "params"}


@pytest.mark.parametrize("command", [
    ["plot", "x.csv", "-o", "x.png"], ["scan"], ["export", "x.mcap", "-o", "x.csv"], ["recordings"],
    ["replay", "x.mcap"], ["params", "--sim", "list"],
])
def test_verbose_before_and_after_every_command(command: list[str]) -> None:
    assert parse(*command).verbose is False
    assert parse("-v", *command).verbose is True
    assert parse(*command, "-v").verbose is True
    assert parse(command[0], "--verbose", *command[1:]).verbose is True
    assert parse().verbose is False and parse("-v").verbose is True  # flying


@pytest.mark.parametrize("argv", [["--version"], ["plot", "--version"], ["scan", "--version"], ["--version", "scan"],
                                  ["params", "--version"], ["replay", "--version"], ["recordings", "--version"],
                                  ["export", "--version"]])
def test_version_everywhere(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(argv)
    assert stop.value.code == 0 and capsys.readouterr().out == f"term {version_text()}\n"


def test_options_shared_with_a_command_stand_on_either_side() -> None:
    before, after = parse("--sim", "--seed", "7", "params", "list"), parse("params", "--sim", "--seed", "7", "list")
    assert (before.sim, before.seed, before.command) == (after.sim, after.seed, after.command) == (True, 7, "params")
    assert parse("params", "list").seed == 1 and parse("params", "list").sim is False  # the defaults still hold
    assert parse("--config", "a.toml", "replay", "x.mcap").config == Path("a.toml")
    assert parse("replay", "x.mcap", "--config", "b.toml").config == Path("b.toml")


@pytest.mark.parametrize("argv, words", [
    (["--sim", "plot", "x.csv", "-o", "x.png"], "--sim is an option of flying, not of 'term plot'"),
    (["--no-joystick", "recordings"], "--no-joystick is an option of flying, not of 'term recordings'"),
    (["--scenario", "gusty", "params", "--sim", "list"], "--scenario is an option of flying, not of 'term params'"),
    (["--sim", "params", "--serial", "/dev/null", "list"], "--sim brings its own board: not with --serial or --ble"),
    (["--preset", "nope", "--sim"], "argument --preset: invalid choice: 'nope'"),
    (["--scenario", "calm", "--sim"], "argument --scenario: invalid choice: 'calm'"),
    (["nonsense"], "argument COMMAND: invalid choice: 'nonsense'"),
    (["--ble", "nonsense"], "--ble 'nonsense' is not a Bluetooth address"),
    (["params", "--ble", "nonsense", "list"], "--ble 'nonsense' is not a Bluetooth address"),
])
def test_refusals_are_one_line(argv: list[str], words: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("term: ") and words in err and err.count("\n") == 1, err


@pytest.mark.parametrize("address", ["F0:5A:00:00:00:01", "f0:5a:00:00:00:0a", "2B1F7A0C-5B0E-4C8D-9A11-0123456789AB"])
def test_bluetooth_addresses_as_the_platforms_name_them(address: str) -> None:
    from term.cli.main import _check_ble_address

    _check_ble_address(address)  # no error: BlueZ and Windows name six hex pairs, macOS a UUID


def test_the_choices_completion_offers() -> None:
    actions = {a.dest: a for a in build_parser()._actions}
    assert list(actions["preset"].choices) == sorted(PRESETS)
    assert tuple(actions["scenario"].choices) == SIM_SCENARIOS
    lessons = actions["lesson"].completer()  # type: ignore[attr-defined]
    assert lessons == builtin_lessons() and "1" in lessons and lessons["1"] == "arm"


def test_the_simulators_scenarios_are_the_protocols() -> None:
    from fcb_sim.hosts.serve import SCENARIOS

    assert tuple(SCENARIOS) == SIM_SCENARIOS


def test_the_built_in_lessons_are_what_completion_offers() -> None:
    from term.input.keymap import DEFAULT_KEYMAP
    from term.lessons.spec import load_lessons

    lessons, skipped = load_lessons((), [b.action.name for b in DEFAULT_KEYMAP])
    assert not skipped and sorted(map(str, lessons)) == sorted(builtin_lessons())


# --- no terminal, no screen ----------------------------------------------------------------------------------


@pytest.mark.parametrize("argv", [["--sim", "--no-joystick"], ["--serial", "/dev/null"], ["--sim", "--demo"]])
def test_no_terminal_no_screen(argv: list[str], tmp_path: Path) -> None:
    """Issue 25: `term --sim < /dev/null > file` drew the whole TUI into the file and ran until killed. Now one
    line, exit 2, before anything starts (no simulated board: it would log its start to QUADRUPEL_LOG_DIR)."""
    out = subprocess.run([TERM, *argv], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60,
                         env={**os.environ, "QUADRUPEL_LOG_DIR": str(tmp_path)})
    assert out.returncode == 2 and out.stdout == "", out
    assert out.stderr.startswith("term: no terminal: the screen needs one on stdin and stdout")
    assert out.stderr.count("\n") == 1 and not (tmp_path / "fcb-sim.log").exists()


def test_no_terminal_no_replay(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from term.data.recording import SessionRecorder
    from term.session.model import Model
    from tests.support.recording_rig import live_session

    rec = SessionRecorder(tmp_path, 0.0, wall_ns=0)
    live_session(rec, Model(), 0.0)
    rec.close()
    path = rec.path
    assert path is not None
    assert main(["replay", str(path)]) == 2  # pytest's stdin is no terminal
    err = capsys.readouterr().err
    assert err.startswith("term: no terminal: ") and err.count("\n") == 1


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a pty")
def test_a_dumb_terminal_gets_no_24_bit_colour() -> None:
    """Issue 25: TERM=dumb still got 24-bit colour (Textual draws in truecolor when it detects no colour system)."""
    import fcntl
    import select
    import struct
    import termios

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    env = {k: v for k, v in os.environ.items() if k not in ("NO_COLOR", "COLORTERM", "TEXTUAL_COLOR_SYSTEM")}
    proc = subprocess.Popen([TERM, "--sim", "--no-joystick", "--no-radio", "--no-record"], stdin=slave,
                            stdout=slave, stderr=slave, start_new_session=True, env={**env, "TERM": "dumb"})
    os.close(slave)
    drawn = b""
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and b"link OK" not in drawn:
            if select.select([master], [], [], 0.1)[0]:
                try:
                    drawn += os.read(master, 65536)
                except OSError:
                    break
    finally:
        proc.terminate()
        proc.wait(timeout=20)
        os.close(master)
    assert b"link OK" in drawn, drawn[-400:]
    assert not re.search(rb"\x1b\[[0-9;]*[34]8;[25];", drawn)  # neither 24-bit nor 256 colours


def test_fcb_sim_takes_verbose_and_version_after_its_command_too(capsys: pytest.CaptureFixture[str]) -> None:
    from fcb_sim.cli import build_parser as fcb_sim_parser

    p = fcb_sim_parser()
    assert p.parse_args(["-v", "run"]).verbose and p.parse_args(["run", "-v"]).verbose
    assert p.parse_args(["serve"]).verbose is False
    for argv in (["--version"], ["serve", "--version"], ["profile", "--version"]):
        with pytest.raises(SystemExit):
            p.parse_args(argv)
        assert capsys.readouterr().out.startswith("fcb-sim ")


def test_the_version_is_read_only_when_asked_for() -> None:
    """Reading the installed package's metadata costs a start-up some 40 ms of CPU (term's and its simulated
    board's, a second of waiting on a busy machine): the parsers ask for it only when --version is given."""
    code = ("import sys; from term.cli.parser import build_parser; from fcb_sim.cli import build_parser as sim\n"
            "build_parser().parse_args(['params', '--sim', 'list']); sim().parse_args(['serve', '--pty'])\n"
            "print('importlib.metadata' in sys.modules)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.stdout.strip() == "False", res.stderr
