"""Flight data in the field's tools: the channels (term/data/channels.py) read back by readers the project does not
write. The MCAP export through the mcap package's reader and the Foxglove SDK's own message types; the live server
(term/data/foxglove_server.py) through a client of Foxglove's WebSocket protocol written from its spec
(tests/support/foxglove_client.py) during a real ``--sim`` flight, its times checked against the recording's."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import threading
import time
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

from term.core.protocol import SPEC_OF, Attitude, Decoder, Mode
from term.data.channels import (
    CRAFT,
    ROOM,
    Channels,
    all_channels,
    frame_transform,
    packet_channel,
    quaternion,
)
from term.data.columns import packet_columns, packet_record
from term.data.export import ExportError, export
from term.data.recording import LinkBytes, StationRecord, TruthSample, iter_file
from tests.support.paths import DOCS
from tests.support.recording_rig import WALL, record
from tests.support.waits import until

foxglove = pytest.importorskip("foxglove", reason="the foxglove extra (foxglove-sdk) is not installed")


def read_mcap(path: Path) -> tuple[dict[str, tuple[str, str, str]], list[tuple[str, int, bytes]]]:
    """The channels (topic: schema name, schema encoding, message encoding) and messages of ``path``, as the
    mcap package reads them; every channel must have a schema."""
    channels: dict[str, tuple[str, str, str]] = {}
    messages = []
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        for ch in summary.channels.values():
            assert ch.schema_id != 0 and ch.schema_id in summary.schemas, f"{ch.topic} has no schema"
            s = summary.schemas[ch.schema_id]
            assert s.name and s.data, ch.topic
            channels[ch.topic] = (s.name, s.encoding, ch.message_encoding)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            messages.append((channel.topic, message.log_time, message.data))
    return channels, messages


def sdk_frame_transform(d: dict) -> object:
    """The JSON FrameTransform as the SDK's own message type (its constructor checks every field's name and type),
    encoded by the SDK: what the 3D panel reads."""
    m = foxglove.messages
    ft = m.FrameTransform(
        timestamp=m.Timestamp(d["timestamp"]["sec"], d["timestamp"]["nsec"]),
        parent_frame_id=d["parent_frame_id"], child_frame_id=d["child_frame_id"],
        translation=m.Vector3(**d["translation"]), rotation=m.Quaternion(**d["rotation"]))
    assert ft.encode()
    return ft


def test_the_attitude_is_a_frame_transform_in_the_rooms_z_up_frame() -> None:
    q = quaternion(0.0, 0.0, 0.0)
    assert (q["x"], q["y"], q["z"], q["w"]) == (0.0, 0.0, 0.0, 1.0)
    yaw = quaternion(0.0, 0.0, math.pi / 2)
    assert yaw["z"] == pytest.approx(math.sqrt(0.5)) and yaw["w"] == pytest.approx(math.sqrt(0.5))
    # The board's NED/FRD: right wing down (phi > 0) stays a positive roll; nose up (theta > 0) is a negative pitch
    # about the room's y (west), a yaw to the east (psi > 0) a negative turn about its z (up).
    ft = frame_transform(WALL, CRAFT, (1.0, 2.0, 3.0), 0.1, 0.2, 0.3)
    assert ft["translation"] == {"x": 1.0, "y": -2.0, "z": 3.0}
    assert ft["rotation"] == quaternion(0.1, -0.2, -0.3)
    assert ft["parent_frame_id"] == ROOM and ft["timestamp"] == {"sec": WALL // 10**9, "nsec": WALL % 10**9}
    sdk_frame_transform(ft)
    names = {c.schema_name for c in all_channels()}
    assert {"foxglove.FrameTransform", "foxglove.Log", "quadrupel.Attitude", "quadrupel.LinkStats"} <= names
    assert all(json.loads(c.schema)["type"] == "object" for c in all_channels())


def test_decoded_packets_are_in_si_units() -> None:
    ch, _ = packet_channel("cable", "rx", SPEC_OF[Attitude])
    msgs = Channels().frame(WALL, "cable", "rx", Attitude(int(Mode.FULL), 9000, -4500, 18000, 164, 0, 0))
    assert [m[0].topic for m in msgs] == ["/cable/rx/Attitude", "/cable/pose"]
    att = json.loads(msgs[0][2])
    assert att["phi_rad"] == pytest.approx(math.pi / 2, abs=1e-6) and att["psi_rad"] == pytest.approx(math.pi, 1e-6)
    assert att["sp_radps"] == pytest.approx(math.radians(10.0), abs=1e-6) and att["mode_name"] == "FULL"
    props = json.loads(ch.schema)["properties"]
    assert props["phi_rad"]["description"] == "roll angle (rad)"
    assert props["mode_name"]["enum"][0] == "SAFE"


def test_the_export_has_a_schema_on_every_channel_and_every_frame_of_the_recording(tmp_path: Path) -> None:
    rec, sent = record(tmp_path / "rec")
    assert rec.path is not None
    res = export(rec.path, tmp_path / "flight.mcap")
    channels, messages = read_mcap(tmp_path / "flight.mcap")
    assert not any(enc == "quadrupel-frames" for _, _, enc in channels.values())  # decoded only by default
    assert "/station" not in channels
    assert all(enc == "json" and senc == "jsonschema" for _, senc, enc in channels.values())
    # Message counts match the recording: one message per frame on its channel, a pose per attitude.
    want = Counter(f"/{link}/{d}/{type(p).__name__}" for link, d, p in sent)
    got = Counter(topic for topic, _, _ in messages)
    for topic, n in want.items():
        assert got[topic] == n, topic
    assert got["/serial/pose"] == want["/serial/rx/Attitude"] and got["/ble/pose"] == want["/ble/rx/Compact"]
    assert got["/events"] == 1 and res.rows == len(sent) + 1  # frames and events, as the CSV counts its rows
    # Each decoded frame, in SI, in the order sent; each pose decodes with the SDK's own FrameTransform.
    decoded = [(t.split("/")[1], t.split("/")[2], json.loads(d)) for t, _, d in messages if t.count("/") == 3]
    assert decoded == [(link, d, packet_record(p, packet_columns(SPEC_OF[type(p)], si=True))) for link, d, p in sent]
    poses = [json.loads(d) for t, _, d in messages if t == "/serial/pose"]
    for pose in poses:
        sdk_frame_transform(pose)
    assert poses[0]["child_frame_id"] == CRAFT and poses[0]["parent_frame_id"] == ROOM
    assert poses[0]["translation"]["z"] == 0.0 and poses[1]["translation"]["z"] == 1.5  # the last Height (150 cm)


def test_raw_bytes_only_with_raw_in_a_channel_a_reader_can_skip_and_the_export_replays(tmp_path: Path) -> None:
    rec, _ = record(tmp_path / "rec")
    assert rec.path is not None
    export(rec.path, tmp_path / "raw.mcap", raw=True)
    channels, _ = read_mcap(tmp_path / "raw.mcap")
    assert channels["/serial/rx"] == ("quadrupel-frames", "quadrupel-frames", "quadrupel-frames")
    assert channels["/station"] == ("quadrupel.StationRecord", "jsonschema", "json")
    kept = (LinkBytes, StationRecord)
    out = [i for i in iter_file(tmp_path / "raw.mcap") if isinstance(i, kept)]
    assert out == [i for i in iter_file(rec.path) if isinstance(i, kept)]
    with pytest.raises(ExportError, match="--raw is for MCAP"):
        export(rec.path, tmp_path / "raw.csv", raw=True)


def test_the_csv_has_an_absolute_utc_time(tmp_path: Path) -> None:
    import csv

    rec, _ = record(tmp_path / "rec")
    assert rec.path is not None
    export(rec.path, tmp_path / "f.csv")
    rows = list(csv.DictReader((tmp_path / "f.csv").open(encoding="utf-8")))
    assert list(rows[0])[:3] == ["t_s", "utc", "link"]
    # WALL is 2023-11-14T22:13:20Z; the first frame was whole 0.5 ms after the session's start (its second read)
    assert rows[0]["utc"] == "2023-11-14T22:13:20.000500Z" and rows[0]["t_s"] == "0.000500"
    assert rows[-1]["utc"].startswith("2023-11-14T22:13:2") and rows[-1]["utc"].endswith("Z")


def tap_threads(live: object) -> list[int]:
    """The threads ``live`` is handed the link's packets on (before the app is made: it takes ``link_packet``),
    one entry a packet."""
    threads: list[int] = []
    link_packet = live.link_packet  # type: ignore[attr-defined]

    def counted(*args: object) -> None:
        threads.append(threading.get_ident())
        link_packet(*args)

    live.link_packet = counted  # type: ignore[attr-defined]
    return threads


async def test_a_client_subscribed_during_a_sim_flight_gets_the_attitude_as_the_recording_has_it(
        tmp_path: Path) -> None:
    """``term --sim --foxglove`` as the cli wires it: the transports tapped for the recording and the live server,
    the instructor's truth. A WebSocket client subscribes during the flight; every attitude it gets carries the time
    the recording gave the same bytes, and the values the export gives them; the truth's pose is served too."""
    from term.core.events import CABLE
    from term.core.protocol import Joystick
    from term.data.foxglove_server import LiveServer
    from term.data.recording import RecordingTransport, SessionRecorder
    from term.lessons.instructor import InstructorClient
    from term.session.sim import SimBoard
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp
    from tests.support.foxglove_client import Client

    sim = SimBoard(seed=3, radio=False, instructor=True)
    port = sim.start()
    live = None
    try:
        rec = SessionRecorder(tmp_path / "rec", time.monotonic(), meta={"cable": port})
        live = LiveServer("127.0.0.1", 0, t0=rec.t0, start_ns=rec.start_ns)
        cable = RecordingTransport(SerialTransport(port), (rec, live), CABLE, time.monotonic)
        instructor = InstructorClient(sim.instructor_address)
        await instructor.open()
        tapped = tap_threads(live)
        app = TermApp(cable, joystick=False, recorder=rec, instructor=instructor, live=live,
                      log_directory=tmp_path / "logs")
        client = Client(live.url, ("/cable/rx/Attitude", "/cable/pose", "/truth/pose", "/truth", "/events",
                                  "/cable/stats"))
        stop = asyncio.Event()
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model
            await until(pilot, lambda: m.mode == Mode.SAFE and m.link is not None)
            # The live server is fed on the link's thread as the packets are decoded, never through the display's
            # loop: with the display held (a slow render), it still gets them.
            display = threading.get_ident()
            n, deadline = len(tapped), time.monotonic() + 5.0
            while len(tapped) == n and time.monotonic() < deadline:
                threading.Event().wait(0.01)  # the display's thread held on purpose
            assert len(tapped) > n, "the live server got no packets while the display was busy"
            assert display not in set(tapped)
            task = asyncio.create_task(client.run(stop))
            await until(pilot, lambda: len(client.on("/cable/pose")) > 20 and len(client.on("/truth/pose")) > 5)
            app.simulate_key("2")
            await until(pilot, lambda: m.mode == Mode.MANUAL)
            app.set_stick(Joystick(2000, 0, 0, 9000, 0))
            await pilot.pause(1.0)
            app.set_stick(Joystick(0, 0, 0, 0, 0))
            for _ in range(20):  # SAFE needs the lift at zero: the board may not have the zero stick yet (NAK)
                app.simulate_key("0")
                with contextlib.suppress(TimeoutError):
                    await until(pilot, lambda: m.mode == Mode.SAFE, 2.0)
                    break
            assert m.mode == Mode.SAFE, [e.text for e in m.events][-8:]
            await until(pilot, lambda: len(client.on("/cable/stats")) > 0 and len(client.on("/cable/rx/Attitude")) > 50
                        and "MANUAL" in {r.json()["mode_name"] for r in client.on("/cable/rx/Attitude")})
            stop.set()
            await task
            app.exit()
        await instructor.close()
        rec.close()
    finally:
        if live is not None:
            live.close()
        sim.stop()
    assert rec.path is not None
    # The recording's attitudes, with the times it gave their bytes.
    recorded: dict[int, list[Attitude]] = {}
    dec = Decoder()
    for item in iter_file(rec.path):
        if isinstance(item, LinkBytes) and item.link == CABLE and item.direction == "rx":
            for p in dec.feed(item.data):
                if type(p) is Attitude:
                    recorded.setdefault(item.t_ns, []).append(p)
    got = client.on("/cable/rx/Attitude")
    assert len(got) > 50
    # The truth is recorded as served: the same samples at the same times.
    recorded_truth = {i.t_ns: i.data["h"] for i in iter_file(rec.path) if isinstance(i, TruthSample)}
    served_truth = client.on("/truth")
    assert len(recorded_truth) > 5 and served_truth
    assert all(recorded_truth.get(r.log_time) == r.json()["h"] for r in served_truth)
    cols = packet_columns(SPEC_OF[Attitude], si=True)
    for r in got:  # the same bytes at the same time: the live message is the recorded one
        assert r.log_time in recorded, "a live attitude the recording does not have at that time"
        assert r.json() in [packet_record(p, cols) for p in recorded[r.log_time]]
    assert {r.json()["mode_name"] for r in got} >= {"SAFE", "MANUAL"}
    # Stamped when its bytes were read, on the clock the client reads: none arrives before it was read (how old
    # they are is a figure, measured by bench.foxglove, not held here).
    assert all(r.arrived >= r.log_time for r in got)
    pose = client.on("/cable/pose")[-1].json()
    sdk_frame_transform(pose)
    truth = client.on("/truth/pose")[-1].json()
    assert truth["child_frame_id"] == "truth" and abs(truth["translation"]["z"]) < 20
    assert any("MANUAL" in r.json()["message"] for r in client.on("/events"))
    stats = client.on("/cable/stats")[-1].json()
    assert stats["frames_ok"] > 100 and (stats["rtt_mean_s"] is None or stats["rtt_mean_s"] < 1.0)


def test_the_address_and_a_missing_sdk_are_one_line() -> None:
    from term.data.foxglove_server import FoxgloveError, parse_address

    assert parse_address("8765") == ("127.0.0.1", 8765)
    assert parse_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_address("[::1]:9000") == ("::1", 9000)
    for bad in ("", "host:", "99999", "x:-1", "nan", "1e308", "9" * 400, "h" * 400 + ":1" + "0" * 400, "\x00"):
        with pytest.raises(FoxgloveError, match="--foxglove") as exc:
            parse_address(bad)
        assert len(str(exc.value)) < 160, "the one line names the input, cut short"
    from term.data.foxglove_server import LiveServer

    first = LiveServer("127.0.0.1", 0, t0=0.0, start_ns=WALL)
    try:
        with pytest.raises(FoxgloveError, match=f"cannot serve Foxglove on 127.0.0.1:{first.port}") as exc:
            LiveServer("127.0.0.1", first.port, t0=0.0, start_ns=WALL)  # the port is taken
        assert "\n" not in str(exc.value)
        with pytest.raises(FoxgloveError, match="cannot serve Foxglove on h+[.][.][.] [(]400 characters[)]") as exc:
            LiveServer("h" * 400, 8765, t0=0.0, start_ns=WALL)  # (no such host: a name too long to look up)
        assert "\n" not in str(exc.value) and len(str(exc.value)) <= 300
    finally:
        first.close()


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="threads are counted in Linux's /proc")
def test_the_sdk_sends_from_one_thread_unless_told_otherwise() -> None:
    """Its default, a thread per core, woke two threads for every message (bench.foxglove); a user's own
    TOKIO_WORKER_THREADS is kept. In a process of its own: the SDK's runtime starts once a process."""
    import os
    import subprocess
    import sys

    probe = ("import os, time\n"
             "from term.data.foxglove_server import LiveServer\n"
             "live = LiveServer('127.0.0.1', 0, t0=0.0, start_ns=0)\n"
             "time.sleep(0.3)\n"
             "names = [open(f'/proc/self/task/{t}/comm').read().strip() for t in os.listdir('/proc/self/task')]\n"
             "print(sum(n.startswith('tokio') for n in names))\n"
             "live.close()\n")
    env = {k: v for k, v in os.environ.items() if k != "TOKIO_WORKER_THREADS"}
    for setting, workers in ((None, "1"), ("3", "3")):
        if setting is not None:
            env["TOKIO_WORKER_THREADS"] = setting
        out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60)
        assert out.stdout.strip() == workers, out.stderr[-2000:]


def test_live_parameters_are_the_boards_read_only() -> None:
    from term.core.protocol import ParamValue
    from term.core.protocol.params import PARAMS, Param
    from term.data.foxglove_server import LiveServer

    live = LiveServer("127.0.0.1", 0, t0=0.0, start_ns=WALL)
    try:
        spec = PARAMS[Param.TELEMETRY_HZ] if hasattr(Param, "TELEMETRY_HZ") else next(iter(PARAMS.values()))
        live.link_packet("cable", ParamValue(int(spec.param), spec.to_raw(spec.default), 0, 1))
        deadline = time.monotonic() + 5
        while spec.name not in live._params.values and time.monotonic() < deadline:
            time.sleep(0.01)
        got = live._params.on_set_parameters(None, [foxglove.Parameter(spec.name, value=1.0)])
        assert [(p.name, p.get_value()) for p in got] == [(spec.name, spec.default)]  # unchanged: read-only
    finally:
        live.close()


def test_the_layout_in_docs_names_only_channels_and_fields_we_serve() -> None:
    layout = json.loads((DOCS / "foxglove-layout.json").read_text(encoding="utf-8"))
    schemas = {c.topic: json.loads(c.schema) for c in all_channels()}
    paths = [p["value"] for cfg in layout["configById"].values() for p in cfg.get("paths", [])]
    assert len(paths) > 10
    for path in paths:
        topic, field = path.split(".", 1)
        assert topic in schemas, path
        assert field in schemas[topic]["properties"], path
    assert {cfg.get("topicToRender") for cfg in layout["configById"].values()} >= {"/events"}
    assert "craft" in json.dumps(layout["configById"]["3D!craft"])


def test_the_sdks_writer_and_the_mcap_packages_write_the_same_messages(tmp_path: Path) -> None:
    rec, _ = record(tmp_path / "rec")
    assert rec.path is not None
    got = {}
    for library in ("sdk", "mcap"):
        export(rec.path, tmp_path / f"{library}.mcap", raw=True, library=library)
        got[library] = read_mcap(tmp_path / f"{library}.mcap")
    assert got["sdk"] == got["mcap"]
    with (tmp_path / "sdk.mcap").open("rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["session"]["exported_from"] == rec.path.name


def test_without_the_sdk_foxglove_says_how_to_add_it_in_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    import sys

    from term.cli.main import main

    rec, _ = record(tmp_path / "rec")
    monkeypatch.setitem(sys.modules, "foxglove", None)  # as if the extra were not installed
    assert main(["replay", str(rec.path), "--foxglove", "8765"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'quadrupel[foxglove]'" in err, err
    assert main(["replay", str(rec.path), "--foxglove", "nope"]) == 2
    assert "--foxglove takes [HOST:]PORT" in capsys.readouterr().err


def test_the_estimates_pose_is_the_frame_transform_as_json() -> None:
    from term.data.channels import craft_pose

    for args in ((WALL, 1.25, 0.1, -0.2, 3.0), (WALL + 999, -0.07, 0.0, 0.0, 0.0), (0, 0.0, -1.5, 1.4, -3.1)):
        t_ns, up, phi, theta, psi = args
        assert json.loads(craft_pose(*args)) == frame_transform(t_ns, CRAFT, (0.0, 0.0, up), phi, theta, psi)


def test_an_export_without_raw_is_refused_by_replay_and_plot_in_one_line(tmp_path: Path) -> None:
    from term.data.plot import PlotError, plot_log
    from term.data.recording import RecordingError
    from term.data.replay import Replay

    rec, _ = record(tmp_path / "rec")
    assert rec.path is not None
    export(rec.path, tmp_path / "decoded.mcap")
    with pytest.raises(RecordingError, match="without --raw"):
        Replay.load(tmp_path / "decoded.mcap")
    with pytest.raises(PlotError, match="without --raw"):
        plot_log(tmp_path / "decoded.mcap", tmp_path / "p.png")
    export(rec.path, tmp_path / "raw.mcap", raw=True)
    assert Replay.load(tmp_path / "raw.mcap").timeline


def sim_truth(i: int, **change: float) -> object:
    """A sample of the simulator's truth as the instructor channel gives it."""
    from term.lessons.instructor import Truth

    d = dict(t=i * 0.02, n=0.5, e=-0.25, h=1.0 + i * 0.01, vn=0.0, ve=0.0, vd=-0.1, phi=0.1, theta=-0.05, psi=1.0,
             p=0.0, q=0.0, r=0.0, on_ground=False, volts=11.8, soc=0.9, landings=0, touchdown=0.0, crashes=0,
             cable=True)
    return Truth(**{**d, **change})  # type: ignore[arg-type]


def test_the_simulators_truth_is_recorded_and_exported_on_its_own_channel_with_its_pose(tmp_path: Path) -> None:
    """In --sim the recording keeps the instructor's truth beside the link's bytes; the export gives it as
    ``/truth`` (quadrupel.Truth) and ``/truth/pose`` (foxglove.FrameTransform, frame ``truth``), as live. A sample
    a hostile file made not finite is left out, never written as NaN into JSON."""
    rec, sent = record(tmp_path / "rec", close=False)
    for i in range(40):
        rec.truth(sim_truth(i), 10.0 + i * 0.02)  # type: ignore[attr-defined]
    rec.truth(sim_truth(40, h=math.nan), 10.9)  # type: ignore[attr-defined]
    rec.close()
    assert rec.path is not None
    export(rec.path, tmp_path / "flight.mcap")
    channels, messages = read_mcap(tmp_path / "flight.mcap")
    assert channels["/truth"] == ("quadrupel.Truth", "jsonschema", "json")
    assert channels["/truth/pose"] == ("foxglove.FrameTransform", "jsonschema", "json")
    got = Counter(topic for topic, _, _ in messages)
    assert got["/truth"] == got["/truth/pose"] == 40
    truths = [(t, json.loads(d)) for topic, t, d in messages if topic == "/truth"]
    assert truths[0][0] == WALL  # the recording's time of the sample (its clock starts at 10.0)
    assert truths[3][1]["h"] == pytest.approx(1.03) and truths[3][1]["on_ground"] is False
    pose = [json.loads(d) for topic, _, d in messages if topic == "/truth/pose"][0]
    sdk_frame_transform(pose)
    assert pose["child_frame_id"] == "truth" and pose["translation"] == {"x": 0.5, "y": 0.25, "z": 1.0}
    # The link's frames are all there as before: the truth is beside them, not instead.
    want = Counter(f"/{link}/{d}/{type(p).__name__}" for link, d, p in sent)
    assert all(got[topic] == n for topic, n in want.items())


def test_a_frame_is_converted_only_for_the_channels_wanted_and_the_height_is_kept_all_the_same() -> None:
    """The live server converts nothing no client asked for (``want``); the pose still has the last height."""
    from term.core.protocol import Height

    maker = Channels()
    assert maker.frame(WALL, "cable", "rx", Height(101325, 150, 100, -2, 1168, 2150), lambda spec: False) == []
    att = Attitude(int(Mode.MANUAL), 1234, -500, 9000, 164, -328, 0)
    only_pose = maker.frame(WALL, "cable", "rx", att, lambda spec: spec.topic == "/cable/pose")
    assert [spec.topic for spec, _, _ in only_pose] == ["/cable/pose"]
    assert json.loads(only_pose[0][2])["translation"]["z"] == 1.5
    assert [spec.topic for spec, _, _ in maker.frame(WALL, "cable", "rx", att)] == ["/cable/rx/Attitude",
                                                                                     "/cable/pose"]
