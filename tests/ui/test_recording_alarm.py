"""A recording that cannot be written (a read-only folder) is an alarm on the screen at once, not a line printed
behind the screen and read after quitting (issue 34): the mode banner says NOT RECORDING, the events list says why,
the alarm rings once; the flight goes on."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from term.data.recording import SessionRecorder
from term.ui.app import TermApp
from term.ui.widgets.mode import ModeBanner


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs a folder this user cannot write")
async def test_a_read_only_folder_is_an_alarm_at_once_as_user(tmp_path: Path) -> None:
    tmp_path.chmod(0o500)
    try:
        await _check(tmp_path / "rec")
    finally:
        tmp_path.chmod(0o700)


async def test_a_recording_that_failed_is_an_alarm_at_once(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the folder should be")  # fails for root too
    await _check(blocker / "rec")


async def _check(directory: Path) -> None:
    rec = SessionRecorder(directory, time.monotonic())
    assert rec.error
    app = TermApp(joystick=False, recorder=rec, config=None)
    async with app.run_test(size=(120, 44)) as pilot:
        await pilot.pause(0.1)
        app.render_now()
        await pilot.pause(0.05)
        assert "NOT RECORDING" in str(app.screen.query_one(ModeBanner).render())
        assert any(rec.error in e.text for e in app.model.events)
        assert "not recording" in app.alarms_rung
