"""`fcb-sim` options at their worst (nan, inf, negative, huge, wrong type, missing files and folders): one line on
stderr and exit 2, never a traceback or argparse's usage block."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from fcb_sim.cli import main
from tests.support.paths import EXCERPT

DATA = EXCERPT


def run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's refusals end here, as they do for the installed command
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


@pytest.mark.parametrize("argv, words", [
    ([], "fcb-sim: the following arguments are required: COMMAND (see fcb-sim --help)"),
    (["fly"], "invalid choice: 'fly'"),
    (["run", "--bogus"], "unrecognized arguments: --bogus"),
    (["run", "--duration", "abc"], "fcb-sim run: argument --duration: invalid float value: 'abc'"),
    (["run", "--duration", "nan"], "--duration must be between"),
    (["run", "--duration", "inf"], "--duration must be between"),
    (["run", "--duration=-5"], "--duration must be between"),
    (["run", "--duration", "1e400"], "--duration must be between"),
    (["run", "--seed", "1.5"], "invalid int value: '1.5'"),
    (["run", "--scenario", "nosuch"], "unknown scenario 'nosuch'"),
    (["profile", "--seconds", "nan"], "--seconds must be between"),
    (["profile", "--seconds=-1"], "--seconds must be between"),
    (["profile", "--mode", "fast"], "invalid choice: 'fast'"),
    (["serve", "--pty", "--link-timeout", "nan"], "--link-timeout must be between 0.05 and 60 s, got nan"),
    (["serve", "--pty", "--link-timeout", "0"], "--link-timeout must be between"),
    (["serve", "--pty", "--link-timeout", "1e400"], "got inf"),
    (["serve", "--pty", "--scenario", "nosuch"], "unknown scenario 'nosuch'"),
    (["serve", "--seed", "x"], "invalid int value: 'x'"),
    (["replay-imu", "/nonexistent-42.csv", "--out", "-"], "/nonexistent-42.csv: no such file"),
    (["replay-imu", str(DATA), "--out", "/nonexistent-42/o.csv"], "/nonexistent-42/o.csv: cannot write"),
    (["replay-imu", str(DATA), "--filter", "nosuch", "--out", "-"], "unknown filter 'nosuch'"),
])
def test_bad_options_are_one_line(capsys: pytest.CaptureFixture[str], argv: list[str], words: str) -> None:
    code, err = run(capsys, argv)
    assert code == 2 and err.startswith("fcb-sim") and words in err and err.count("\n") == 1, err


@pytest.mark.parametrize("content, words", [
    ("t,gx,gy,gz,ax,ay,az\n0,nan,0,0,0,0,9.8\n", "non-finite"),
    ("t,gx,gy,gz,ax,ay,az\n0,1,0\n", "too few fields"),
    ("a,b,c\n1,2\n", "missing column"),
])
def test_a_bad_imu_csv_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path, content: str,
                                   words: str) -> None:
    path = tmp_path / "imu.csv"
    path.write_text(content, encoding="utf-8")
    code, err = run(capsys, ["replay-imu", str(path), "--out", str(tmp_path / "out.csv")])
    assert code == 2 and words in err and err.count("\n") == 1, err


def test_a_port_out_of_range_for_the_radio_is_one_line() -> None:
    """It was an OverflowError traceback from bind(); run as a user runs it (the board opens its pty first)."""
    exe = str(Path(sys.executable).with_name("fcb-sim"))
    out = subprocess.run([exe, "serve", "--pty", "--ble-hci", "tcp-server:127.0.0.1:99999"], capture_output=True,
                         text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert out.returncode == 2, out
    assert out.stderr.count("\n") == 1 and "PORT 0 to 65535" in out.stderr, out.stderr
