"""`fcb-sim replay-imu` reads what `term export` writes (issue 14): a flash log's SI export replays as the log
itself does, a session recording's export replays to the board's own angles; the session file itself is refused
with the command that exports it; bad input is one line with nothing written before it (/dev/zero included)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from fcb_sim.board.telemetry import i16
from fcb_sim.cli import main
from fcb_sim.lab.replay_imu import EXPORT, FLASH_LOG
from term.core.protocol import Attitude, Encoder, Joystick, Mode, Motion, field_spec
from term.data.export import column_name, export
from term.data.recording import SessionRecorder
from tests.support.recording_rig import _raw_flight_log

WALL = 1_700_000_000_000_000_000


def _read(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_the_export_columns_replay_imu_reads_are_the_ones_term_export_writes() -> None:
    packet = {"sp": Attitude, "sq": Attitude, "sr": Attitude, "sax": Motion, "say": Motion, "saz": Motion}
    names = [column_name(f, field_spec(packet[f], f).scaled_unit) for f in FLASH_LOG[1:]]
    assert ["t_s", *names] == list(EXPORT)


@pytest.mark.parametrize("board_units", [False, True])
def test_a_flash_log_replays_the_same_from_its_export(tmp_path: Path, board_units: bool) -> None:
    """The SI export (and the board-units one, which is the log again) gives the same angles as the log."""
    src, rows = _raw_flight_log(tmp_path, seconds=8.0)
    assert main(["replay-imu", str(src), "--out", str(tmp_path / "log.out.csv")]) == 0
    exported = tmp_path / "si.csv"
    export(src, exported, board_units=board_units)
    assert main(["replay-imu", str(exported), "--out", str(tmp_path / "si.out.csv")]) == 0
    a, b = _read(tmp_path / "log.out.csv"), _read(tmp_path / "si.out.csv")
    assert len(a) == len(b) == len(rows)
    for x, y in zip(a, b, strict=True):
        assert float(y["t"]) == pytest.approx(float(x["t"]), abs=1e-6)
        for k in ("roll", "pitch", "yaw"):
            assert float(y[k]) == pytest.approx(float(x[k]), abs=1e-5)  # the export keeps 6 decimals of °/s and g


def _recorded_flight(directory: Path, seconds: float = 10.0, gap: tuple[float, float] | None = None
                     ) -> tuple[Path, list[tuple[float, float, float]]]:
    """A RAW flight in the simulator whose telemetry (Attitude and Motion at 50 Hz, built as the board's telemetry
    task builds them) is recorded as term records a session: the cable's bytes with the time they were read (every
    fifth pair read together with the next), the sticks going out, and the radio's Compact beside. Returns the
    recording and the board's own (t, phi, theta) in degrees at each Attitude."""
    from fcb_sim.lab.scenarios import Sim, _roll_stick
    from term.core.protocol import Compact

    sim = Sim(3)
    rec = SessionRecorder(directory, 0.0, wall_ns=WALL)
    cable, radio, out = Encoder(), Encoder(), Encoder()
    truth: list[tuple[float, float, float]] = []
    held = [b""]
    n = [0]

    def tick(s: Sim) -> None:
        n[0] += 1
        if s.t <= 1.0 or n[0] % 8 or (gap and gap[0] <= s.t < gap[1]):
            return
        fc = s.fc
        phi, theta, psi = fc.attitude_centideg()
        pkts = [Attitude(s.mode, i16(phi), i16(theta), i16(psi), i16(fc.sp), i16(fc.sq), i16(fc.sr)),
                Motion(i16(fc.sax), i16(fc.say), i16(fc.saz), *fc.ae)]
        truth.append((s.t, phi / 100.0, theta / 100.0))
        data = held[0] + b"".join(cable.encode(p) for p in pkts)
        if n[0] % 40 == 0:
            held[0] = data  # read together with the next pair: one read time for both
            return
        held[0] = b""
        rec.received("cable", data, s.t)
        rec.sent("cable", out.encode(Joystick(0, 0, 0, 0, 0)), s.t)
        rec.received("radio", radio.encode(Compact(s.mode, 0, i16(phi), i16(theta), i16(psi), 1200)), s.t)
        rec.poll(s.t)

    sim.on_tick = tick
    sim.prologue(Mode.RAW)
    sim.run_until(5.0)
    for k in range(int((seconds - 5.0) / 0.5)):  # the roll stick thrown side to side every half second
        sim.sticks[0] = _roll_stick(math.radians(15.0 if k % 2 else -15.0))
        sim.run_until(5.0 + 0.5 * (k + 1))
    if held[0]:
        rec.received("cable", held[0], sim.t)
    rec.close()
    assert rec.path is not None
    return rec.path, truth


def _scored(out: Path, truth: list[tuple[float, float, float]], skip_s: float) -> tuple[float, float]:
    """RMS and worst of the replayed angle against the board's, in degrees, after ``skip_s`` (the filter settles)."""
    got = _read(out)
    assert len(got) == len(truth)  # one sample per Attitude, whatever else the session holds
    t0 = truth[0][0]
    diffs = [math.hypot(phi - math.degrees(float(g["roll"])), theta + math.degrees(float(g["pitch"])))
             for (t, phi, theta), g in zip(truth, got, strict=True) if t - t0 > skip_s]
    return math.sqrt(sum(d * d for d in diffs) / len(diffs)), max(diffs)


def test_a_session_recording_is_scored_offline_through_its_export(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The board flew RAW with its filter at 400 Hz; the session kept its telemetry at 50 Hz. Replayed through the
    same filter from the export, the angles agree with the board's within 1.5° RMS while the quad swings ±13°
    (the flash log's 400 Hz replays within 0.25°: test_estimation_replay)."""
    path, truth = _recorded_flight(tmp_path / "rec")
    assert main(["replay-imu", str(path), "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "a session recording (MCAP)" in err and f"term export {path} -o" in err and err.count("\n") == 1
    assert not (tmp_path / "x.csv").exists()

    exported = tmp_path / "session.csv"
    export(path, exported)
    out = tmp_path / "replayed.csv"
    assert main(["replay-imu", str(exported), "--out", str(out)]) == 0
    assert max(abs(phi) for _, phi, _ in truth) > 10.0  # it did fly the swings
    rms, worst = _scored(out, truth, skip_s=3.0)  # the filter starts from one noisy sample (hover vibration)
    assert rms < 1.5 and worst < 6.0, (rms, worst)  # measured 0.93° and 4.4° (50 Hz rates of ±200 °/s throws)


def test_a_silent_link_is_one_long_step(tmp_path: Path) -> None:
    """Two seconds without telemetry (the cable lost): the replay goes on across the hole, one row per Attitude, and
    keeps its attitude (a restart from the accelerometer of a quad in flight was 28° off; this is 6° while the quad
    swings, then converging)."""
    path, truth = _recorded_flight(tmp_path / "rec", seconds=8.0, gap=(4.0, 6.0))
    exported = tmp_path / "session.csv"
    export(path, exported)
    out = tmp_path / "replayed.csv"
    assert main(["replay-imu", str(exported), "--out", str(out)]) == 0
    t = [float(g["t"]) for g in _read(out)]
    steps = [b - a for a, b in zip(t, t[1:], strict=False)]
    assert min(steps) > 0 and max(steps) > 1.9
    rms, worst = _scored(out, truth, skip_s=1.0)
    assert rms < 8.0 and worst < 12.0, (rms, worst)


def test_nothing_is_written_before_the_input_is_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 14: a missing file printed the CSV header to stdout first; /dev/zero ran out of memory."""
    for src, words in ((tmp_path / "missing.csv", "no such file"),
                       (Path("/dev/zero"), ":1: a line longer than 65536 characters"),
                       (tmp_path / "header-only.csv", "no data rows")):
        if src.name == "header-only.csv":
            src.write_text(",".join(EXPORT) + "\n", encoding="utf-8")
        capsys.readouterr()
        assert main(["replay-imu", str(src), "--out", "-"]) == 2
        out, err = capsys.readouterr()
        assert out == "" and words in err and err.count("\n") == 1, (out, err)


def test_a_bad_export_row_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    head = "segment,t_s,sp_dps,sq_dps,sr_dps,sax_g,say_g,saz_g\n"
    cases = {
        "nan.csv": (head + "0,0.0025,0,0,0,0,0,-1\n0,0.005,nan,0,0,0,0,-1\n", ":3: non-finite value"),
        "word.csv": (head + "0,0.0025,0,x,0,0,0,-1\n", ":2: column sq_dps is not a number: 'x'"),
        "back.csv": (head + "0,0.005,0,0,0,0,0,-1\n0,0.0025,0,0,0,0,0,-1\n", ":3: time t_s=0.0025 does not increase"),
        "short.csv": (head + "0,0.005,0,0,0,0,0\n", ":2: 7 fields for 8 columns"),
    }
    for name, (text, words) in cases.items():
        src = tmp_path / name
        src.write_text(text, encoding="utf-8")
        capsys.readouterr()
        assert main(["replay-imu", str(src), "--out", str(tmp_path / "o.csv")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
