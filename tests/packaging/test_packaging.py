"""The package as a user installs and starts it: the entry points in a subprocess (--version, python -m, shell
completion), start-up where POSIX-only parts are missing (as on Windows), the log directory, the floors in
pyproject.toml against constraints-lowest.txt (and, under `make test-lowest`, against what is installed), the
lock file, and the sdist's contents and metadata."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tarfile
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest
from packaging.requirements import Requirement

from term.core.protocol import PROTOCOL_VERSION

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def _run(argv: list[str], env: dict[str, str] | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=ROOT,
                          env={**os.environ, **(env or {})}, stdin=subprocess.DEVNULL)


def _script(name: str) -> str:
    path = BIN / name
    if not path.exists():
        pytest.skip(f"{name} is not installed next to {sys.executable} (pip install -e .)")
    return str(path)


def _requirements(extras: tuple[str, ...] = ("plot", "analysis", "test", "bench", "docs")) -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(project["dependencies"])
    for extra in extras:
        reqs += project["optional-dependencies"][extra]
    return [Requirement(r) for r in reqs]


def _pins(name: str) -> dict[str, str]:
    pins = {}
    for line in (ROOT / name).read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            req = Requirement(line)
            (spec,) = req.specifier
            assert spec.operator == "==", line
            pins[req.name.lower()] = spec.version
    return pins


# --- the entry points ------------------------------------------------------------------------------------------


def test_version_and_python_dash_m() -> None:
    expected = f"{version('quadrupel')} (protocol v{PROTOCOL_VERSION})"
    out = _run([_script("term"), "--version"])
    assert out.returncode == 0 and out.stdout.strip() == f"term {expected}", out
    out = _run([_script("fcb-sim"), "--version"])
    assert out.returncode == 0 and out.stdout.strip() == f"fcb-sim {expected}", out
    out = _run([sys.executable, "-m", "term", "--help"])
    assert out.returncode == 0 and out.stdout.startswith("usage: term") and "--version" in out.stdout, out
    out = _run([sys.executable, "-m", "fcb_sim", "serve", "--scenario", "nope"])  # its one-line errors too
    assert out.returncode == 2 and out.stderr.startswith("fcb-sim: ") and out.stderr.count("\n") == 1, out


@pytest.mark.parametrize(("line", "words"), [
    ("term --ser", ["--serial"]),
    ("term rec", ["recordings"]),
    ("term ", ["plot", "scan", "export", "recordings", "replay", "params"]),
    ("term scan --ti", ["--timeout"]),
    ("term plot -", ["--verbose", "--version", "--output"]),
    ("term --sim --preset ", ["default", "report"]),
    ("term --sim --scenario ", ["bench", "breeze", "gusty", "low-battery", "no-spikes"]),
    ("term --sim --lesson ", ["1", "2", "8"]),
    ("term params --sim ", ["list", "get", "set", "save", "load", "diff"]),
    ("fcb-sim se", ["serve"]),
    ("fcb-sim run --ver", ["--verbose", "--version"]),
])
def test_shell_completion(tmp_path: Path, line: str, words: list[str]) -> None:
    pytest.importorskip("argcomplete")
    out_file = tmp_path / "completions"
    env = {"_ARGCOMPLETE": "1", "COMP_LINE": line, "COMP_POINT": str(len(line)),
           "_ARGCOMPLETE_STDOUT_FILENAME": str(out_file)}
    res = _run([_script(line.split()[0])], env)
    assert res.returncode == 0, res
    offered = out_file.read_text().replace("\v", " ").split()
    assert all(w in offered for w in words), offered


# --- start-up without the POSIX-only parts (as on Windows) -----------------------------------------------------

WITHOUT_POSIX = """
import os, select, signal, sys
del signal.SIGHUP, os.openpty, select.poll  # what Windows lacks (pyserial brings its own backend there)
from term.transports import serial
real_open = serial.SerialTransport.open
async def traced_open(self):
    print("opening", self.port, file=sys.stderr, flush=True)
    return await real_open(self)
serial.SerialTransport.open = traced_open
import term.cli.main
term.cli.main.has_terminal = lambda: True  # (no terminal here: what comes after that check is tested)
sys.exit(term.cli.main.main(sys.argv[1:]))
"""


def test_term_starts_without_sighup_and_ptys() -> None:
    res = _run([sys.executable, "-c", WITHOUT_POSIX, "--serial", "COM3", "--no-joystick", "--no-record"])
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    # it got as far as opening the port, and that failure is one line
    assert lines[0] == "opening COM3" and len(lines) == 2, res.stderr
    assert lines[1].startswith("term: ") and "COM3" in lines[1]


def test_fcb_sim_without_ptys() -> None:
    code = (WITHOUT_POSIX.split("from term.transports")[0] + "sys.modules['termios'] = sys.modules['tty'] = None\n"
            "from fcb_sim.cli import main\nsys.exit(main(sys.argv[1:]))")  # (None in sys.modules: import fails)
    res = _run([sys.executable, "-c", code, "serve", "--pty"])
    assert res.returncode == 2 and "Traceback" not in res.stderr
    # one line that names the way that works without them: the TCP link (issue 33)
    assert res.stderr.startswith("fcb-sim: serve --pty needs pseudo-terminals") and res.stderr.count("\n") == 1
    assert "--tcp" in res.stderr and "socket://" in res.stderr, res.stderr
    res = _run([sys.executable, "-c", code, "run", "--list"])
    assert res.returncode == 0 and "hover" in res.stdout, res.stderr


# --- what term keeps in its log directory ----------------------------------------------------------------------


def test_no_port_names_the_serial_ports(tmp_path: Path) -> None:
    from serial.tools import list_ports

    (tmp_path / "term.toml").write_text("")
    res = _run([_script("term"), "--config", str(tmp_path / "term.toml")])
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "no board given" in res.stderr
    ports = [p.device for p in list_ports.comports()]
    assert all(p in res.stderr for p in ports) and ("serial ports seen here" if ports else "no serial ports") \
        in res.stderr


# A scenario term offers and the board does not know (two versions), in a terminal: the simulator fails to start.
SKEWED = """
import sys
import term.cli.main, term.core.protocol
term.core.protocol.SIM_SCENARIOS += ("nope",)
term.cli.main.has_terminal = lambda: True
sys.exit(term.cli.main.main(sys.argv[1:]))
"""


def test_the_simulators_stderr_and_the_log_are_kept(tmp_path: Path) -> None:
    env = {"QUADRUPEL_LOG_DIR": str(tmp_path)}
    res = _run([sys.executable, "-c", SKEWED, "--sim", "--scenario", "nope", "--no-joystick", "--verbose"], env)
    assert res.returncode == 2 and f"term: logging to {tmp_path / 'term.log'}" in res.stderr
    assert "unknown scenario 'nope'" in res.stderr.splitlines()[-1]
    kept = (tmp_path / "fcb-sim.log").read_text()
    assert "started by term" in kept and "fcb-sim: unknown scenario 'nope'" in kept
    assert "term started" in (tmp_path / "term.log").read_text()


def test_the_log_file_takes_library_warnings(tmp_path: Path) -> None:
    code = ("import logging, warnings\nfrom term.session.applog import setup_logging\np = setup_logging()\n"
            "logging.getLogger('bumble.device').warning('a bumble warning')\nwarnings.warn('a py warning')\n"
            "logging.getLogger('term.x').info('not without --verbose')\nprint(p)")
    res = _run([sys.executable, "-c", code], {"QUADRUPEL_LOG_DIR": str(tmp_path)})
    text = Path(res.stdout.strip()).read_text()
    assert "WARNING bumble.device: a bumble warning" in text and "a py warning" in text
    assert "not without --verbose" not in text


# --- the floors, the lock and the sdist ------------------------------------------------------------------------


def test_every_floor_is_pinned_in_constraints_lowest() -> None:
    floors: dict[str, str] = {}
    # (the bench extra's floors are not proven: no test imports them)
    for req in _requirements(("plot", "analysis", "test")):
        lows = [s.version for s in req.specifier if s.operator == ">="]
        assert len(lows) == 1, f"{req}: every dependency has one floor (>=) that make test-lowest proves"
        assert floors.setdefault(req.name.lower(), lows[0]) == lows[0], f"{req}: one floor in every extra"
    assert floors == _pins("constraints-lowest.txt")


# --- extras by job (issue 25): the default install flies; plotting and the offline fits are extras -----------

FLYING = {"textual", "pyserial", "bleak", "bumble", "pygame-ce", "platformdirs", "mcap", "argcomplete", "tomlkit"}


def test_the_default_install_is_what_flying_needs() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    default = {Requirement(r).name.lower() for r in project["dependencies"]}
    assert default == FLYING  # no matplotlib, no numpy: 169 MiB of the 329 MB install flew nothing
    extras = project["optional-dependencies"]
    assert [Requirement(r).name for r in extras["plot"]] == ["matplotlib"]
    assert [Requirement(r).name for r in extras["analysis"]] == ["numpy"]
    # and the installed metadata says the same (what pip resolved from)
    from importlib.metadata import requires

    unconditional = {Requirement(r).name.lower() for r in requires("quadrupel") or [] if "extra ==" not in r}
    assert unconditional == FLYING


BLOCKED = """
import importlib, pkgutil, sys
for name in ("numpy", "matplotlib", "vqf", "ahrs"):  # as if not installed: import fails
    sys.modules[name] = None
import term, fcb_sim
for package in (term, fcb_sim):
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        if not info.name.endswith("__main__"):
            importlib.import_module(info.name)
from term.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_flying_imports_no_numpy_nor_matplotlib(tmp_path: Path) -> None:
    """Every module of term and fcb_sim imports without them, and term plot says in one line how to add them."""
    (tmp_path / "log.csv").write_text("t_us,phi\n0,1\n")
    res = _run([sys.executable, "-c", BLOCKED, "plot", str(tmp_path / "log.csv"), "-o", str(tmp_path / "p.png")])
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert res.stderr == ("term: term plot needs matplotlib, which the default install leaves out: "
                          "pip install 'quadrupel[plot]' (in a clone: .venv/bin/pip install -e '.[plot]')\n")
    assert not (tmp_path / "p.png").exists()
    code = "import sys\nsys.modules['numpy'] = None\nfrom fcb_sim.estimation.fixed import fit_atan2_correction\n" \
           "fit_atan2_correction([(1.0, 1.0)])"
    res = _run([sys.executable, "-c", code])
    assert res.returncode == 1 and "needs numpy: pip install 'quadrupel[analysis]'" in res.stderr


# --- the command line as a user meets it ----------------------------------------------------------------------


def test_help_names_every_command_with_a_line() -> None:
    out = _run([_script("term"), "--help"])
    assert out.returncode == 0
    commands = out.stdout.split("commands (none: fly")[1].split("flying (no command)")[0]
    for name in ("plot", "scan", "export", "recordings", "replay", "params"):
        assert re.search(rf"^    {name} +\S", commands, re.M), commands
    for option in ("--serial PATH", "--ble ADDR", "--sim", "-v, --verbose", "--version"):
        assert option in out.stdout


def test_no_terminal_is_one_line_and_exit_2() -> None:
    res = _run([_script("term"), "--sim", "--no-joystick"], timeout=30)  # stdin /dev/null, stdout a pipe
    assert res.returncode == 2 and res.stdout == "" and res.stderr.count("\n") == 1, res
    assert res.stderr.startswith("term: no terminal: the screen needs one on stdin and stdout")


def test_the_lock_satisfies_pyproject() -> None:
    pins = _pins("constraints.txt")
    for req in _requirements():
        assert req.name.lower() in pins, f"constraints.txt does not pin {req.name}"
        assert req.specifier.contains(pins[req.name.lower()]), f"constraints.txt: {req.name} outside {req}"


@pytest.mark.skipif(not os.environ.get("QUADRUPEL_EXPECT_FLOORS"), reason="only under make test-lowest")
def test_running_at_the_floors() -> None:
    installed = {name: version(name) for name in _pins("constraints-lowest.txt")}
    assert installed == _pins("constraints-lowest.txt")


def test_the_sdist_carries_docs_tests_and_licence(tmp_path: Path) -> None:
    setuptools = pytest.importorskip("setuptools")
    if int(setuptools.__version__.split(".")[0]) < 77:
        pytest.skip("setuptools >= 77 builds the SPDX license string")
    code = "import sys\nfrom setuptools import build_meta\nprint(build_meta.build_sdist(sys.argv[1]))"
    res = _run([sys.executable, "-W", "always", "-c", code, str(tmp_path)], timeout=120)
    assert res.returncode == 0, res.stderr
    # no "project.license as a TOML table is deprecated" (nor any other warning about the licence)
    assert not [ln for ln in res.stderr.lower().splitlines() if "licen" in ln and "deprecat" in ln], res.stderr
    with tarfile.open(tmp_path / res.stdout.strip().splitlines()[-1]) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
        info = tar.extractfile(next(n for n in tar.getnames() if n.endswith("/PKG-INFO")))
        assert info is not None
        meta = info.read().decode()
    for path in ("LICENSE", "setup.py", "CHANGELOG.md", "CONTRIBUTING.md", "mkdocs.yml", "docs/user-guide.md",
                 "docs/protocol.md", "tests/vectors/protocol.json",
                 "tests/fixtures/broad_07_fast_rotation_excerpt.csv.gz", "tests/conftest.py", "constraints.txt",
                 "term/ui/app.tcss", "fcb_sim/cli.py"):
        assert path in names, path
    assert "License-Expression: MIT" in meta and "License-File: LICENSE" in meta
    assert "Classifier: Operating System :: Microsoft :: Windows" in meta
