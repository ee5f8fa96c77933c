"""The command line's small faults of issue 34, each through ``term.cli.main.main`` as a user types it: a negative
exponent value for ``params set``, ``params`` without an action, ``params save`` to a FIFO, ``recordings --dir`` on a
missing folder, ``export -o`` into a missing folder, ``term plot`` of ``term export``'s own CSV, the CSV's column
names, ``fcb-sim run --scenario`` completion."""

from __future__ import annotations

import csv
import os
import time
from pathlib import Path

import pytest

from term.cli.main import main
from term.core.protocol import Attitude, Mode, Profile, Status, encode
from term.data.recording import SessionRecorder


def recording(directory: Path) -> Path:
    now = time.monotonic()
    rec = SessionRecorder(directory, now, meta={"cable": "test"})
    for i in range(30):
        rec.received("cable", encode(Attitude(Mode.FULL, 100 * i, -50, 9000, 16, -8, 3), i & 0xFF), now + 0.02 * i)
        rec.received("cable", encode(Status(1, 0, 0, 0, 100, 42, 3, 0), i & 0xFF), now + 0.02 * i)
    rec.received("cable", encode(Profile(2, 1979, 2560, 3000, 2500, 0), 0), now + 0.7)
    rec.close()
    assert rec.path is not None
    return rec.path


def test_params_set_takes_a_negative_exponent_value(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "--sim", "set", "ctrl.p1", "-1e308"]) == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments" not in err and "ctrl.p1" in err, err


def test_params_without_an_action_names_the_actions(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "--sim"]) == 2
    err = capsys.readouterr().err
    assert "words" not in err and "list" in err and "set" in err, err


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX FIFOs")
def test_params_save_refuses_a_fifo(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert main(["params", "--sim", "save", str(fifo)]) == 2  # refused before the board is asked: never hangs
    assert "not a regular file" in capsys.readouterr().err


def test_recordings_on_a_missing_folder_is_a_usage_error(tmp_path: Path) -> None:
    assert main(["recordings", "--dir", str(tmp_path / "nonexistent")]) == 2


def test_export_does_not_create_folders_without_a_word(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = recording(tmp_path / "rec")
    out = tmp_path / "no" / "such" / "x.csv"
    assert main(["export", str(src), "-o", str(out)]) == 0
    assert out.exists() and f"made folder {out.parent}" in capsys.readouterr().err
    from term.data.export import ExportError, export  # the library itself makes none

    with pytest.raises(ExportError, match="does not exist"):
        export(src, tmp_path / "elsewhere" / "y.csv", None, False)


def test_plot_takes_exports_own_csv_and_its_columns_have_one_unit(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    src = recording(tmp_path / "rec")
    out = tmp_path / "flight.csv"
    assert main(["export", str(src), "-o", str(out)]) == 0
    with out.open(encoding="utf-8") as f:
        header = next(csv.reader(f))
    assert "mean_us" in header and not any(h.endswith("_us_us") for h in header), header
    image = tmp_path / "flight.png"
    assert main(["plot", str(out), "-o", str(image)]) == 0 and image.stat().st_size > 0


def test_fcb_sim_run_completes_its_scenarios() -> None:
    import argparse

    from fcb_sim.cli import build_parser
    from fcb_sim.lab.scenarios import SCENARIOS

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    run = sub.choices["run"]
    scenario = next(a for a in run._actions if "--scenario" in a.option_strings)
    assert set(scenario.completer()) == set(SCENARIOS)  # type: ignore[attr-defined]
