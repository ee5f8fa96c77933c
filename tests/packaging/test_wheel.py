"""The wheel is the product: `python -m build` makes it from a copy of the sources (sdist, then the wheel from the
sdist, as pip does from PyPI), pip installs it with the locked versions (constraints.txt) into a fresh venv, and
from another directory, with no clone in reach, it flies: `fcb-sim run --scenario hover --board c` builds the C
board from the sources the wheel carries, `term params --sim list` reads the simulated board's parameters, `term
--sim` flies on a pseudo-terminal and records the session, and `term export` writes that recording out. Every
build lands in the user's cache directory given; nothing is written into the installation (its file list, sizes
and times are the same after). The help names where docs/ is, and every docs/ file it names is there.

One venv for the module, installed by uv where make test installed it, else by pip. Needs a C compiler and
make (--board c).
"""

from __future__ import annotations

import csv
import os
import re
import select
import shutil
import struct
import subprocess
import sys
import time
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from fcb_sim import cbuild

ROOT = Path(__file__).resolve().parents[2]
IGNORED = shutil.ignore_patterns(".git", ".venv*", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache",
                                 ".hypothesis", ".ruff_cache", "logs", "*.pyc")

pytestmark = [
    pytest.mark.skipif(not cbuild.have(os.environ.get("CC", "cc"), "make"),
                       reason="no C compiler (cc) or make: the wheel's --board c cannot build, so it is not tried"),
    pytest.mark.skipif(not hasattr(os, "openpty"), reason="term --sim here flies over a pseudo-terminal"),
]


@dataclass
class Installed:
    venv: Path
    site: Path  # the venv's site-packages: the installation
    wheel: Path
    home: Path  # the user's directories (cache, data, logs) and the working directory: outside the installation
    env: dict[str, str]

    def bin(self, name: str) -> str:
        return str(self.venv / ("Scripts" if os.name == "nt" else "bin") / name)

    def run(self, *argv: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
        return subprocess.run([self.bin(argv[0]), *argv[1:]], capture_output=True, text=True, timeout=timeout,
                              cwd=self.home, env=self.env, stdin=subprocess.DEVNULL)

    @property
    def cache(self) -> Path:
        return self.home / "cache" / "quadrupel" / "build"


def _files(root: Path) -> dict[str, tuple[int, int]]:
    return {p.relative_to(root).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in root.rglob("*") if p.is_file()}


def _check(proc: subprocess.CompletedProcess[str]) -> subprocess.CompletedProcess[str]:
    assert proc.returncode == 0, f"{proc.args}: exit {proc.returncode}\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
    return proc


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Installed]:
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=IGNORED)
    shutil.rmtree(src / "firmware" / "build", ignore_errors=True)
    _check(subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(tmp / "dist"), str(src)],
                          capture_output=True, text=True, timeout=180))
    (wheel,) = (tmp / "dist").glob("quadrupel-*.whl")
    venv = tmp / "venv"
    # No pip inside (ensurepip costs 15 s): this interpreter's pip installs into it (pip --python, pip >= 22.3).
    _check(subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], capture_output=True, text=True,
                          timeout=120))
    python = venv / ("Scripts" if os.name == "nt" else "bin") / "python"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV", "QUADRUPEL_"))}
    # uv where make test put it beside this interpreter (its cache holds the wheels: 2 s, where pip took 11 s)
    uv = shutil.which("uv", path=str(Path(sys.executable).parent))
    installer = [uv, "pip", "install", "--python", str(python)] if uv else [
        sys.executable, "-m", "pip", "--python", str(python), "install", "--no-compile", "--disable-pip-version-check"]
    _check(subprocess.run([*installer, "-q", "-c", str(ROOT / "constraints.txt"), str(wheel)],
                          capture_output=True, text=True, timeout=300, env=env))
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                               capture_output=True, text=True, check=True, env=env).stdout.strip())
    home = tmp / "home"
    home.mkdir()
    env.update({"XDG_CACHE_HOME": str(home / "cache"), "XDG_DATA_HOME": str(home / "data"),
                "XDG_CONFIG_HOME": str(home / "config"), "QUADRUPEL_LOG_DIR": str(home / "log"),
                "PYTHONPYCACHEPREFIX": str(home / "pycache")})  # (Python's bytecode cache: kept out too)
    if not sys.platform.startswith("linux"):  # (platformdirs reads XDG_CACHE_HOME on Linux only)
        env[cbuild.ENV_BUILD_DIR] = str(home / "cache" / "quadrupel" / "build")
    yield Installed(venv, site, wheel, home, env)


def test_the_wheel_carries_the_c_sources_and_the_docs(installed: Installed) -> None:
    names = set(zipfile.ZipFile(installed.wheel).namelist())
    wanted = {f"fcb_sim/_firmware/{p.relative_to(ROOT / 'firmware').as_posix()}"
              for p in cbuild.source_files(ROOT / "firmware")}
    assert wanted <= names and "fcb_sim/_firmware/board/qb_board.c" in wanted
    assert {f"term/_docs/{p.name}" for p in (ROOT / "docs").glob("*.md")} <= names
    assert not [n for n in names if n.endswith(".so") or "/build/" in n or n.endswith(("gen_c.py", "gen_protocol.py"))]
    meta = zipfile.ZipFile(installed.wheel).read(next(n for n in names if n.endswith("/METADATA"))).decode()
    urls = dict(re.findall(r"^Project-URL: ([^,]+), (\S+)$", meta, re.M))
    assert set(urls) >= {"Homepage", "Documentation", "Changelog", "Issues"}, meta[:2000]


def test_every_package_is_in_the_wheel() -> None:
    """pyproject.toml lists the packages by name (the data-only ones need it): a new one must be added there."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for tree in ("term", "fcb_sim")
             for p in (ROOT / tree).rglob("__init__.py")}
    assert listed - {"fcb_sim._firmware", "term._docs"} == found


def test_the_installed_wheel_flies_and_writes_nothing_into_itself(installed: Installed) -> None:
    before = _files(installed.site)
    where = _check(installed.run("python", "-c", "import fcb_sim.cbuild as c, term; print(c.firmware_dir()); "
                                 "print(term.__file__)")).stdout.split()
    assert where == [str(installed.site / "fcb_sim" / "_firmware"), str(installed.site / "term" / "__init__.py")]

    # the C board from the wheel's sources, built into the user's cache
    res = _check(installed.run("fcb-sim", "run", "--scenario", "hover", "--board", "c", "--json", timeout=180))
    last = res.stdout.strip().splitlines()[-1]
    assert '"board": "c"' in last and '"mode": "FULL"' in last, res.stdout[-1000:]
    builds = list(installed.cache.glob("*/libqb_host.so"))
    assert len(builds) == 1, sorted(installed.home.rglob("*.so"))

    # the simulated board's parameters
    res = _check(installed.run("term", "params", "--sim", "list", timeout=90))
    assert re.search(r"^\s+ctrl\.p1\s+\S+", res.stdout, re.M), res.stdout

    # term --sim flies on a pseudo-terminal and records the session; term export writes it out
    _fly_term_sim(installed)
    out = installed.home / "session.csv"
    res = _check(installed.run("term", "export", "--latest", "-o", str(out)))
    with out.open() as f:
        rows = list(csv.reader(f))
    assert len(rows) > 2 and any("mode" in c for c in rows[0]), rows[:3]

    after = _files(installed.site)
    assert after == before, {k: (before.get(k), after.get(k)) for k in set(before) ^ set(after) | {
        k for k in before if k in after and before[k] != after[k]}}
    built = sorted(p.relative_to(installed.home).as_posix() for p in installed.home.rglob("*.so"))
    assert built and all(b.startswith("cache/quadrupel/build/") for b in built), built


def _fly_term_sim(installed: Installed) -> None:
    """`term --sim` in a 120x40 pseudo-terminal until the link is up, then Ctrl+Q (the recording closed whole)."""
    import fcntl
    import termios

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    proc = subprocess.Popen([installed.bin("term"), "--sim", "--no-joystick", "--no-radio"], stdin=slave,
                            stdout=slave, stderr=slave, cwd=installed.home, start_new_session=True,
                            env={**installed.env, "TERM": "xterm-256color"})
    os.close(slave)
    drawn = b""
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and b"link OK" not in drawn:
            if select.select([master], [], [], 0.1)[0]:
                try:
                    drawn += os.read(master, 65536)
                except OSError:
                    break
        assert b"link OK" in drawn, drawn[-600:]
        # Ctrl+Q, again every 3 s until it quits: on a loaded machine the first can come before the keys are read
        deadline, pressed = time.monotonic() + 90, 0.0
        while proc.poll() is None and time.monotonic() < deadline:
            if time.monotonic() - pressed > 3:
                os.write(master, b"\x11")
                pressed = time.monotonic()
            if select.select([master], [], [], 0.1)[0]:
                try:
                    os.read(master, 65536)  # (drained: a full pty would block its writes)
                except OSError:
                    break
        assert proc.wait(timeout=30) == 0, "term --sim did not quit on Ctrl+Q"
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=20)
        os.close(master)


def test_the_help_names_where_the_docs_are(installed: Installed) -> None:
    docs = installed.site / "term" / "_docs"
    for argv in (("term", "--help"), ("term", "params", "--help"), ("fcb-sim", "serve", "--help"),
                 ("fcb-sim", "--help")):
        text = " ".join(_check(installed.run(*argv)).stdout.split())
        unwrapped = "".join(text.split())  # (argparse wraps a long path at its hyphens)
        assert "".join(f"The docs/ files the help names are in {docs}.".split()) in unwrapped, text[-400:]
        for name in re.findall(r"docs/([\w-]+\.md)", text):
            assert (docs / name).is_file(), name

