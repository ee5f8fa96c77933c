"""term export: columns named and scaled from the packet table, MCAP that the mcap package reads back (JSON schemas,
events, the raw bytes), CSV in the terminal's units or board units, flash logs, and one-line errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from term.core.logfile import write_csv
from term.core.protocol import (
    PACKETS,
    SPEC_OF,
    Attitude,
    Height,
    Joystick,
    Mode,
    column_scale,
    scaled,
)
from term.data.export import ExportError, all_packet_schemas, export, packet_columns, packet_record
from term.data.recording import LinkBytes, SessionRecorder, StationRecord, iter_file
from tests.support.recording_rig import WALL, flash_log_csv, record
from tests.support.waits import until


def test_columns_are_named_and_scaled_from_the_packet_table() -> None:
    names = {c.field: c.name for c in packet_columns(SPEC_OF[Attitude])}
    assert names == {"mode": "mode", "phi": "phi_deg", "theta": "theta_deg", "psi": "psi_deg",
                     "sp": "sp_dps", "sq": "sq_dps", "sr": "sr_dps"}
    names = {c.field: c.name for c in packet_columns(SPEC_OF[Height])}
    assert names == {"pressure": "pressure_pa", "height": "height_m", "setpoint": "setpoint_m", "vz": "vz_mps",
                     "battery": "battery_v", "temperature": "temperature_degc"}
    h = Height(101325, 150, 100, -2, 1168, 2150)  # cm, cm/s (protocol 2)
    rec = packet_record(h, packet_columns(SPEC_OF[Height]))
    for fs in SPEC_OF[Height].fields:  # the table's own conversion, to the last kept digit
        key = [c.name for c in packet_columns(SPEC_OF[Height]) if c.field == fs.name][0]
        assert rec[key] == pytest.approx(scaled(h, fs.name), abs=1e-6)
    assert rec["height_m"] == 1.5 and rec["battery_v"] == 11.68 and rec["temperature_degc"] == 21.5
    a = packet_record(Attitude(7, 0, 0, 0, 0, 0, 0), packet_columns(SPEC_OF[Attitude]))
    assert a["mode"] == 7 and a["mode_name"] == "HEIGHT"
    assert packet_record(Attitude(99, 0, 0, 0, 0, 0, 0), packet_columns(SPEC_OF[Attitude]))["mode_name"] == "99"


def test_every_packet_has_a_json_schema_that_fits_its_messages() -> None:
    schemas = all_packet_schemas()
    assert set(schemas) == {spec.cls.__name__ for spec in PACKETS.values()}
    for spec in PACKETS.values():
        schema = schemas[spec.cls.__name__]
        assert schema["title"] == f"quadrupel.{spec.cls.__name__}" and spec.doc in schema["description"]
        sample = spec.cls(*(b"\x01" * 12 if fs.fmt.endswith("s") else 1 for fs in spec.fields))
        rec = packet_record(sample, packet_columns(spec))
        assert set(rec) == set(schema["properties"])
        for key, value in rec.items():
            kind = schema["properties"][key]["type"]
            assert isinstance(value, {"integer": int, "number": (int, float), "string": str}[kind]), (spec, key)
    phi = schemas["Attitude"]["properties"]["phi_deg"]
    assert phi == {"type": "number", "description": "roll angle (°)"}


def test_a_session_to_mcap_has_every_frame_on_its_channel_in_order(tmp_path: Path) -> None:
    rec, sent = record(tmp_path / "rec")
    assert rec.path is not None
    out = tmp_path / "flight.mcap"
    res = export(rec.path, out, raw=True)
    assert res.kind == "session" and res.complete and res.rows == len(sent) + 1
    got: list[tuple[str, str, dict]] = []
    events = []
    with out.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        schema_names = {s.name for s in summary.schemas.values()}
        assert {"quadrupel.Attitude", "quadrupel.Height", "quadrupel.Compact", "quadrupel.Joystick",
                "foxglove.Log"} <= schema_names
        last = 0
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert message.log_time >= last  # written in time order
            last = message.log_time
            parts = channel.topic.strip("/").split("/")
            if channel.topic == "/events":
                events.append(json.loads(message.data))
            elif len(parts) == 3:
                assert schema is not None and schema.encoding == "jsonschema" and channel.message_encoding == "json"
                assert schema.name == f"quadrupel.{parts[2]}"
                got.append((parts[0], parts[1], json.loads(message.data)))
    want = [(link, d, packet_record(p, packet_columns(SPEC_OF[type(p)], si=True))) for link, d, p in sent]
    assert got == want
    assert events == [{"timestamp": {"sec": WALL // 10**9 + 1, "nsec": 501_000_000}, "level": 4,
                       "message": "LINK LOST: nothing from the board for 0.5 s", "name": "link", "file": "", "line": 0}]
    # With --raw the exported file carries the raw bytes and the station's records too: it replays as the session
    # did (tests/data/test_foxglove.py: without it, decoded channels only).
    kept = (LinkBytes, StationRecord)
    assert [i for i in iter_file(out) if isinstance(i, kept)] == [i for i in iter_file(rec.path) if isinstance(i, kept)]
    assert any(isinstance(i, StationRecord) for i in iter_file(out))


def test_a_recording_cut_short_is_written_out_complete(tmp_path: Path) -> None:
    rec, sent = record(tmp_path / "rec", close=False)
    assert rec.path is not None
    crashed = tmp_path / "crashed.mcap"
    crashed.write_bytes(rec.path.read_bytes())  # what a SIGKILL leaves
    rec.close()
    with crashed.open("rb") as f, pytest.raises(Exception):  # noqa: B017  # the mcap package's reader gives up
        list(make_reader(f).iter_messages())
    res = export(crashed, tmp_path / "fixed.mcap")
    assert not res.complete and 0 < res.rows < len(sent)
    with (tmp_path / "fixed.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None and summary.statistics.message_count > res.rows


def test_a_session_to_csv_in_the_terminals_units_and_in_board_units(tmp_path: Path) -> None:
    rec, sent = record(tmp_path / "rec")
    assert rec.path is not None
    export(rec.path, tmp_path / "si.csv")
    rows = list(csv.DictReader((tmp_path / "si.csv").open(encoding="utf-8")))
    assert len(rows) == len(sent) + 1
    att = [r for r in rows if r["packet"] == "Attitude"]
    assert len(att) == 300 and att[0]["link"] == "serial" and att[0]["dir"] == "rx"
    assert float(att[0]["phi_deg"]) == 12.34 and float(att[0]["sp_dps"]) == pytest.approx(10.0)
    assert att[0]["mode_name"] == "MANUAL" and att[0]["height_m"] == ""
    assert float(att[1]["t_s"]) == pytest.approx(0.0105, abs=1e-6)  # the second read of each split frame
    h = [r for r in rows if r["packet"] == "Height"]
    assert float(h[0]["height_m"]) == 1.5 and float(h[0]["battery_v"]) == 11.68
    log = [r for r in rows if r["packet"] == "log"]
    assert [(r["level"], r["source"], r["message"]) for r in log] == \
        [("error", "link", "LINK LOST: nothing from the board for 0.5 s")]
    assert float(log[0]["t_s"]) == pytest.approx(1.501)
    ble = [r for r in rows if r["link"] == "ble"]
    assert len(ble) == 100 and all(r["packet"] == "Compact" for r in ble)

    export(rec.path, tmp_path / "raw.csv", board_units=True)
    raw = [r for r in csv.DictReader((tmp_path / "raw.csv").open(encoding="utf-8")) if r["packet"] == "Attitude"]
    assert raw[0]["phi"] == "1234" and raw[0]["sp"] == "164"


def test_a_flash_log_to_csv_and_mcap(tmp_path: Path) -> None:
    src = tmp_path / "quadrupel-log.csv"
    rows = flash_log_csv(src)
    res = export(src, tmp_path / "si.csv")
    assert res.kind == "flashlog" and res.rows == len(rows)
    got = list(csv.DictReader((tmp_path / "si.csv").open(encoding="utf-8")))
    assert list(got[0])[:5] == ["segment", "t_s", "mode", "mode_name", "phi_deg"]
    assert "height_m" in got[0] and "battery_v" in got[0] and "saz_g" in got[0]
    scale, unit = column_scale("phi")
    assert unit == "°"
    for g, r in zip(got, rows, strict=True):
        assert float(g["t_s"]) == pytest.approx(r[0] * 1e-6, abs=2e-5)  # the log's own quantisation (32 µs)
        assert float(g["phi_deg"]) == pytest.approx(r[2] * scale, abs=0.011)
        assert float(g["battery_v"]) == pytest.approx(11.6) and g["mode_name"] == "FULL"
        assert float(g["saz_g"]) == pytest.approx(-1.0, abs=1e-3)
    export(src, tmp_path / "board.csv", board_units=True)
    board = list(csv.DictReader((tmp_path / "board.csv").open(encoding="utf-8")))
    assert board[0]["battery"] == "1160" and board[0]["t_us"] == "0"

    export(src, tmp_path / "log.mcap")
    with (tmp_path / "log.mcap").open("rb") as f:
        msgs = [(m.log_time, json.loads(m.data)) for _, ch, m in make_reader(f).iter_messages(topics=["/flashlog"])]
    assert len(msgs) == len(rows)
    assert msgs[10][0] == pytest.approx(rows[10][0] * 1000, abs=32_000)
    assert msgs[10][1]["battery_v"] == 11.6 and msgs[10][1]["mode_name"] == "FULL"


def test_bad_input_is_one_clear_line(tmp_path: Path) -> None:
    rec, _ = record(tmp_path / "rec")
    assert rec.path is not None
    with pytest.raises(ExportError, match="unknown format 'png'"):
        export(rec.path, tmp_path / "x.png")
    with pytest.raises(ExportError, match="not found"):
        export(tmp_path / "nope.mcap", tmp_path / "x.csv")
    with pytest.raises(ExportError, match="is the input"):
        export(rec.path, rec.path, "mcap")
    with pytest.raises(ExportError, match="--board-units is for CSV"):
        export(rec.path, tmp_path / "x.mcap", board_units=True)
    hexdump = tmp_path / "hex.csv"
    write_csv(b"\x01\x02\x03" * 10, hexdump)
    with pytest.raises(ExportError, match="raw log bytes"):
        export(hexdump, tmp_path / "x.csv")
    other = tmp_path / "other.txt"
    other.write_bytes(b"\xff\xfe\x00 not a log")
    with pytest.raises(ExportError, match="neither a session recording"):
        export(other, tmp_path / "x.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("segment,t_us,phi\n0,1,2\n0,nan?,3\n")
    with pytest.raises(ExportError, match="line 3: not numbers"):
        export(bad, tmp_path / "x.csv")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ExportError, match="cannot write"):
        export(rec.path, blocker / "out.csv")


def test_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from term.cli.main import main

    rec, sent = record(tmp_path / "rec")
    assert rec.path is not None
    out = tmp_path / "out" / "latest.csv"
    assert main(["export", "--latest", "--dir", str(tmp_path / "rec"), "-o", str(out)]) == 0
    assert f"wrote {out}: {len(sent) + 1} frames and events from {rec.path}" in capsys.readouterr().out
    assert main(["export", str(rec.path), "-f", "mcap", "-o", str(tmp_path / "x.bin")]) == 0
    assert (tmp_path / "x.bin").read_bytes()[:8] == b"\x89MCAP0\r\n"
    capsys.readouterr()
    assert main(["recordings", "--dir", str(tmp_path / "rec")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["start", "length", "size", "file"]
    assert lines[1].split()[2:] == ["0:00:03", f"{rec.path.stat().st_size / 1000:.1f}", "kB", str(rec.path)]
    for argv, why in [
        (["export", "-o", str(out)], "give one recording or flash log, or --latest"),
        (["export", str(rec.path), "--latest", "-o", str(out)], "give one recording or flash log, or --latest"),
        (["export", "--latest", "--dir", str(tmp_path / "none"), "-o", str(out)], "no session recordings in"),
        (["export", str(rec.path), "-o", str(tmp_path / "x.txt")], "unknown format 'txt'"),
        (["export", str(rec.path), "-f", "png", "-o", str(out)], "invalid choice: 'png'"),
        (["export", str(tmp_path / "nope.mcap"), "-o", str(out)], "nope.mcap not found"),
    ]:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("term: ") and why in err and err.count("\n") == 1, err
    assert main(["recordings", "--dir", str(tmp_path / "none")]) == 2  # a folder named wrong: usage (issue 34)
    assert "no session recordings" in capsys.readouterr().err


async def test_a_flight_with_a_handover_is_recorded_whole_and_agrees_with_the_flash_log(tmp_path: Path) -> None:
    """The simulator flown through TermApp (cable, handover to BLE, back to the cable) with the recording on, then:
    the session file read with the mcap package holds every frame each link decoded, in order; the export has
    plausible values in the table's units; its CSV agrees with the board's own flash log of the same flight."""
    import bisect
    import contextlib
    import time

    from term.core.events import CABLE, RADIO, FromLink
    from term.core.link import PacketReceived
    from term.core.protocol import Decoder, Heartbeat, Op
    from term.data.recording import RecordingTransport
    from term.session.sim import SimBoard
    from term.transports.ble import BleTransport
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp

    sim = SimBoard(seed=3, radio=True)
    port = sim.start()
    decoded: dict[str, list] = {CABLE: [], RADIO: []}
    try:
        rec = SessionRecorder(tmp_path / "rec", time.monotonic(), meta={"cable": port, "radio": sim.ble_address})
        cable = RecordingTransport(SerialTransport(port), rec, CABLE, time.monotonic)
        radio = RecordingTransport(BleTransport(sim.ble_address, hci=sim.ble_hci, timeout=5.0), rec, RADIO,
                                   time.monotonic)
        app = TermApp(cable, joystick=False, radio=radio, recorder=rec, log_directory=tmp_path / "logs")
        live = app.station.on_event
        assert live is not None

        def tap(ev: object) -> None:  # what each link decoded, in order, as the model got it
            if type(ev) is FromLink and type(ev.event) is PacketReceived:
                decoded[ev.link].append(ev.event.packet)
            live(ev)  # type: ignore[arg-type]

        app.station.on_event = tap
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            async def fly(seconds: float) -> None:
                app.simulate_key("2")
                await until(pilot, lambda: m.mode == Mode.MANUAL)
                app.set_stick(Joystick(2000, -1500, 0, 9000, 0))
                await pilot.pause(seconds)
                app.set_stick(Joystick(0, 0, 0, 0, 0))
                for _ in range(20):  # SAFE needs the lift at zero: the board may not have the zero stick yet
                    app.simulate_key("0")
                    with contextlib.suppress(TimeoutError):
                        await until(pilot, lambda: m.mode == Mode.SAFE, 2.0)
                        break
                assert m.mode == Mode.SAFE, [e.text for e in m.events][-8:]

            await until(pilot, lambda: m.mode == Mode.SAFE and m.radio_up and m.link is not None)
            app.simulate_key("f2")  # the flash log records
            await until(pilot, lambda: m.status is not None and bool(m.status.flags & 4))
            await fly(1.5)  # over the cable
            app.simulate_key("8")  # the handover
            await until(pilot, lambda: m.over_ble)
            await fly(1.5)  # over BLE
            app.send(Op.WIRELESS, 0)  # control back to the cable
            await until(pilot, lambda: not m.over_ble and m.wireless == 0 and not m.link_lost)
            app.simulate_key("f3")
            await until(pilot, lambda: m.status is not None and not m.status.flags & 4)
            app.simulate_key("f5")  # download the flash log to CSV
            await until(pilot, lambda: "log saved" in m.download_note, 40.0)
            app.exit()
        rec.close()
    finally:
        sim.stop()
    assert rec.path is not None and len(decoded[CABLE]) > 300 and len(decoded[RADIO]) > 50

    # 1. The session file through the mcap package: every frame each link decoded, in order.
    streams: dict[str, list] = {CABLE: [], RADIO: []}
    decoders = {CABLE: Decoder(), RADIO: Decoder()}
    with rec.path.open("rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None
        for _, channel, message in reader.iter_messages(topics=["/cable/rx", "/radio/rx"], log_time_order=False):
            link = channel.topic.split("/")[1]
            streams[link] += decoders[link].feed(message.data)
    assert streams == decoded

    # 2. The export: plausible values in SI units on both links.
    export(rec.path, tmp_path / "flight.mcap")
    values: dict[str, list[dict]] = {}
    with (tmp_path / "flight.mcap").open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.topic.count("/") == 3:
                values.setdefault(channel.topic, []).append(json.loads(message.data))
    assert all(abs(a["phi_rad"]) < 0.8 and abs(a["theta_rad"]) < 0.8 for a in values["/cable/rx/Attitude"])
    assert all(10.5 < h["battery_v"] < 13 and abs(h["height_m"]) < 5 for h in values["/cable/rx/Height"])
    assert all(-11.8 < mo["saz_mps2"] < -4.9 for mo in values["/cable/rx/Motion"])  # about -1 g: it flies level
    assert {c["mode_name"] for c in values["/radio/rx/Compact"]} >= {"SAFE", "MANUAL"}
    assert any(j["lift"] == 9000 for j in values["/radio/tx/Joystick"])

    # 3. The CSV against the flash log of the same flight, both in the table's units.
    export(rec.path, tmp_path / "session.csv")
    (log_csv,) = (tmp_path / "logs").glob("*.csv")
    export(log_csv, tmp_path / "log.csv")
    session = list(csv.DictReader((tmp_path / "session.csv").open(encoding="utf-8")))
    log = list(csv.DictReader((tmp_path / "log.csv").open(encoding="utf-8")))
    # The board's clock against the receive times: the quickest heartbeat gives the offset.
    hb = [(float(r["t_s"]), float(r["board_ms_s"])) for r in session if r["packet"] == "Heartbeat"
          and r["link"] == CABLE]
    offset = min(t - b for t, b in hb)
    log_t = [float(r["t_s"]) for r in log]
    flying = [r for r in session if r["packet"] == "Attitude" and r["link"] == CABLE and r["mode_name"] == "MANUAL"]
    assert len(flying) > 40
    matched = 0
    for r in flying:
        board_t = float(r["t_s"]) - offset  # when the board sent it, at the latest
        lo = bisect.bisect_left(log_t, board_t - 0.5)  # a busy machine delivers late, never early
        hi = bisect.bisect_right(log_t, board_t + 0.005)
        if any(all(abs(float(log[i][k]) - float(r[k])) <= 0.011 for k in ("phi_deg", "theta_deg", "psi_deg"))
               and log[i]["mode_name"] == "MANUAL" for i in range(lo, hi)):
            matched += 1
    assert matched >= 0.9 * len(flying), (matched, len(flying))
    # The attitude changed while flying, so the match means something.
    assert len({(r["phi_deg"], r["theta_deg"], r["psi_deg"]) for r in flying}) > 0.5 * len(flying)
    assert Heartbeat in {type(p) for p in decoded[CABLE]}
