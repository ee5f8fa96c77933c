"""`term` on the command line: help, one clear line and a non-zero exit for every user error, `term plot`."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fcb_sim.flash_log import LOG_VARS, encode_log
from term.cli import main
from term.logfile import decode_to_rows, write_csv


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_help_lists_everything() -> None:
    out = subprocess.run([sys.executable, "-m", "term.cli", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    for word in ("--serial", "--baud", "--sim", "--seed", "--scenario", "--ble", "--hci", "term plot", "term scan",
                 "--config", "--no-joystick", "--log-dir"):
        assert word in out.stdout


@pytest.mark.parametrize("argv, words", [
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--serial", "/dev/does-not-exist-42"], "serial port /dev/does-not-exist-42 not found"),
    (["--serial", "/dev/null", "--sim"], "not allowed with argument"),
    (["--scenario", "gusty"], "--scenario needs --sim"),
    (["--baud", "0", "--serial", "/dev/null"], "--baud must be positive"),
    (["--baud", "fast"], "invalid int value"),
    (["--link-timeout", "-1", "--serial", "/dev/null"], "--link-timeout must be positive"),
    (["plot", "nope.csv", "-o", "x.png"], "nope.csv not found"),
    (["plot", "x.csv"], "required: -o/--output"),
    (["--config", "/nonexistent/term.toml", "--sim"], "config file /nonexistent/term.toml not found"),
])
def test_user_errors_are_one_line_and_non_zero(capsys: pytest.CaptureFixture[str], argv: list[str],
                                               words: str) -> None:
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert words in err and err.startswith("term: ") and err.count("\n") == 1, err
    assert "Traceback" not in err


def test_a_simulated_board_that_does_not_start(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "--sim", "--scenario", "nope", "--no-joystick")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("term: the simulated board did not start: unknown scenario 'nope'; choose one of: bench")


def test_no_port_anywhere(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cfg = tmp_path / "term.toml"
    cfg.write_text("[plots]\nwindow = 5\n")
    code, _, err = run(capsys, "--config", str(cfg))
    assert code == 2 and "no board given" in err and err.count("\n") == 1


def test_a_malformed_config_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cfg = tmp_path / "term.toml"
    cfg.write_text("[connection]\nbaud = 'fast'\n")
    code, _, err = run(capsys, "--config", str(cfg), "--serial", "/dev/null")
    assert code == 2 and f"config file {cfg}: [connection] baud must be int" in err and err.count("\n") == 1


def test_a_path_that_is_not_a_serial_port(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = run(capsys, "--serial", str(tmp_path), "--no-joystick")
    assert code == 2 and "is not a serial port" in err and err.count("\n") == 1


def test_config_path(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--config-path")
    assert code == 0 and out.strip().endswith("term.toml")


def _log_csv(tmp_path: Path) -> Path:
    n = len(LOG_VARS)
    rows = []
    for i in range(400):
        row = [0] * n
        row[0] = i * 2500  # t_us at 400 Hz
        row[2] = (i * 7) % 500  # phi
        row[11:15] = [400 + i % 9] * 4  # motors
        row[17] = 1150  # battery
        rows.append(row)
    path = tmp_path / "log.csv"
    write_csv(encode_log(rows), path, decode_to_rows)
    return path


def test_plot_draws_a_downloaded_log(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out_png = tmp_path / "out" / "flight.png"
    code, out, err = run(capsys, "plot", str(_log_csv(tmp_path)), "-o", str(out_png))
    assert code == 0, err
    assert out_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out_png.stat().st_size > 10_000


def test_plot_chosen_signals_and_unknown_ones(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    log = _log_csv(tmp_path)
    code, _, _ = run(capsys, "plot", str(log), "-o", str(tmp_path / "a.svg"), "--signals", "phi,ae1")
    assert code == 0 and b"<svg" in (tmp_path / "a.svg").read_bytes()[:400]
    code, _, err = run(capsys, "plot", str(log), "-o", str(tmp_path / "b.png"), "--signals", "warp")
    assert code == 2 and "no column 'warp'" in err


def test_plot_refuses_a_raw_hex_log(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    raw = tmp_path / "raw.csv"
    write_csv(b"\x01\x02" * 30, raw, decode_to_rows)  # not the board's format: the hex fallback
    code, _, err = run(capsys, "plot", str(raw), "-o", str(tmp_path / "r.png"))
    assert code == 2 and "raw log bytes" in err


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as f:
            return any(line.startswith("State:") and "Z" in line for line in f)  # a zombie has exited
    except FileNotFoundError:
        return True


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_the_simulated_board_dies_with_term_even_when_term_is_killed() -> None:
    import time

    code = ("import os, signal\n"
            "from term.cli import SimBoard\n"
            "s = SimBoard(); path = s.start()\n"
            "print(s.proc.pid, path, flush=True)\n"
            "os.kill(os.getpid(), signal.SIGKILL)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    pid_text, path = out.stdout.split()
    assert path.startswith("/dev/pts/") and out.returncode == -9
    deadline = time.monotonic() + 10
    while not _gone(int(pid_text)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _gone(int(pid_text))


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_term_ends_with_its_terminal_and_stops_the_board() -> None:
    """A terminal closed without a SIGHUP reaching term (its session leader ignores it, as under tmux here):
    term sees the hang-up, exits in order as for SIGHUP, and the simulated board goes with it."""
    import fcntl
    import select
    import struct
    import termios
    import time

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "term.cli", "--sim", "--no-joystick", "--no-radio"],
                            stdin=slave, stdout=slave, stderr=slave, start_new_session=True,
                            env={**os.environ, "TERM": "xterm-256color"})
    os.close(slave)
    board: list[int] = []
    drawn = b""
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (board and b"link" in drawn):
            if select.select([master], [], [], 0.1)[0]:
                drawn = (drawn + os.read(master, 65536))[-200_000:]  # keep draining: term must never block
            board = _children(proc.pid)
        assert board and b"link" in drawn, "term --sim did not come up"
    finally:
        os.close(master)  # the terminal goes away
    assert proc.wait(timeout=20) == 128 + 1  # as SIGHUP
    deadline = time.monotonic() + 10
    while not all(_gone(b) for b in board) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(b) for b in board)


async def test_a_board_with_another_protocol_version_is_one_line_and_exit_3(pty_pair, scripted_board) -> None:  # noqa: ANN001
    """The whole path: `term --serial PTY` in a real terminal (`script` gives it one) against a board that
    answers Hello with protocol v99."""
    import asyncio
    import shutil
    import time

    from tests.conftest import PtyBoard

    if shutil.which("script") is None:
        pytest.skip("needs script(1) to give term a terminal")
    master, path = pty_pair
    board = PtyBoard(master, scripted_board(protocol=99, start=time.monotonic()), time.monotonic)
    await board.start()
    try:
        proc = await asyncio.create_subprocess_exec(
            "script", "-qec", f"{sys.executable} -m term.cli --serial {path} --no-joystick", "/dev/null",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, stdin=asyncio.subprocess.DEVNULL,
            env={**os.environ, "TERM": "xterm-256color", "COLUMNS": "120", "LINES": "40"},
        )
        out, _ = await asyncio.wait_for(proc.communicate(), 30)
    finally:
        await board.stop()
    text = out.decode(errors="replace")
    assert proc.returncode == 3, text[-500:]
    last = [ln for ln in text.replace("\r", "\n").splitlines() if ln.strip()][-1]
    import re

    last = re.sub(r"\x1b(\[[0-9;?<>=$]*[a-zA-Z~]|\][^\x07\x1b]*(\x07|\x1b\\)?)", "", last)  # the screen given back
    assert last.strip() == ("term: board speaks protocol v99, this terminal v1: update the board's firmware or "
                            "the terminal")
    assert text.count("board speaks protocol") == 1 and "Traceback" not in text
