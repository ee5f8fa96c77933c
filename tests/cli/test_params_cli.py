"""`term params` against a served board (fcb-sim serve --pty in a child process, a real pseudo-terminal): list,
get, set (accepted and refused, with the board's reason), save, load, diff; bad input is one line and exit 2."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from term.cli.main import main
from term.core.protocol import PARAMS
from term.session.sim import SimBoard


@pytest.fixture(scope="module")
def port() -> Iterator[str]:
    sim = SimBoard(seed=1)
    try:
        yield sim.start()
    finally:
        sim.stop()


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, list[str], str]:
    code = main(["params", *args])
    out, err = capsys.readouterr()
    return code, out.splitlines(), err


def test_list_prints_one_parameter_a_line(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, lines, _ = run(capsys, "--serial", port, "list")
    assert code == 0 and len(lines) == len(PARAMS)
    p1 = next(x for x in lines if " ctrl.p1 " in x)
    assert p1.split() == ["ctrl.p1", "0.4", "LSB/LSB", "(default", "0.4)"]
    assert any(x.split()[:2] == ["link.timeout_ms", "500"] for x in lines)


def test_set_get_and_a_refusal_with_the_boards_reason(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(capsys, "--serial", port, "set", "ctrl.p2", "120")[:2] == (0, ["ctrl.p2 = 120"])
    code, lines, _ = run(capsys, "--serial", port, "get", "ctrl.p2")
    assert code == 0 and lines[0].startswith("* ctrl.p2") and "120" in lines[0]
    # a log in the flash: the scheme may not change (the board's own rule, LOG_BUSY)
    _flash_some_log(port)
    code, lines, _ = run(capsys, "--serial", port, "set", "log.scheme", "delta8")
    assert code == 1 and lines == ["log.scheme: refused: log is busy"]
    assert run(capsys, "--serial", port, "set", "ctrl.p2", "111")[0] == 0


def _flash_some_log(port: str) -> None:
    """Start and stop the board's log over the same port, so the flash holds a little."""
    import asyncio

    from term.core.protocol import Op
    from term.session.param_client import ParamClient
    from term.transports.serial import SerialTransport

    async def go() -> None:
        from term.core.link import LinkSession
        from term.session.connection import Connection

        loop = asyncio.get_running_loop()
        conn = Connection(SerialTransport(port), LinkSession(loop.time()), loop.time)
        await conn.start()
        try:
            client = ParamClient(conn)
            await client.command(Op.LOG_START)
            await asyncio.sleep(0.2)
            await client.command(Op.LOG_STOP)
        finally:
            await conn.stop()

    asyncio.run(go())


def test_save_load_and_diff(port: str, capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    saved = tmp_path / "board.toml"
    code, lines, _ = run(capsys, "--serial", port, "save", str(saved))
    assert code == 0 and lines == [f"wrote {saved}: {len(PARAMS)} parameters"]
    assert run(capsys, "--serial", port, "diff", str(saved))[:2] == (0, [])
    mine = tmp_path / "mine.toml"
    mine.write_text("[ctrl]\np1 = 0.45\nyaw_p = 850.0\n", encoding="utf-8")
    code, lines, _ = run(capsys, "--serial", port, "diff", str(mine))
    assert code == 1 and lines == ["ctrl.p1: board 0.4, file 0.45", "ctrl.yaw_p: board 800, file 850"]
    code, lines, _ = run(capsys, "--serial", port, "load", str(mine))
    assert code == 0 and lines == ["ctrl.p1 = 0.45", "ctrl.yaw_p = 850", "2 of 2 parameters as in the file"]
    assert run(capsys, "--serial", port, "diff", str(mine))[:2] == (0, [])
    assert run(capsys, "--serial", port, "load", str(saved))[0] == 0  # back as it was
    assert run(capsys, "--serial", port, "diff", str(saved))[:2] == (0, [])


@pytest.mark.parametrize("args, words", [
    (["set", "ctrl.p1", "nan"], "ctrl.p1 must be a number from 0 to 10"),
    (["set", "ctrl.p11", "0.4"], "did you mean 'ctrl.p1'"),
    (["set", "ctrl.p1"], "usage: term params set NAME VALUE"),
    (["lst"], "unknown action 'lst' (did you mean 'list'?)"),
    (["load", "/nonexistent/x.toml"], "cannot read parameter file"),
    (["save", "/nonexistent/dir/x.toml"], "no directory /nonexistent/dir"),
])
def test_bad_input_is_one_line_before_the_link(port: str, capsys: pytest.CaptureFixture[str], args: list[str],
                                               words: str) -> None:
    code, lines, err = run(capsys, "--serial", port, *args)
    assert code == 2 and not lines and words in err and err.count("\n") == 1


def test_no_board_and_a_preset_without_sim(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = run(capsys, "--config", str(tmp_path / "none.toml"), "list")
    assert code == 2 and "config file" in err
    code, _, err = run(capsys, "--serial", "/dev/null", "--preset", "report", "list")
    assert code == 2 and err == "term: --preset needs --sim (a real board keeps its parameters: 'term params load " \
                               "FILE')\n"


def test_the_simulated_report_board(capsys: pytest.CaptureFixture[str]) -> None:
    code, lines, _ = run(capsys, "--sim", "--preset", "report", "list")
    assert code == 0
    shown = {x.split()[1 if x.startswith("*") else 0]: x for x in lines}
    assert shown["est.attitude"].startswith("*") and "complementary" in shown["est.attitude"]
    assert shown["est.height"].startswith("*") and not shown["ctrl.p1"].startswith("*")


def _children() -> set[int]:
    """This process's live children (Linux's /proc: the ppid is the fourth field of /proc/PID/stat)."""
    import os

    found = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == os.getpid() and fields[0] != "Z":
                found.add(int(d.name))
    return found


def test_the_simulated_board_boots_while_the_config_is_read(capsys: pytest.CaptureFixture[str],
                                                            monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """`term params --sim` starts the child first and reads the config (Textual's key names: a fifth of a second)
    while the board boots on the other core; a bad config still stops the child."""
    from term.session import config

    before = _children()
    seen: list[set[int]] = []
    real = config.load_config

    def load_config(*args: object, **kwargs: object) -> object:
        seen.append(_children() - before)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(config, "load_config", load_config)
    code, lines, _ = run(capsys, "--sim", "list")
    assert code == 0 and len(lines) == len(PARAMS)
    assert len(seen) == 1 and len(seen[0]) == 1, "the board's child was not running while the config was read"
    code, _, err = run(capsys, "--sim", "--config", str(tmp_path / "none.toml"), "list")
    assert code == 2 and "config file" in err
    assert len(seen) == 2 and seen[1] and _children() - before == set()
