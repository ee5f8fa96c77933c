"""--foxglove beyond this machine needs its own flag, as the instructor's channel does (issue 34: 0.0.0.0:PORT served
the whole flight on every interface with one line the screen covered at once); the live server's address is on
the screen while it serves."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from term.cli.main import main
from term.data.foxglove_server import LiveServer, public_refusal
from term.data.recording import SessionRecorder
from term.ui.app import TermApp
from term.ui.widgets.mode import ModeBanner


def test_a_public_address_needs_the_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    now = time.monotonic()
    rec = SessionRecorder(tmp_path / "rec", now)
    rec.received("cable", b"\x00" * 8, now)
    rec.event(now + 0.1, "info", "term", "a line")
    rec.close()
    assert rec.path is not None
    assert main(["replay", str(rec.path), "--foxglove", "0.0.0.0:0"]) == 2
    err = capsys.readouterr().err
    assert "--foxglove-public" in err and err.count("\n") == 1, err
    assert public_refusal("127.0.0.1", False) == "" and public_refusal("localhost", False) == ""
    assert public_refusal("::1", False) == "" and public_refusal("0.0.0.0", True) == ""
    assert public_refusal("192.168.1.5", False) and public_refusal("lab-pc", False)


async def test_the_live_servers_address_is_on_the_screen() -> None:
    pytest.importorskip("foxglove")
    live = LiveServer("127.0.0.1", 0, t0=time.monotonic(), start_ns=time.time_ns())
    try:
        app = TermApp(joystick=False, live=live)
        async with app.run_test(size=(120, 44)) as pilot:
            app.render_now()
            await pilot.pause(0.05)
            assert live.url in str(app.screen.query_one(ModeBanner).render())
    finally:
        live.close()
