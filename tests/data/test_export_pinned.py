"""term export's output pinned, byte for byte (CSV) and message for message (MCAP: topics, schemas, times, payloads,
metadata; the container's chunking is the writer's), for small recordings: the export may get faster, never
different (issue 22). A change of format is a deliberate change of these digests, said in the commit."""

from __future__ import annotations

import hashlib
import random
from pathlib import Path

import pytest
from mcap.reader import make_reader

from term.core.protocol import MAX_FRAME, Attitude, Encoder, Height, Mode
from term.data.export import export
from term.data.recording import SessionRecorder
from tests.support.recording_rig import flash_log_csv, record
from tests.support.session_writer import write_session


def _mcap_digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        reader = make_reader(f)
        for m in reader.iter_metadata():
            h.update(repr((m.name, sorted(m.metadata.items()))).encode())
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            h.update(repr((channel.topic, channel.message_encoding, schema.name if schema else None,
                           schema.data if schema else None, msg.log_time, msg.publish_time)).encode())
            h.update(msg.data)
    return h.hexdigest()[:16]


def noisy_session(directory: Path) -> Path:
    """A line with noise: frames split across reads, zeros and runs of bytes longer than a frame without a zero
    (some across reads), a frame cut short."""
    rng = random.Random(7)
    rec = SessionRecorder(directory, 0.0, wall_ns=WALL)
    enc = Encoder()
    for i in range(400):
        data = enc.encode(Attitude(int(Mode.FULL), i, -i, 9000, 0, 0, 0))
        if i % 7 == 0:
            data += enc.encode(Height(101325, 150 + i, 150, 0, 1168, 2150))
        if i % 50 == 3:  # a long run without a delimiter, over three reads
            for _ in range(3):
                rec.received("cable", bytes(rng.randrange(1, 256) for _ in range(MAX_FRAME + 5)), i / 100)
        if i % 31 == 5:
            data = bytes(rng.randrange(0, 256) for _ in range(rng.randrange(1, 40))) + data[3:]
        cut = rng.randrange(0, len(data) + 1)
        rec.received("cable", data[:cut], i / 100)
        rec.received("cable", data[cut:], i / 100 + 0.001)
        rec.poll(i / 100)
    rec.close()
    assert rec.path is not None
    return rec.path


WALL = 1_700_000_000_000_000_000


@pytest.fixture(scope="module")
def sources(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("pinned")
    rec, _ = record(d / "two-links")
    flash = d / "quadrupel-log.csv"
    flash_log_csv(flash)
    assert rec.path is not None
    return {"two-links": rec.path, "full-telemetry": write_session(d / "full", 0.1), "flash": flash,
            "noisy": noisy_session(d / "noisy")}


PINNED = {
    ("two-links", "csv", False, False): "aca624fd9b2aa54c",
    ("two-links", "csv", True, False): "e672b78a00a4884f",
    ("two-links", "mcap", False, False): "daadd16129f5c379",  # issues 34, 35, 37: the new event codes (the schemas
    ("two-links", "mcap", False, True): "825229056e514b46",  # list every name)
    ("full-telemetry", "csv", False, False): "4418701f1c0d787e",
    ("full-telemetry", "csv", True, False): "a84f8d7c1878efe4",
    ("full-telemetry", "mcap", False, False): "dfb8280bd1613bfa",
    ("full-telemetry", "mcap", False, True): "0140ae7813c1669d",
    ("noisy", "csv", False, False): "9bb35b6b00fa0973",
    ("noisy", "mcap", False, False): "830c298ed96496a6",
    ("flash", "csv", False, False): "320403bcfcfd0a83",
    ("flash", "csv", True, False): "29bec888cc3ebce2",
    ("flash", "mcap", False, False): "371543421664ec7b",
}


CASES = [(case, library) for case in PINNED for library in (("sdk", "mcap") if case[1] == "mcap" else ("auto",))]


@pytest.mark.parametrize(("case", "library"), CASES, ids=lambda c: "-".join(map(str, c)) if isinstance(c, tuple) else c)
def test_the_export_is_what_it_was(sources: dict[str, Path], tmp_path: Path, case: tuple[str, str, bool, bool],
                                   library: str) -> None:
    name, fmt, board_units, raw = case
    out = tmp_path / f"out.{fmt}"
    export(sources[name], out, fmt, board_units=board_units, raw=raw, library=library)
    got = hashlib.sha256(out.read_bytes()).hexdigest()[:16] if fmt == "csv" else _mcap_digest(out)
    assert got == PINNED[case]


def test_a_link_name_that_needs_quoting_is_quoted(tmp_path: Path) -> None:
    import csv

    rec = SessionRecorder(tmp_path, 0.0, wall_ns=WALL)
    rec.received('odd, "link"', Encoder().encode(Attitude(int(Mode.SAFE), 1, 2, 3, 0, 0, 0)), 0.5)
    rec.close()
    assert rec.path is not None
    export(rec.path, tmp_path / "out.csv")
    rows = list(csv.DictReader((tmp_path / "out.csv").open(encoding="utf-8", newline="")))
    assert [(r["link"], r["packet"], r["phi_deg"]) for r in rows] == [('odd, "link"', "Attitude", "0.01")]
