"""`fcb-sim replay-imu` on good and malformed files, through the real command-line entry point."""

from __future__ import annotations

import csv
import gzip
import math
from pathlib import Path

import pytest

from fcb_sim.cli import main
from tests.support.paths import EXCERPT
from tests.support.recording_rig import _raw_flight_log

HEADER = "t,gx,gy,gz,ax,ay,az"


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _good_rows(n: int = 50, dt: float = 0.01) -> str:
    # tilted 10° in roll, still; an extra column that must be ignored
    g = 9.81
    ay, az = g * math.sin(math.radians(10)), g * math.cos(math.radians(10))
    lines = ["note," + HEADER]
    lines += [f"x,{i * dt:.4f},0,0,0,0,{ay:.5f},{az:.5f}" for i in range(n)]
    return "\n".join(lines) + "\n"


def _read(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.parametrize(("name", "fixed"), [(None, False), ("complementary", True), ("kalman-cov", False)])
def test_replay_good_file(tmp_path: Path, name: str | None, fixed: bool, capsys: pytest.CaptureFixture) -> None:
    src = _write(tmp_path / "in.csv", _good_rows())
    out = tmp_path / "out.csv"
    argv = ["replay-imu", str(src), "--out", str(out)]
    if name:
        argv += ["--filter", name]
    if fixed:
        argv.append("--fixed-point")
    assert main(argv) == 0
    rows = _read(out)
    assert list(rows[0]) == ["t", "roll", "pitch", "yaw", "qw", "qx", "qy", "qz"]
    assert len(rows) == 50
    assert float(rows[-1]["t"]) == pytest.approx(0.49)
    assert math.degrees(float(rows[-1]["roll"])) == pytest.approx(10.0, abs=0.5)
    q = [float(rows[-1][k]) for k in ("qw", "qx", "qy", "qz")]
    assert sum(c * c for c in q) == pytest.approx(1.0, abs=1e-6)
    assert q[1] == pytest.approx(math.sin(math.radians(5.0)), abs=0.005)  # roll 10° -> x = sin(5°)
    assert "50 rows" in capsys.readouterr().err


def test_replay_gzip_real_data(tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    assert main(["replay-imu", str(EXCERPT), "--out", str(out)]) == 0
    with gzip.open(EXCERPT, "rt") as fh:
        n_in = sum(1 for _ in fh) - 1
    assert len(_read(out)) == n_in


def test_list_filters(capsys: pytest.CaptureFixture) -> None:
    assert main(["replay-imu", "--list-filters"]) == 0
    out = capsys.readouterr().out
    for name in ("complementary", "kalman", "kalman-cov", "qgate"):
        assert name in out
    assert "default" in out


BAD_FILES = {
    "missing_columns.csv": ("t,gx,gy\n0,1,2\n", "missing column(s) gz, ax, ay, az"),
    "not_a_number.csv": (HEADER + "\n0,0,0,0,0,0,9.8\n0.01,0,abc,0,0,0,9.8\n", ":3: column gy is not a number"),
    "time_backwards.csv": (HEADER + "\n0.02,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n", "does not increase"),
    "nan.csv": (HEADER + "\n0,0,0,0,0,0,nan\n", "non-finite"),
    "empty.csv": ("", "empty file"),
    "header_only.csv": (HEADER + "\n", "no data rows"),
    "short_row.csv": (HEADER + "\n0,0,0\n", "too few fields"),
}


@pytest.mark.parametrize("fname", sorted(BAD_FILES))
def test_replay_malformed_file(tmp_path: Path, fname: str, capsys: pytest.CaptureFixture) -> None:
    text, expected = BAD_FILES[fname]
    src = _write(tmp_path / fname, text)
    out = tmp_path / "out.csv"
    assert main(["replay-imu", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert expected in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()  # nothing half-written


def test_replay_unreadable_inputs(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = str(tmp_path / "out.csv")
    garbage = tmp_path / "bad.csv.gz"
    garbage.write_bytes(b"\x00\x9d\x01 not gzip at all")
    binary = tmp_path / "bin.csv"
    binary.write_bytes(bytes(range(128, 256)) * 4)
    cases = [
        ([str(tmp_path / "nope.csv")], "no such file"),
        ([str(garbage)], "not a readable CSV file"),
        ([str(binary)], "not a readable CSV file"),
        ([str(tmp_path)], "is a directory"),
    ]
    for extra, expected in cases:
        assert main(["replay-imu", *extra, "--out", out]) == 2
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1


def test_replay_bad_options(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    src = _write(tmp_path / "in.csv", _good_rows(5))
    out = str(tmp_path / "out.csv")
    assert main(["replay-imu", str(src), "--out", out, "--filter", "nope"]) == 2
    assert "unknown filter 'nope'" in capsys.readouterr().err
    assert main(["replay-imu", str(src), "--out", out, "--filter", "qgate", "--fixed-point"]) == 2
    assert "no fixed-point variant" in capsys.readouterr().err
    assert main(["replay-imu", str(src)]) == 2
    assert "--out" in capsys.readouterr().err
    assert main(["replay-imu", "--out", out]) == 2
    assert "input CSV" in capsys.readouterr().err
    assert main(["replay-imu", str(src), "--out", str(tmp_path / "no_dir" / "o.csv")]) == 2
    assert "cannot write" in capsys.readouterr().err


# --- the board's own flash log ------------------------------------------------------------------------------


@pytest.mark.parametrize("fixed", [False, True])
def test_replay_the_boards_flash_log(tmp_path: Path, fixed: bool) -> None:
    """A flight's log replayed through the board's own filter gives back the angles the board flew on, within
    0.25° RMS and 0.6° at worst while the quad swings ±13° (measured 0.15° and 0.20°). The replay sees the logged
    words (gyro to 4 LSB, accelerometer to 8, time to 32 µs), the board saw them unrounded; most of the
    difference is the log quantiser's ties-up rounding, which leaves a noisy 4-LSB word 0.5 LSB high on average:
    a 0.03 °/s gyro bias the filter cannot learn in flight (no rest). In fixed point the board flies ikf's variant
    that fits the M0 (its gravity part spread over 4 samples) and the replay runs the same."""
    src, rows = _raw_flight_log(tmp_path, fixed=fixed)
    out = tmp_path / "out.csv"
    argv = ["replay-imu", str(src), "--out", str(out)] + (["--fixed-point"] if fixed else [])
    assert main(argv) == 0
    got = _read(out)
    assert len(got) == len(rows)
    assert float(got[0]["t"]) == pytest.approx(rows[0][0] / 1e6, abs=1e-4)
    diffs, swing = [], 0.0
    for r, g in zip(rows, got, strict=True):
        phi, theta = r[2] / 100.0, r[3] / 100.0  # the board's angles, FRD: phi = roll, theta = -pitch
        swing = max(swing, abs(phi))
        diffs.append(math.hypot(phi - math.degrees(float(g["roll"])), theta + math.degrees(float(g["pitch"]))))
    assert swing > 10.0  # it did fly the swings
    assert math.sqrt(sum(d * d for d in diffs) / len(diffs)) < 0.25
    assert max(diffs) < 0.6


def test_flash_log_segments_and_bad_logs(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Two recordings in one log (segments 0 and 1, time jumping back) replay as two flights; a log row with a
    missing word or a time going back within a segment is one line, naming the line."""
    head = "segment,t_us,mode,phi,theta,psi,sp,sq,sr,sax,say,saz\n"
    level = "0,0,0,0,0,{saz}\n"
    ok = head + "".join(f"{s},{t},6,0,0,0," + level.format(saz=-16384) for s, t in
                        ((0, 5000), (0, 7500), (0, 10000), (1, 2500), (1, 5000)))
    src = _write(tmp_path / "log.csv", ok)
    out = tmp_path / "out.csv"
    assert main(["replay-imu", str(src), "--out", str(out)]) == 0
    assert [float(r["t"]) for r in _read(out)] == [0.005, 0.0075, 0.01, 0.0025, 0.005]
    bad = {
        "short.csv": (head + "0,5000,6,0,0,0,0,0,0,0,0\n", ":2: too few fields"),
        "back.csv": (head + "0,5000,6,0,0,0,0,0,0,0,0,-16384\n0,4000,6,0,0,0,0,0,0,0,0,-16384\n",
                     ":3: time t_us=4000 does not increase"),
        "word.csv": (head + "0,5000,6,0,0,0,0,x,0,0,0,-16384\n", ":2: column sq is not a number"),
    }
    for name, (text, expected) in bad.items():
        capsys.readouterr()
        assert main(["replay-imu", str(_write(tmp_path / name, text)), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1
