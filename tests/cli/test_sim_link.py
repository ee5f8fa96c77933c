"""`--sim-link`: the simulated board's cable chosen on the command line (pty where there are pseudo-terminals, tcp
anywhere), for flying and for `term params --sim`; its misuse is one line."""

from __future__ import annotations

import pytest

from term.cli.main import main
from term.session.sim import SimBoard, pty_missing


def test_params_over_the_tcp_link(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "--sim", "--sim-link", "tcp", "get", "ctrl.p1"]) == 0
    assert capsys.readouterr().out.split()[0] == "ctrl.p1"


@pytest.mark.parametrize("argv, words", [
    (["--sim-link", "tcp", "--serial", "/dev/null"], "--sim-link needs --sim"),
    (["--sim", "--sim-link", "serial"], "argument --sim-link: invalid choice: 'serial'"),
    (["params", "--sim-link", "tcp", "list"], "--sim-link needs --sim"),
])
def test_misuse_is_one_line(argv: list[str], words: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("term: ") and words in err and err.count("\n") == 1, err


def test_the_platform_chooses_the_link_and_a_missing_pty_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    assert SimBoard().link == ("tcp" if pty_missing() else "pty")
    assert SimBoard(link="tcp").cmd[3:6] == ["serve", "--tcp", "127.0.0.1:0"]
    monkeypatch.setattr("sys.platform", "win32")
    assert pty_missing() == "Windows has no pseudo-terminals"
    assert SimBoard().link == "tcp"
    with pytest.raises(Exception, match="--sim-link pty: Windows has no pseudo-terminals; use --sim-link tcp"):
        SimBoard(link="pty")
