"""Replay: station events survive the recording (JSON and back), the tap records what a transport carries, and a
replayed session brings a fresh model to the same state, with the same times, as the live one; seek and speed."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterable
from pathlib import Path

import pytest

from term.core.events import (
    CABLE,
    RADIO,
    EventsCleared,
    Fatal,
    FromLink,
    JoystickNamed,
    LinkConnecting,
    LinkDown,
    LinkFailed,
    LinkUp,
    LinkWaiting,
    Note,
    NotSent,
    Requested,
    StatsSample,
    StickSet,
)
from term.core.link import (
    CommandAcked,
    CommandFailed,
    LinkLost,
    LinkRestored,
    PacketReceived,
    VersionMismatch,
)
from term.core.protocol import Attitude, Joystick, Mode, Nak, Op
from term.data.recording import LinkBytes, RecordingTransport, SessionRecorder, decode_event, encode_event, iter_file
from term.data.replay import Replay
from term.session.model import Model
from term.transports.loopback import loopback_pair
from tests.support.recording_rig import STATS, live_session

EVENTS = [
    LinkUp(CABLE, "/dev/pts/3", False), LinkDown(RADIO, "out of range"), LinkWaiting(RADIO, "lost", 2.0),
    LinkConnecting(RADIO), LinkFailed(RADIO, "no board", True), StatsSample(CABLE, STATS),
    Requested(int(Op.MODE), int(Mode.MANUAL), CABLE), NotSent("MANUAL", "lift not at zero", "MANUAL refused"),
    Note("warning", "term", "héllo ✓"), StickSet(Joystick(1, -2, 3, 400, 1)), JoystickNamed("Pad", "xbox"),
    JoystickNamed(None, ""), EventsCleared(), Fatal("bye", 3),
    FromLink(CABLE, CommandAcked(4, Op.MODE, 2, 2)),
    FromLink(RADIO, CommandFailed(5, Op.WIRELESS, 1, "no BLE connection", Nak.NO_BLE_CONNECTION)),
    FromLink(CABLE, LinkLost(0.6)), FromLink(CABLE, LinkRestored(1.25)), FromLink(CABLE, VersionMismatch(2, 1)),
]


@pytest.mark.parametrize("ev", EVENTS, ids=lambda e: type(e).__name__)
def test_every_station_event_round_trips_through_json(ev: object) -> None:
    back = decode_event(json.loads(json.dumps(encode_event(ev))))
    assert back == ev and type(back) is type(ev)
    if isinstance(ev, FromLink) and isinstance(ev.event, CommandAcked):
        assert isinstance(back.event.op, Op)  # enums come back as enums


def test_unknown_events_are_skipped_not_fatal() -> None:
    assert decode_event({"~": "FromTheFuture", "x": 1}) is None
    assert decode_event({"~": "LinkUp", "link": "cable"}) is None  # a field missing, no default
    assert decode_event({"~packet": {"type": "Nope"}}) is None


async def test_the_tap_records_what_the_transport_carries(tmp_path: Path) -> None:
    now = [5.0]
    rec = SessionRecorder(tmp_path, 5.0, wall_ns=0)
    a, b = loopback_pair()
    tap = RecordingTransport(a, rec, CABLE, lambda: now[0])
    assert tap.name == a.name
    await tap.open()
    await b.open()
    now[0] = 5.25
    await tap.write(b"\x01\x02\x00")
    await b.write(b"\x03\x00")
    got = await asyncio.wait_for(tap.read(), 2.0)
    assert got == b"\x03\x00"
    await tap.close()
    await b.close()
    rec.close()
    assert rec.path is not None
    items = list(iter_file(rec.path))
    assert items == [LinkBytes(250_000_000, CABLE, "tx", b"\x01\x02\x00"),
                     LinkBytes(250_000_000, CABLE, "rx", b"\x03\x00")]


def test_a_replay_brings_a_fresh_model_to_the_live_state_at_the_recorded_times(tmp_path: Path) -> None:
    t0 = 1000.0
    live = Model(start=t0)
    rec = SessionRecorder(tmp_path, t0, wall_ns=1_700_000_000_000_000_000, meta={"cable": "/dev/pts/7"})
    live_session(rec, live, t0)
    rec.close()
    assert rec.path is not None

    replay = Replay.load(rec.path)
    assert replay.meta["cable"] == "/dev/pts/7" and replay.duration == pytest.approx(4.04)
    model = Model(start=0.0)
    seen_times = []
    for ev in replay.advance(10.0):  # 1x, past the end
        model.apply(ev, replay.clock())
        seen_times.append(replay.clock())
    assert replay.finished and seen_times == sorted(seen_times)
    assert model.attitude == live.attitude and model.height == live.height and model.status == live.status
    assert model.stick == live.stick and model.link == live.link and model.mode == live.mode
    assert [(round(e.t, 6), e.severity, e.source, e.text.replace("replay of ", "")) for e in model.events] == \
        [(round(e.t, 6), e.severity, e.source, e.text) for e in live.events]
    assert any("replay of /dev/pts/7" in e.text for e in model.events)  # the link panel's name says replay
    for name, series in live.history.items():
        assert [(round(t, 6), v) for t, v in model.history[name]] == [(round(t, 6), v) for t, v in series], name


def test_playback_speed_pause_and_seek(tmp_path: Path) -> None:
    rec = SessionRecorder(tmp_path, 0.0, wall_ns=0)
    live_session(rec, Model(), 0.0)
    rec.close()
    assert rec.path is not None
    replay = Replay.load(rec.path)

    def attitude_count(events: Iterable[object]) -> int:
        return sum(1 for e in events if isinstance(e, FromLink) and isinstance(e.event, PacketReceived)
                   and isinstance(e.event.packet, Attitude))

    assert attitude_count(replay.advance(1.0)) == 96  # 1 s at 1x: the frames of t = 0.05 .. 1.0
    assert replay.status() == "REPLAY 00:01.0 / 00:04.0 1x"
    assert replay.faster() == 2.0
    assert attitude_count(replay.advance(0.5)) == 100  # 0.5 s at 2x
    replay.paused = True
    assert list(replay.advance(1.0)) == [] and replay.position == pytest.approx(2.0)
    assert replay.status().endswith("paused")
    assert replay.seek(1.0) is True  # back: start again from a fresh model
    evs = replay.catch_up()
    assert attitude_count(evs) == 96 and replay.clock() == pytest.approx(1.0)
    assert replay.seek(3.0) is False
    assert attitude_count(replay.catch_up()) == 200
    assert replay.seek(99.0) is False and replay.position == replay.duration
    assert replay.slower() == 1.0 and replay.slower() == 0.5


async def test_term_replay_shows_the_recorded_values_at_the_recorded_times(tmp_path: Path) -> None:
    """The replay through the app itself (Textual's Pilot): the panels show what was recorded at the time sought,
    the link panel says it is a replay, and the keys play, pause and seek."""
    from term.ui.app import TermApp

    rec = SessionRecorder(tmp_path, 0.0, wall_ns=0, meta={"cable": "/dev/pts/7"})
    live_session(rec, Model(), 0.0)
    rec.close()
    assert rec.path is not None
    replay = Replay.load(rec.path)
    replay.paused = True
    app = TermApp(None, replay=replay)
    assert app.replayer is not None
    app.replayer.wall = lambda: 0.0  # the replay's wall clock stands still: it plays only where the test seeks
    async with app.run_test(size=(120, 44)) as pilot:

        def shown(wid: str) -> str:
            return str(app.screen.query_one(wid).render())

        app.replay_seek(1.0)  # the frame at t = 0.05 + 0.95: i = 95, phi 9.50°, theta -19.00°
        await pilot.pause()
        assert "roll   +9.5°   pitch  -19.0°" in shown("#heading")
        assert "REPLAY 00:01.0 / 00:04.0 paused" in shown("#link")
        assert app.model.mode == Mode.SAFE  # until i = 101
        app.replay_seek(2.0)
        await pilot.pause()
        assert "roll  +19.5°   pitch  -39.0°" in shown("#heading") and app.model.mode == Mode.MANUAL
        events = shown("#events")
        assert "hello pilot" in events and "request MANUAL" in events
        app.replay_seek(0.5)  # back: a fresh model brought to t = 0.5
        await pilot.pause()
        assert "roll   +4.5°   pitch   -9.0°" in shown("#heading") and "request MANUAL" not in shown("#events")
        await pilot.press("right")  # 5 s on: the end
        await pilot.pause()
        assert replay.position == replay.duration and "roll  +39.9°   pitch  -79.8°" in shown("#heading")
        await pilot.press("home", "space")  # from the start, playing (on a clock that stands still here)
        assert not replay.paused and replay.position == 0.0
        await pilot.press("plus")
        assert replay.speed == 2.0
        await pilot.press("2")  # a pilot's key does nothing: there is no board
        assert not any("not sent" in e.text for e in app.model.events)


async def test_a_replay_of_two_links_says_replay_in_the_link_panel(tmp_path: Path) -> None:
    from term.ui.app import TermApp

    rec = SessionRecorder(tmp_path, 0.0, wall_ns=0, meta={"cable": "/dev/pts/7", "radio": "BLE F0:5A"})
    model = Model(radio_name="BLE F0:5A")
    live_session(rec, model, 0.0)
    rec.station_event(LinkUp(RADIO, "BLE F0:5A", False), 4.1)
    rec.close()
    assert rec.path is not None
    replay = Replay.load(rec.path)
    replay.paused = True
    app = TermApp(None, replay=replay)
    assert app.model.radio_name == "BLE F0:5A"
    async with app.run_test(size=(120, 44)) as pilot:
        app.replay_seek(4.1)
        await pilot.pause()
        panel = str(app.screen.query_one("#link").render())
        assert panel.startswith("REPLAY 00:04.1 / 00:04.1 paused") and "ble" in panel


def test_term_replay_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from term.cli.main import main

    bad = tmp_path / "x.csv"
    bad.write_text("t_us,phi\n")
    for argv, why in [
        (["replay"], "give one recording, or --latest"),
        (["replay", "--latest", "--dir", str(tmp_path / "none")], "no session recordings in"),
        (["replay", str(tmp_path / "missing.mcap")], "cannot read"),
        (["replay", str(bad)], "not a session recording"),
        (["replay", str(bad), "--speed", "nan"], "--speed must be between 0.25 and 16"),
        (["replay", str(bad), "--speed", "100"], "--speed must be between 0.25 and 16"),
    ]:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("term: ") and why in err and err.count("\n") == 1, err
