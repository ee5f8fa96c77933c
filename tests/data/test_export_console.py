"""The console's lines in a session recording (kept with the station's events) and in its export: foxglove.Log on
/console in MCAP, rows with packet "console" in CSV."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from mcap.reader import make_reader

from term.core.console import ConsoleLine
from term.core.events import FromLink
from term.core.protocol import Encoder, Heartbeat
from term.data.export import export
from term.data.recording import SessionRecorder

WALL = 1_700_000_000_000_000_000


def _session(directory: Path) -> Path:
    rec = SessionRecorder(directory, 10.0, wall_ns=WALL)
    enc = Encoder()
    rec.received("serial", b"boot ok\n" + enc.encode(Heartbeat(1, 1)) + enc.encode(Heartbeat(2, 2)), 10.0)
    rec.station_event(FromLink("serial", ConsoleLine("boot ok", 2, "uart")), 10.01)
    rec.station_event(FromLink("serial", ConsoleLine("ASSERT x > 0", 4, "board", dropped=3)), 10.5)
    rec.close()
    return rec.path


def test_console_lines_export_to_mcap_as_foxglove_log(tmp_path: Path) -> None:
    src = _session(tmp_path / "rec")
    out = tmp_path / "out.mcap"
    export(src, out, library="mcap")
    with out.open("rb") as f:
        msgs = [(ch.topic, sch.name, json.loads(m.data)) for sch, ch, m in make_reader(f).iter_messages()
                if ch.topic == "/console"]
    assert [(t, s) for t, s, _ in msgs] == [("/console", "foxglove.Log")] * 2
    assert [(d["message"], d["level"], d["name"]) for _, _, d in msgs] == [
        ("boot ok", 2, "serial/uart"), ("[3 dropped] ASSERT x > 0", 4, "serial/board")]


def test_console_lines_export_to_csv_rows(tmp_path: Path) -> None:
    src = _session(tmp_path / "rec")
    out = tmp_path / "out.csv"
    export(src, out)
    rows = list(csv.DictReader(out.open()))
    console = [r for r in rows if r["packet"] == "console"]
    assert [(r["message"], r["level"], r["source"]) for r in console] == [
        ("boot ok", "info", "uart"), ("[3 dropped] ASSERT x > 0", "error", "board")]
    assert [r["counter"] for r in rows if r["packet"] == "Heartbeat"] == ["1", "2"]  # the printed line cost no frame


def test_the_live_server_serves_console_lines_on_console() -> None:
    import pytest

    pytest.importorskip("foxglove")
    from term.data.foxglove_server import LiveServer

    live = LiveServer("127.0.0.1", 0, t0=0.0, start_ns=WALL)
    got = []
    try:
        live._publish = lambda messages, wanted=False: got.extend(messages)  # what would go to the SDK
        live.station_event(FromLink("cable", ConsoleLine("E: i2c timeout", 4, "uart", dropped=2)), 1.0)
    finally:
        live.close()
    assert [(spec.topic, spec.schema_name, msg["message"], msg["level"], msg["name"]) for spec, _, msg in got] == [
        ("/console", "foxglove.Log", "[2 dropped] E: i2c timeout", 4, "cable/uart")]


def test_a_recorded_console_line_replays_as_itself() -> None:
    from term.data.recording import decode_event, encode_event

    ev = FromLink("cable", ConsoleLine("ASSERT x > 0", 4, "board", dropped=3, cut=True))
    assert decode_event(json.loads(json.dumps(encode_event(ev)))) == ev
