"""fcb_sim/cbuild.py: the C builds go to one folder per version of the sources (a changed source builds anew, an
unchanged one never again), whole or not at all, one process at a time; and nothing of fcb_sim needs fcntl at
import (Windows has none): the native filter builds and flies without it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fcb_sim import cbuild

ROOT = Path(__file__).resolve().parents[2]

# A stand-in firmware/: one target whose every run leaves a line in $(RUNS), one that fails.
MAKEFILE = """\
BUILD ?= build
lib: $(BUILD)/sub/lib.txt
$(BUILD)/sub/lib.txt: a.c
\t@mkdir -p $(@D)
\t@echo ran >> $(RUNS)
\t@cat a.c > $@
bad:
\t@echo 'a.c:1: error: expected ; before }' >&2
\t@echo 'one more line' >&2
\t@exit 1
"""


@pytest.fixture
def firmware(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    src = tmp_path / "firmware"
    src.mkdir()
    (src / "Makefile").write_text(MAKEFILE)
    (src / "a.c").write_text("int a;\n")
    monkeypatch.setenv("RUNS", str(tmp_path / "runs"))
    monkeypatch.setenv(cbuild.ENV_BUILD_DIR, str(tmp_path / "cache"))
    return src


def _runs(firmware: Path) -> int:
    runs = firmware.parent / "runs"
    return len(runs.read_text().splitlines()) if runs.exists() else 0


needs_make = pytest.mark.skipif(not cbuild.have("make"), reason="no make: the builds are not tried")


@needs_make
def test_a_changed_source_builds_anew_and_an_unchanged_one_never(firmware: Path) -> None:
    out = cbuild.build("lib", ["sub/lib.txt"], firmware=firmware)
    assert out == firmware.parent / "cache" / cbuild.source_key(firmware)
    assert (out / "sub" / "lib.txt").read_text() == "int a;\n" and _runs(firmware) == 1
    assert cbuild.build("lib", ["sub/lib.txt"], firmware=firmware) == out and _runs(firmware) == 1
    assert [p.name for p in out.iterdir() if p.name.startswith(".building")] == []  # the scratch folder is gone
    (firmware / "a.c").write_text("int b;\n")
    again = cbuild.build("lib", ["sub/lib.txt"], firmware=firmware)
    assert again != out and (again / "sub" / "lib.txt").read_text() == "int b;\n" and _runs(firmware) == 2
    assert (out / "sub" / "lib.txt").read_text() == "int a;\n"  # the other version's build is left as it was


def test_the_key_follows_the_sources_and_the_compiler(firmware: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    key = cbuild.source_key(firmware)
    (firmware / "notes.txt").write_text("not a source")  # what no build reads does not count
    assert cbuild.source_key(firmware) == key
    monkeypatch.setenv("CC", "clang")
    assert cbuild.source_key(firmware) != key
    monkeypatch.delenv("CC")
    (firmware / "a.c").write_text("int a; \n")
    assert cbuild.source_key(firmware) != key


def test_the_builds_go_to_the_users_cache_unless_told(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from platformdirs import user_cache_path

    monkeypatch.delenv(cbuild.ENV_BUILD_DIR, raising=False)
    assert cbuild.build_root() == user_cache_path("quadrupel", appauthor=False) / "build"
    assert cbuild.build_dir().parent == cbuild.build_root()
    monkeypatch.setenv(cbuild.ENV_BUILD_DIR, str(tmp_path))
    assert cbuild.build_dir() == tmp_path / cbuild.source_key()
    assert cbuild.firmware_dir() == ROOT / "firmware" and cbuild.docs_dir() == ROOT / "docs"  # (in a clone)


@needs_make
def test_a_failed_build_is_one_line_and_leaves_nothing(firmware: Path) -> None:
    with pytest.raises(cbuild.BuildError) as err:
        cbuild.build("bad", ["sub/lib.txt"], firmware=firmware, what="the stand-in")
    said = str(err.value)
    assert "\n" not in said and said.startswith("the stand-in does not build: a.c:1: error") and "one more" in said
    out = cbuild.build_dir(firmware)
    assert sorted(p.name for p in out.iterdir()) == [".lock"]


def test_a_missing_tool_is_the_callers_line(firmware: Path) -> None:
    with pytest.raises(cbuild.BuildError, match="^install cc-that-is-not-there$"):
        cbuild.build("lib", ["sub/lib.txt"], firmware=firmware, tools=["cc-that-is-not-there"],
                     missing="install cc-that-is-not-there")
    assert _runs(firmware) == 0


def _blocked_on(lock: Path) -> bool:
    """A process waits for the flock on ``lock`` (Linux's /proc/locks marks a waiter with "->")."""
    inode = f":{os.stat(lock).st_ino} "
    return any("->" in line and inode in line for line in Path("/proc/locks").read_text().splitlines())


@needs_make
@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="waiting on a lock is seen in Linux's /proc/locks")
def test_a_second_builder_waits_for_the_first_and_builds_nothing(firmware: Path) -> None:
    out = cbuild.build_dir(firmware)
    code = ("import sys; from pathlib import Path; from fcb_sim import cbuild\n"
            "print(cbuild.build('lib', ['sub/lib.txt'], firmware=Path(sys.argv[1])))")
    with cbuild.file_lock(out / ".lock"):  # this process is "the first builder", in the middle of its build
        proc = subprocess.Popen([sys.executable, "-c", code, str(firmware)], stdout=subprocess.PIPE, text=True,
                                env={**os.environ, "PYTHONPATH": str(ROOT)})
        deadline = time.monotonic() + 30
        while not _blocked_on(out / ".lock"):
            assert proc.poll() is None, "the second builder did not wait for the lock"
            assert time.monotonic() < deadline, "the second builder never reached the lock"
            time.sleep(0.01)
        (out / "sub").mkdir()
        (out / "sub" / "lib.txt").write_text("built by the first\n")
    stdout, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0 and stdout.strip() == str(out)
    assert _runs(firmware) == 0 and (out / "sub" / "lib.txt").read_text() == "built by the first\n"


# --- no fcntl at import (Windows): the native filter builds and flies without it -----------------------------

WITHOUT_FCNTL = """
import importlib, pkgutil, sys
sys.modules["fcntl"] = None  # as on Windows: importing it fails
import fcb_sim
for info in pkgutil.walk_packages(fcb_sim.__path__, "fcb_sim."):
    if info.name != "fcb_sim.__main__":  # (it runs the command line)
        importlib.import_module(info.name)
from fcb_sim.estimation import native
print(native.why_not(), native.build())
"""


@pytest.mark.skipif(not cbuild.have("cc", "make"), reason="no C compiler (cc) or make: the native build is not tried")
def test_nothing_needs_fcntl_and_the_filter_builds_without_it(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT), cbuild.ENV_BUILD_DIR: str(tmp_path)}
    res = subprocess.run([sys.executable, "-c", WITHOUT_FCNTL], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["None", str(tmp_path / cbuild.source_key() / "libikfq.so")]
