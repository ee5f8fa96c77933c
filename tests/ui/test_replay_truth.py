"""Replaying a `term --sim` recording shows the recorded truth in the room view (issue 34: it said "No room view: a
real board has no position" although the truth was recorded); a recording without truth still says so."""

from __future__ import annotations

import time
from pathlib import Path

from term.data.recording import SessionRecorder
from term.data.replay import Replay
from term.lessons.instructor import Truth
from term.ui.app import TermApp
from term.ui.widgets.room import NO_ROOM, RoomView


def truth(t: float, n: float) -> Truth:
    return Truth(t=t, n=n, e=0.5, h=1.2, vn=0.0, ve=0.0, vd=0.0, phi=0.0, theta=0.0, psi=0.0, p=0.0, q=0.0, r=0.0,
                 on_ground=False, volts=11.8, soc=0.9, landings=0, touchdown=0.0, crashes=0, cable=True)


def record(directory: Path, with_truth: bool) -> Path:
    now = time.monotonic()
    rec = SessionRecorder(directory, now, meta={"cable": "sim"})
    for i in range(40):
        rec.event(now + 0.05 * i, "info", "term", f"line {i}")
        if with_truth:
            rec.truth(truth(0.05 * i, -1.0 + 0.05 * i), now + 0.05 * i)
    rec.close()
    assert rec.path is not None
    return rec.path


async def test_a_sim_recording_replays_its_truth_in_the_room_view(tmp_path: Path) -> None:
    replay = Replay.load(record(tmp_path / "sim", with_truth=True))
    assert replay.has_truth
    app = TermApp(replay=replay, joystick=False)
    async with app.run_test(size=(160, 50)) as pilot:
        view = app.screen.query_one(RoomView)
        for _ in range(40):
            await pilot.pause(0.1)
            if view.room is not None and view.room.truth is not None:
                break
        assert view.room is not None and view.room.truth is not None
        app.render_now()
        await pilot.pause(0.05)
        assert NO_ROOM not in str(view.render())


async def test_a_recording_without_truth_has_no_room(tmp_path: Path) -> None:
    replay = Replay.load(record(tmp_path / "real", with_truth=False))
    assert not replay.has_truth
    app = TermApp(replay=replay, joystick=False)
    async with app.run_test(size=(160, 50)) as pilot:
        app.render_now()
        await pilot.pause(0.05)
        assert NO_ROOM in str(app.screen.query_one(RoomView).render())
