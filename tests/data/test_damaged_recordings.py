"""Export and replay keep everything readable (issue 36): one flipped byte in any chunk of a recording costs that
chunk, counted, and the rest is exported; the output is written beside and renamed at the end; a damaged header is
named as damage, with where, and term export exits non-zero."""

from __future__ import annotations

import csv
import os
import random
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from term.core.protocol import Attitude, Encoder, Height, Joystick, Mode
from term.data.export import ExportError, export
from term.data.recording import MAGIC, Recording, RecordingError, SessionRecorder, iter_file
from term.data.replay import Replay

WALL = 1_700_000_000_000_000_000
CHUNK = 0x06


def _record(directory: Path) -> Path:
    """Six seconds of telemetry and sticks, a chunk each quarter second (flush_period): some two dozen chunks."""
    rec = SessionRecorder(directory, 10.0, wall_ns=WALL, flush_period=0.25)
    cable, out = Encoder(), Encoder()
    for i in range(600):
        now = 10.0 + i * 0.01
        rec.received("serial", cable.encode(Attitude(int(Mode.MANUAL), 1234 + i, -500, 9000, 164, -328, 0)), now)
        if i % 5 == 0:
            rec.received("serial", cable.encode(Height(101325 - i, 150 + i, 100, -2, 1168, 2150)), now)
        rec.sent("serial", out.encode(Joystick(i, -i, 0, 2000, 0)), now + 0.001)
        if i == 300:
            rec.event(now, "error", "link", "LINK LOST: nothing from the board for 0.5 s")
        rec.poll(now)
    rec.close()
    assert rec.path is not None
    return rec.path


def _chunks(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of every top-level chunk record."""
    pos, out = len(MAGIC), []
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if opcode == CHUNK:
            out.append((pos, pos + 9 + length))
        if opcode == 0x02:
            break
        pos += 9 + length
    return out


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    path = _record(tmp_path_factory.mktemp("rec"))
    out = path.with_name("whole.csv")
    res = export(path, out)
    assert not res.damage and res.complete
    return path, res.rows


def test_one_flipped_byte_in_each_chunk_costs_that_chunk_and_the_rest_is_exported(
        recording: tuple[Path, int], tmp_path: Path) -> None:
    src, whole = recording
    data = src.read_bytes()
    chunks = _chunks(data)
    assert len(chunks) >= 15
    rng = random.Random(36)
    for n, (start, end) in enumerate(chunks):  # one flip per run: in the chunk's compressed records
        at = rng.randrange(start + 9 + 40, end)
        damaged = bytearray(data)
        damaged[at] ^= 1 << rng.randrange(8)
        bad = tmp_path / f"flip{n}.mcap"
        bad.write_bytes(bytes(damaged))
        res = export(bad, tmp_path / f"flip{n}.csv")
        assert len(res.damage) == 1 and f"at byte {start:,}" in res.damage[0], (n, at, res.damage)
        assert whole * 0.8 < res.rows < whole, (n, at, res.rows, whole)  # one chunk of ~24 lost, the rest there
        assert len(_rows(tmp_path / f"flip{n}.csv")) == res.rows
        mres = export(bad, tmp_path / f"flip{n}.mcap.out.mcap", raw=True)
        assert mres.rows == res.rows and mres.damage
        with (tmp_path / f"flip{n}.mcap.out.mcap").open("rb") as f:  # the mcap package reads it whole
            assert sum(1 for _ in make_reader(f).iter_messages()) > 0
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]  # nothing half written left


def test_a_flipped_chunk_length_costs_that_chunk_and_replay_plays_the_rest(
        recording: tuple[Path, int], tmp_path: Path) -> None:
    src, whole = recording
    data = bytearray(src.read_bytes())
    start, _ = _chunks(bytes(data))[len(_chunks(bytes(data))) // 2]
    data[start + 5] ^= 0x40  # the length's sixth byte: the record now claims far past the end of the file
    bad = tmp_path / "len.mcap"
    bad.write_bytes(bytes(data))
    rec = Recording(bad)
    items = list(iter_file(bad, rec))
    assert rec.damage and rec.damage[0].start == start and rec.complete
    res = export(bad, tmp_path / "len.csv")
    assert whole * 0.8 < res.rows < whole
    replay = Replay.load(bad)
    replay.seek(1e9)
    assert replay.duration > 5.0 and len(items) > 0
    assert replay.damage == 1 and "1 damaged part skipped" in replay.status()


def test_a_huge_first_record_length_is_named_damage_at_byte_8(recording: tuple[Path, int], tmp_path: Path) -> None:
    src, whole = recording
    data = bytearray(src.read_bytes())
    data[len(MAGIC) + 1 : len(MAGIC) + 9] = struct.pack("<Q", 2**62)
    bad = tmp_path / "head.mcap"
    bad.write_bytes(bytes(data))
    res = export(bad, tmp_path / "head.csv")
    assert res.rows == whole and res.damage and "at byte 8: the header record" in res.damage[0]
    cli = _cli_export(bad, tmp_path / "head2.csv")
    assert cli.returncode == 1 and "byte 8" in cli.stderr and "Traceback" not in cli.stderr, cli.stderr


def test_the_magic_then_random_bytes_is_damage_with_where_and_no_file_left(tmp_path: Path) -> None:
    bad = tmp_path / "noise.mcap"
    bad.write_bytes(MAGIC + random.Random(5).randbytes(100_000))
    with pytest.raises(RecordingError, match="damaged at byte 8"):
        list(iter_file(bad))
    out = tmp_path / "noise.csv"
    with pytest.raises(ExportError, match="damaged at byte 8"):
        export(bad, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["noise.mcap"]
    cli = _cli_export(bad, tmp_path / "noise2.mcap")
    assert cli.returncode not in (0, 1) and "damaged at byte 8" in cli.stderr and "Traceback" not in cli.stderr
    assert "wrote" not in cli.stdout and not (tmp_path / "noise2.mcap").exists()


def test_a_recording_cut_short_is_still_cut_short_not_damage(recording: tuple[Path, int], tmp_path: Path) -> None:
    src, whole = recording
    data = src.read_bytes()
    start, end = _chunks(data)[-3]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: (start + end) // 2])  # a crash while writing a chunk
    rec = Recording(cut)
    assert list(iter_file(cut, rec)) and not rec.damage and not rec.complete
    res = export(cut, tmp_path / "cut.csv")
    assert not res.damage and not res.complete and 0 < res.rows < whole


def test_an_export_that_fails_leaves_the_earlier_output_as_it_was(recording: tuple[Path, int],
                                                                  tmp_path: Path) -> None:
    bad = tmp_path / "noise.mcap"
    bad.write_bytes(MAGIC + bytes(range(256)) * 10)
    out = tmp_path / "flight.csv"
    out.write_text("an earlier export\n")
    with pytest.raises(ExportError):
        export(bad, out)
    assert out.read_text() == "an earlier export\n" and sorted(os.listdir(tmp_path)) == ["flight.csv", "noise.mcap"]


def _cli_export(src: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "term.cli.main", "export", str(src), "-o", str(out)],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ, NO_COLOR="1"))
