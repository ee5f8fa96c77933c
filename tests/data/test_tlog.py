"""`term export -o flight.tlog` (term/data/tlog.py): a session recording as a MAVLink telemetry log that pymavlink's
own reader and its mavlogdump tool read back, with the recording's times; and the mapping's pure parts
(term/data/mavlink_map.py): the parameter names, the units, the long STATUSTEXT."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from term.core.protocol import (
    PARAMS,
    Attitude,
    Encoder,
    Event,
    EventCode,
    Height,
    Mode,
    Motion,
    Param,
    ParamValue,
)
from term.data.recording import SessionRecorder

pytest.importorskip("pymavlink", reason="the mavlink extra (pymavlink) is not installed")

from term.data.export import ExportError, export  # noqa: E402
from term.data.mavlink_map import (  # noqa: E402
    PARAM_BY_MAV,
    PARAM_NAMES,
    Telemetry,
    codec,
    param_raw,
    scales_agree,
    statustexts,
)

WALL = 1_790_000_000_000_000_000  # the recording's start, Unix ns


def record(directory: Path) -> Path:
    """Three seconds of a MANUAL flight over the cable at 50 Hz, its height at 10 Hz, a parameter and an event."""
    rec = SessionRecorder(directory, 10.0, wall_ns=WALL)
    enc = Encoder()
    for i in range(150):
        now = 10.0 + i * 0.02
        pkts: list[object] = [Attitude(int(Mode.MANUAL), 1000 + i, -500, 9000, 164, -328, 0),
                              Motion(0, 0, -16384, 400, 410, 420, 430)]
        if i % 5 == 0:
            pkts.append(Height(100000, 150 + i, 100, -2, 1168, 2150))
        if i == 75:
            pkts += [ParamValue(int(Param.P1), 4000, 0, 1), Event(int(EventCode.LOW_BATTERY), 1040, 123456)]
        rec.received("serial", b"".join(enc.encode(p) for p in pkts), now)
        rec.poll(now)
    rec.close()
    assert rec.path is not None
    return rec.path


def test_a_recording_is_a_telemetry_log_pymavlink_reads_with_its_times(tmp_path: Path) -> None:
    from pymavlink import mavutil  # (here: its every dialect takes 0.7 s to import, on each worker)

    src = record(tmp_path / "rec")
    out = tmp_path / "flight.tlog"
    res = export(src, out)
    assert res.rows > 150
    log = mavutil.mavlink_connection(str(out), dialect="common")
    msgs = []
    while (m := log.recv_match()) is not None:
        msgs.append(m)
    kinds = {m.get_type() for m in msgs}
    assert {"HEARTBEAT", "SYS_STATUS", "BATTERY_STATUS", "ATTITUDE", "ALTITUDE", "VFR_HUD", "SCALED_PRESSURE",
            "SERVO_OUTPUT_RAW", "STATUSTEXT", "PARAM_VALUE"} <= kinds
    atts = [m for m in msgs if m.get_type() == "ATTITUDE"]
    assert len(atts) == 150  # every Attitude (50 Hz, within its cap)
    first = atts[0]
    assert first._timestamp == pytest.approx(WALL / 1e9, abs=1e-3)  # the time its bytes crossed the link
    assert atts[-1]._timestamp - first._timestamp == pytest.approx(149 * 0.02, abs=1e-3)
    assert math.degrees(first.roll) == pytest.approx(10.0) and math.degrees(first.yaw) == pytest.approx(90.0)
    assert math.degrees(first.rollspeed) == pytest.approx(10.0)  # 164 LSB at 16.4 LSB per °/s
    assert len([m for m in msgs if m.get_type() == "ALTITUDE"]) == 30  # the Height's 10 Hz
    alt = [m for m in msgs if m.get_type() == "ALTITUDE"][0]
    assert alt.altitude_relative == pytest.approx(1.5)
    hbs = [m for m in msgs if m.get_type() == "HEARTBEAT"]
    assert len(hbs) == 3 and all(hb.custom_mode == Mode.MANUAL and hb.base_mode & 128 and hb.type == 2 for hb in hbs)
    servo = [m for m in msgs if m.get_type() == "SERVO_OUTPUT_RAW"][0]
    assert (servo.servo1_raw, servo.servo4_raw) == (1400, 1430)
    p1 = [m for m in msgs if m.get_type() == "PARAM_VALUE"][0]
    assert (p1.param_id, p1.param_value) == ("CTRL_P1", pytest.approx(0.4))
    text = [m for m in msgs if m.get_type() == "STATUSTEXT"][0]
    assert "LOW BATTERY 10.40 V" in text.text and text.severity == 2  # MAV_SEVERITY_CRITICAL
    # mavlogdump, pymavlink's own tool, reads it too.
    dump = subprocess.run([sys.executable, "-m", "pymavlink.tools.mavlogdump", "--types", "ATTITUDE", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert dump.returncode == 0, dump.stderr
    assert dump.stdout.count("ATTITUDE") == 150


def test_a_tlog_is_written_from_a_session_recording_only(tmp_path: Path) -> None:
    csv = tmp_path / "log.csv"
    csv.write_text("t_us,phi\n0,1\n")
    with pytest.raises(ExportError, match="from a session recording"):
        export(csv, tmp_path / "x.tlog")
    with pytest.raises(ExportError, match="no --board-units, no --raw"):
        export(record(tmp_path / "rec"), tmp_path / "x.tlog", raw=True)


def test_every_parameter_has_a_mavlink_name_of_16_characters_both_ways() -> None:
    assert len(PARAM_NAMES) == len(PARAMS) == len(set(PARAM_NAMES.values()))
    for pid, name in PARAM_NAMES.items():
        assert len(name) <= 16 and name.isascii() and name == name.upper()
        assert int(PARAM_BY_MAV[name].param) == pid
    assert PARAM_NAMES[int(Param.YAW_P)] == "CTRL_YAW_P"
    # docs/mavlink.md's table: every parameter, in the table's order, with both names
    doc = (Path(__file__).resolve().parents[2] / "docs" / "mavlink.md").read_text(encoding="utf-8")
    rows = [r.split("|")[1:4] for r in doc.splitlines() if r.startswith("| ") and "` | `" in r]
    assert [(int(i), m.strip(" `"), t.strip(" `")) for i, m, t in rows] == [
        (i, PARAM_NAMES[int(p)], PARAMS[p].name) for i, p in enumerate(PARAMS)]


def test_a_ground_stations_float_goes_to_the_tables_step_or_is_refused() -> None:
    k = PARAMS[Param.K_GYRO]
    import struct

    as_float32 = struct.unpack("<f", struct.pack("<f", 0.99))[0]  # what crossed the link: 0.9900000095...
    assert param_raw(k, as_float32) == (99000, "")
    assert param_raw(PARAMS[Param.P1], 50.0)[0] is None and "outside 0..10" in param_raw(PARAMS[Param.P1], 50.0)[1]
    assert param_raw(PARAMS[Param.P1], float("nan"))[0] is None
    assert param_raw(PARAMS[Param.ATTITUDE_FILTER], 1.0) == (1, "")
    raw, why = param_raw(PARAMS[Param.ATTITUDE_FILTER], 7.0)
    assert raw is None and "0 complementary" in why and "4 ikf" in why
    assert param_raw(PARAMS[Param.FIXED_POINT], 0.5)[0] is None


def test_units_come_from_the_packet_table_and_long_texts_are_chunked() -> None:
    assert scales_agree()
    mav = codec()
    msgs = statustexts(mav, 6, "x" * 120, 7)
    assert [len(m.text) for m in msgs] == [50, 50, 20] and {m.id for m in msgs} == {7}
    assert [m.chunk_seq for m in msgs] == [0, 1, 2]
    assert len(statustexts(mav, 6, "y" * 100, 8)) == 3  # a full last chunk is followed by an empty one
    tele = Telemetry(mav)
    assert tele.packet(Attitude(0, 0, 0, 0, 0, 0, 0), 0.0) and not tele.packet(Attitude(0, 0, 0, 0, 0, 0, 0), 0.001)
