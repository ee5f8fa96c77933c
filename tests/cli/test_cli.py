"""`term` on the command line: help, one clear line and a non-zero exit for every user error, `term plot`."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fcb_sim.board.flash_log import LOG_VARS, encode_log
from term.cli.main import main
from term.core.logfile import decode_to_rows, write_csv
from term.core.protocol import PROTOCOL_VERSION


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    """As if term ran in a terminal (pytest's stdin is none): what comes after the no-terminal check is tested."""
    monkeypatch.setattr("term.cli.main.has_terminal", lambda: True)


def test_help_lists_everything() -> None:
    out = subprocess.run([sys.executable, "-m", "term.cli.main", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    for word in ("--serial", "--baud", "--sim", "--seed", "--scenario", "--ble", "--hci", "plot", "scan",
                 "--config", "--no-joystick", "--log-dir"):
        assert word in out.stdout


@pytest.mark.parametrize("argv, words", [
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--serial", "/dev/does-not-exist-42"], "serial port /dev/does-not-exist-42 not found"),
    (["--serial", "/dev/null", "--sim"], "not allowed with argument"),
    (["--scenario", "gusty"], "--scenario needs --sim"),
    (["--baud", "0", "--serial", "/dev/null"], "--baud: must be an integer between 50 and 4000000 baud, got 0"),
    (["--baud", "100000000000000000000", "--serial", "/dev/null"], "got 100000000000000000000"),
    (["--baud", "fast"], "invalid int value"),
    (["--link-timeout", "-1", "--serial", "/dev/null"], "--link-timeout: must be a number between 0.05 and 60 s"),
    (["--link-timeout", "nan", "--serial", "/dev/null"], "--link-timeout: must be a number between 0.05 and 60 s, "
                                                         "got nan"),
    (["--link-timeout", "inf", "--sim"], "got inf"),
    (["--ble-timeout", "nan", "--ble", "F0:5A:00:00:00:01"], "--ble-timeout: must be a number between 0.1 and 600 s"),
    (["scan", "--timeout=-inf"], "--timeout: must be a number between 0.1 and 600 s, got -inf"),
    (["--log-dir", "/dev/null/logs", "--sim"], "--log-dir: log folder /dev/null/logs: /dev/null is a file"),
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


def test_a_simulated_board_that_does_not_start(capsys: pytest.CaptureFixture[str], a_terminal: None,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """A scenario term offers but the board does not know (the two programs of different versions)."""
    import term.core.protocol

    monkeypatch.setattr(term.core.protocol, "SIM_SCENARIOS", (*term.core.protocol.SIM_SCENARIOS, "nope"))
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
    assert code == 2 and f"config file {cfg}: [connection] baud: must be an integer" in err and err.count("\n") == 1


def test_a_path_that_is_not_a_serial_port(capsys: pytest.CaptureFixture[str], tmp_path: Path, a_terminal: None) -> None:
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
    out_png = tmp_path / "flight.png"
    code, out, err = run(capsys, "plot", str(_log_csv(tmp_path)), "-o", str(out_png))
    assert code == 0, err
    assert out == f"wrote {out_png}\n"
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


def _edit(log: Path, tmp_path: Path, column: str, value: str, name: str = "edited.csv") -> Path:
    lines = log.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    row = lines[1].split(",")
    row[header.index(column)] = value
    out = tmp_path / name
    out.write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n", encoding="utf-8")
    return out


@pytest.mark.parametrize("make, words", [
    (lambda log, d: _write(d, "a,b,c\n1,2\n"), "is not a flight log: its header (\"a,b,c\") needs t_us"),
    (lambda log, d: _write(d, "a,b,c\n1,2,3\n"), "is not a flight log"),
    (lambda log, d: _write(d, ""), "is empty"),
    (lambda log, d: _edit(log, d, "mode", "nan"), "line 2, column mode: must be an integer between 0 and 255, "
                                                 "got \"nan\""),
    (lambda log, d: _edit(log, d, "mode", "inf"), "column mode: must be an integer"),
    (lambda log, d: _edit(log, d, "mode", "2.5"), "column mode: must be an integer"),
    (lambda log, d: _edit(log, d, "phi", "-inf"), "line 2, column phi: must be a number between"),
    (lambda log, d: _edit(log, d, "phi", "1e300"), "column phi: must be a number between"),
    (lambda log, d: _edit(log, d, "phi", "x" * 140_000), "line 2 is longer than 4096 characters"),
    (lambda log, d: _edit(log, d, "phi", '"' + "1" * 3000 + '\n' + "2" * 3000 + '"'), "column phi: must be a number"),
    (lambda log, d: _edit(log, d, "phi", "1" * 1000), "column phi: must be a number between"),
    (lambda log, d: _edit(log, d, "t_us", "-1"), "column t_us: must be an integer between 0 and"),
    (lambda log, d: _edit(log, d, "phi", "1,2"), "line 2: 20 fields, the header has 19"),
    (lambda log, d: _edit(log, d, "phi", '"1'), "not a readable CSV (unexpected end of data)"),
    (lambda log, d: _write(d, b"t_us,phi\n0,\xff\xfe\n"), "is not UTF-8 text (byte 0xff)"),
    (lambda log, d: _write(d, "t_us,phi,phi\n0,1,2\n"), "column 3 is 'phi' again"),
    (lambda log, d: _write(d, "t_us,phi\n"), "has a header but no records"),
    (lambda log, d: Path("/dev/zero"), "/dev/zero is a device, not a file"),  # refused before a byte is read
])
def test_plot_refuses_a_csv_that_is_not_a_flight_log(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                     make, words: str) -> None:  # noqa: ANN001
    """Issues 10 and 11: each of these ended in a traceback, a three-line error, or "wrote ..."."""
    bad = make(_log_csv(tmp_path), tmp_path)
    out_png = tmp_path / "p.png"
    code, out, err = run(capsys, "plot", str(bad), "-o", str(out_png))
    assert code == 2 and out == "" and not out_png.exists()
    assert err.startswith("term: ") and str(bad) in err and words in err and err.count("\n") == 1, err


def _write(tmp_path: Path, content: str | bytes) -> Path:
    p = tmp_path / "other.csv"
    if isinstance(content, bytes):
        p.write_bytes(content)
    else:
        p.write_text(content, encoding="utf-8")
    return p


@pytest.mark.parametrize("output, words", [
    ("/nonexistent-dir-42/p.png", "cannot write /nonexistent-dir-42/p.png: folder /nonexistent-dir-42 does not exist"),
    ("outfile", "outfile: the name must end in .png, .svg, .pdf"),
    ("plot.jpeg", "must end in .png, .svg, .pdf"),
    ("DIR", "is a folder: name the image"),
])
def test_plot_writes_the_file_it_names_or_nothing(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                  output: str, words: str) -> None:
    """Issue 10: -o /nonexistent/p.png created the folder; issue 11: -o outfile wrote outfile.png."""
    log = _log_csv(tmp_path)
    (tmp_path / "DIR").mkdir()
    target = output if output.startswith("/") else str(tmp_path / output)
    before = sorted(p.name for p in tmp_path.iterdir())
    code, out, err = run(capsys, "plot", str(log), "-o", target)
    assert code == 2 and out == "" and words in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before and not Path("/nonexistent-dir-42").exists()


TERM = str(Path(sys.executable).with_name("term"))


@pytest.mark.parametrize("args, files, words", [
    (["--config", "{d}/bin.toml", "--serial", "/nonexistent"], {"bin.toml": b"\xfc\x00\x9f\x92"},
     "is not UTF-8 text"),
    (["--config", "{d}/k.toml", "--serial", "/nonexistent"], {"k.toml": b"[keys]\nmode_panic = ['nosuchkey']\n"},
     "[keys] mode_panic: unknown key name 'nosuchkey'"),
    (["--link-timeout", "nan", "--serial", "/nonexistent"], {}, "--link-timeout: must be a number"),
    (["plot", "{d}/bad.csv", "-o", "{d}/p.png"], {"bad.csv": b"a,b,c\n1,2\n"}, "is not a flight log"),
])
def test_bad_input_from_the_outside_is_one_line(tmp_path: Path, args: list[str], files: dict[str, bytes],
                                                words: str) -> None:
    """The installed `term` as a user runs it: exactly one line on stderr, exit 2, nothing on stdout."""
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    argv = [a.format(d=tmp_path) for a in args]
    out = subprocess.run([TERM, *argv], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert out.returncode == 2 and out.stdout == "", out
    assert out.stderr.startswith("term: ") and out.stderr.count("\n") == 1 and words in out.stderr, out.stderr


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
            "from term.session.sim import SimBoard\n"
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
    proc = subprocess.Popen([sys.executable, "-m", "term.cli.main", "--sim", "--no-joystick", "--no-radio"],
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
            "script", "-qec", f"{sys.executable} -m term.cli.main --serial {path} --no-joystick", "/dev/null",
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
    assert last.strip() == (f"term: board speaks protocol v99, this terminal v{PROTOCOL_VERSION}: update the board's "
                            "firmware or the terminal")
    assert text.count("board speaks protocol") == 1 and "Traceback" not in text
