"""`fcb-sim replay-imu` on good and malformed files, through the real command-line entry point."""

from __future__ import annotations

import csv
import gzip
import math
from pathlib import Path

import pytest

from fcb_sim.cli import main

EXCERPT = Path(__file__).parent / "data" / "broad_07_fast_rotation_excerpt.csv.gz"
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
