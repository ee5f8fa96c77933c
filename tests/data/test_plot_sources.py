"""`term plot` on a session recording and on a flash log alike (issue 14): the same SI units from the packet table,
series chosen by field or export column name, a time window; every bad input one line and exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from term.cli.main import main
from term.core.protocol import Attitude, Height, column_scale, field_spec
from term.data.export import export
from term.data.plot import PlotError, panels_of, read_source
from tests.support.recording_rig import flash_log_csv, record


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_a_recording_reads_in_si_units_with_its_times_and_links(tmp_path: Path) -> None:
    rec, sent = record(tmp_path / "rec")
    src = read_source(rec.path)
    assert src.kind == "session" and "session" in src.xlabel
    att = [p for link, d, p in sent if link == "serial" and d == "rx" and type(p) is Attitude]
    phi = {tr.label: tr for tr in src.traces["phi"]}
    assert set(phi) == {"phi (serial)", "phi (ble)"}  # both links brought roll: one line each, named
    cable = phi["phi (serial)"]
    assert cable.unit == "°" and list(cable.v) == pytest.approx([p.phi * 0.01 for p in att])
    assert cable.t[0] == pytest.approx(0.0, abs=1e-3) and cable.t[-1] == pytest.approx(2.99, abs=1e-3)  # since start
    (height,) = src.traces["height"]
    hs = [p for _, d, p in sent if type(p) is Height]
    assert height.label == "height" and height.unit == "m"
    assert list(height.v) == pytest.approx([p.height * field_spec(Height, "height").scale for p in hs])
    assert "sq" not in {k for k, v in src.traces.items() if not v}  # every field present has samples


def test_a_flash_log_and_a_recording_share_units_and_names(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    rows = flash_log_csv(log)
    rec, _ = record(tmp_path / "rec")
    flash, session = read_source(log), read_source(rec.path)
    assert flash.kind == "flashlog" and "board time" in flash.xlabel
    common = set(flash.traces) & set(session.traces)
    assert {"phi", "theta", "psi", "sp", "height", "pressure", "battery", "mode"} <= common
    for name in common:
        assert flash.traces[name][0].unit == session.traces[name][0].unit == column_scale(name)[1], name
    (phi,) = flash.traces["phi"]
    assert list(phi.v) == pytest.approx([r[2] * 0.01 for r in rows], abs=0.011)
    assert phi.t[1] == pytest.approx(0.0025, abs=5e-5)
    # the same panels for both, in the same order (this session has no Motion: no accelerations, no motors)
    titles = [p[0] for p in panels_of(session, rec.path)]
    assert titles == ["attitude", "body rates", "height", "pressure", "battery", "mode"]
    assert [p[0] for p in panels_of(flash, log) if p[0] in titles] == titles


def test_series_and_a_time_window(tmp_path: Path) -> None:
    rec, _ = record(tmp_path / "rec")
    src = read_source(rec.path)
    panels = panels_of(src, rec.path, ["phi_deg", "height", "battery_v"], 1.0, 2.0)
    assert [(t, u) for t, u, _ in panels] == [("phi", "°"), ("height", "m"), ("battery", "V")]
    for _, _, traces in panels:
        assert traces and all(tr.t and 1.0 <= min(tr.t) and max(tr.t) <= 2.0 for tr in traces)
    (h,) = panels[1][2]
    assert len(h.t) == 20  # Height at 20 Hz for a second
    with pytest.raises(PlotError, match=r"has nothing between 5 s and 6 s \(it spans 0.0 to 3.0 s\)"):
        panels_of(src, rec.path, None, 5.0, 6.0)
    with pytest.raises(PlotError, match="no column 'warp'"):
        panels_of(src, rec.path, ["phi", "warp"])


def test_the_command_line_on_a_recording_a_flash_log_and_the_latest(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    rec, _ = record(tmp_path / "rec")
    log = tmp_path / "log.csv"
    flash_log_csv(log)
    for src, extra in ((str(rec.path), []), (str(log), ["--signals", "phi,battery_v", "--from", "0.1", "--to", "0.3"])):
        out_png = tmp_path / "p.png"
        code, out, err = run(capsys, "plot", src, "-o", str(out_png), *extra)
        assert code == 0 and out == f"wrote {out_png}\n", err
        assert out_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        out_png.unlink()
    code, out, _ = run(capsys, "plot", "--latest", "--dir", str(tmp_path / "rec"), "-o", str(tmp_path / "l.svg"),
                       "--signals", "theta,mode")
    assert code == 0 and b"<svg" in (tmp_path / "l.svg").read_bytes()[:400]
    exported = tmp_path / "flight.mcap"  # a term export --raw MCAP is a recording too
    export(rec.path, exported, raw=True)
    code, _, err = run(capsys, "plot", str(exported), "-o", str(tmp_path / "e.png"), "--from", "2")
    assert code == 0, err


@pytest.mark.parametrize("args, words", [
    (["{rec}", "--from", "nan"], "--from must be a finite number of seconds, got nan"),
    (["{rec}", "--to", "inf"], "--to must be a finite number of seconds, got inf"),
    (["{rec}", "--from", "2", "--to", "1"], "the window is empty: --from 2 s is not before --to 1 s"),
    (["{rec}", "--from", "x"], "--from: invalid float value: 'x'"),
    (["{rec}", "--from", "10"], "has nothing between 10 s and inf s (it spans 0.0 to 3.0 s)"),
    (["{rec}", "--signals", "phi_dps"], "no column 'phi_dps'"),
    (["{rec}", "--latest"], "give one recording or flight log, or --latest"),
    (["--latest", "--dir", "{d}/empty"], "no session recordings in"),
    (["{d}/cut.mcap"], "is not a session recording"),
    (["{d}/flashlog.mcap"], "holds no telemetry from the board"),
])
def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                               words: str) -> None:
    rec, _ = record(tmp_path / "rec")
    (tmp_path / "empty").mkdir()
    (tmp_path / "cut.mcap").write_bytes(b"\x89MCA")
    good = rec.path.read_bytes()
    (tmp_path / "garbage.mcap").write_bytes(good[:200] + bytes(b ^ 0x5A for b in good[200:4000]) + good[4000:])
    log = tmp_path / "log.csv"
    flash_log_csv(log)
    export(log, tmp_path / "flashlog.mcap")
    out_png = tmp_path / "out.png"
    argv = [a.format(rec=rec.path, d=tmp_path) for a in args]
    code, out, err = run(capsys, "plot", *argv, "-o", str(out_png))
    assert code == 2 and out == "" and not out_png.exists()
    assert words in err and err.count("\n") == 1, err


def test_over_ble_the_motors_and_height_come_from_compact2(tmp_path: Path) -> None:
    """A session flown over BLE: Compact2 brings the motors and the height; plotted per link, in the table's units
    (a motor command in steps of 4)."""
    from term.core.protocol import Compact2, Encoder, Motion
    from term.data.recording import SessionRecorder

    rec = SessionRecorder(tmp_path / "rec", 10.0, wall_ns=1_700_000_000_000_000_000)
    cable, radio = Encoder(), Encoder()
    for i in range(20):
        now = 10.0 + 0.1 * i
        if i < 10:  # on the cable first, then handed over
            rec.received("serial", cable.encode(Motion(0, 0, -16384, 400, 401, 402, 403)), now)
            rec.received("serial", cable.encode(Height(101325, 100 + i, 0, 0, 1168, 2150)), now)
        else:
            rec.received("ble", radio.encode(Compact2(100, 101, 99, 250, 100 + i, 0, 5, 2, 0)), now)
        rec.poll(now)
    rec.close()
    src = read_source(rec.path)
    ae1 = {tr.label: tr for tr in src.traces["ae1"]}
    assert set(ae1) == {"ae1 (serial)", "ae1 (ble)"} and list(ae1["ae1 (ble)"].v) == [400.0] * 10
    height = {tr.label: list(tr.v) for tr in src.traces["height"]}
    assert height["height (ble)"] == pytest.approx([(100 + i) * 0.01 for i in range(10, 20)])


def test_a_damaged_recording_is_plotted_from_what_survives(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 36: a damaged stretch is skipped and the rest read (it was read up to the damage, as a cut-short file,
    and refused as holding no telemetry)."""
    rec, _ = record(tmp_path / "rec")
    good = rec.path.read_bytes()
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(good[:200] + bytes(b ^ 0x5A for b in good[200:4000]) + good[4000:])
    out_png = tmp_path / "out.png"
    code, out, err = run(capsys, "plot", str(garbage), "-o", str(out_png))
    assert code == 0 and out_png.exists(), err
