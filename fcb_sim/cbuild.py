"""Where the C sources are, where their host builds go, and the lock that lets processes build them at once.

Three parts of fcb_sim compile firmware/ on first use: the native RAW filter (fcb_sim/estimation/native.py,
``make native``), the C board (fcb_sim/hosts/cboard.py, ``make board``) and the Cortex-M0 task bodies
(fcb_sim/hosts/m0emu.py, ``make m0-tasks``). All of them go through :func:`build`.

- The sources, :func:`firmware_dir`: in a clone the repository's ``firmware/``; installed from a wheel the same
  files shipped inside the package as ``fcb_sim/_firmware/`` (pyproject.toml maps that package to ``firmware/``,
  so the folder stays at the top of the repository and no copy is kept in git). :data:`SOURCES` names what a
  build reads; the wheel carries exactly those.
- The builds, :func:`build_dir`: the user's cache directory (platformdirs: ``~/.cache/quadrupel/build`` on Linux,
  ``~/Library/Caches/quadrupel/build`` on macOS, ``%LOCALAPPDATA%\\quadrupel\\Cache\\build`` on Windows), never
  the installation (site-packages is often read-only, and a build there outlives an uninstall), one folder per
  :func:`source_key`: a hash of the sources and of the compiler settings, so a changed source builds anew and
  two versions side by side never share a library. ``QUADRUPEL_BUILD_DIR`` (or a parameter) puts the builds
  elsewhere (the tests do).
- Each output is built in a scratch folder and moved in whole (os.replace), under :func:`file_lock`, so a process
  that finds the file finds it complete and two processes starting together compile once.

Stdlib and platformdirs only (floor 0: anything in fcb_sim may use it). The POSIX and Windows lock modules are
imported inside :func:`file_lock`, so importing this module works everywhere; what only a build needs is imported
when one runs (fcb-sim's help names :func:`docs_dir` at every start).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path

ENV_BUILD_DIR = "QUADRUPEL_BUILD_DIR"
# What the host builds read, relative to firmware/ (the wheel ships these: pyproject.toml's package-data says the
# same, tests/packaging/test_wheel.py checks it). The tests, the examples and the generator stay in the clone.
SOURCES = ("Makefile", "*.c", "*.h", "board/*.c", "board/*.h", "m0/*.c", "m0/*.ld")
# Settings the Makefile reads from the environment: a build with other ones is another build.
BUILD_ENV = ("CC", "ARM_CC", "OPT", "CPPFLAGS", "CFLAGS", "LDFLAGS")
_HERE = Path(__file__).resolve().parent
_THREADS = threading.Lock()  # (the file lock serialises processes; this, threads of one process on every OS)


class BuildError(RuntimeError):
    """A build that failed or cannot run; its message is one line."""


def firmware_dir() -> Path:
    """The C sources: the clone's firmware/ beside the package, else the copy installed inside it."""
    clone = _HERE.parent / "firmware"
    return clone if (clone / "Makefile").is_file() else _HERE / "_firmware"


def docs_dir() -> Path:
    """The documentation the help texts name (docs/...): the clone's docs/, else the copy the wheel installs
    beside the packages (pyproject.toml maps ``term._docs`` to docs/)."""
    clone = _HERE.parent / "docs"
    return clone if (clone / "architecture.md").is_file() else _HERE.parent / "term" / "_docs"


def source_files(firmware: Path | None = None) -> list[Path]:
    """The files a build reads (:data:`SOURCES`), sorted."""
    root = firmware or firmware_dir()
    return sorted({p for pattern in SOURCES for p in root.glob(pattern) if p.is_file()})


def source_key(firmware: Path | None = None) -> str:
    """A hash of the sources' names and bytes, the machine and the compiler settings (16 hex digits)."""
    import hashlib
    import platform

    root = firmware or firmware_dir()
    h = hashlib.sha256()
    for path in source_files(root):
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    h.update(platform.system().encode() + b"\0" + platform.machine().encode())
    for name in BUILD_ENV:
        h.update(f"\0{name}={os.environ.get(name, '')}".encode())
    return h.hexdigest()[:16]


def build_root() -> Path:
    """Where the builds go: ``QUADRUPEL_BUILD_DIR``, else ``build`` in the user's cache directory."""
    given = os.environ.get(ENV_BUILD_DIR)
    if given:
        return Path(given).expanduser()
    from platformdirs import user_cache_path

    return user_cache_path("quadrupel", appauthor=False) / "build"


def build_dir(firmware: Path | None = None) -> Path:
    """This version's build folder (under :func:`build_root`, named by :func:`source_key`)."""
    return build_root() / source_key(firmware)


def have(*programs: str) -> bool:
    """Every program is on PATH."""
    return all(shutil.which(p) is not None for p in programs)


@contextlib.contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` (created if missing) against other processes; blocks until it is free.
    fcntl.flock on POSIX, msvcrt.locking on Windows, each imported here, so this module imports everywhere. Where
    neither exists no lock is taken: :func:`build` moves whole files in, so two builders cost time, not a torn
    library."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+b") as f:
        try:
            import fcntl
        except ImportError:
            fcntl = None  # type: ignore[assignment]
        if fcntl is not None:
            fcntl.flock(f, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(f, fcntl.LOCK_UN)
            return
        try:
            import msvcrt
        except ImportError:
            yield
            return
        while True:
            f.seek(0)
            try:
                msvcrt.locking(f.fileno(), msvcrt.LK_LOCK, 1)  # retries for ~10 s, then OSError: wait on
                break
            except OSError:
                continue
        try:
            yield
        finally:
            f.seek(0)
            msvcrt.locking(f.fileno(), msvcrt.LK_UNLCK, 1)


def build(target: str, outputs: Sequence[str], *, out: Path | None = None, firmware: Path | None = None,
          tools: Sequence[str] = (), missing: str = "", what: str | None = None) -> Path:
    """``make -C firmware BUILD=<scratch> target``, its ``outputs`` (paths relative to the build folder) moved
    into ``out`` (default :func:`build_dir`); returns ``out``. Nothing runs when every output is there already.
    :class:`BuildError` (one line): ``missing`` when one of ``tools`` (make is always one) is not on PATH, or
    the compiler's last words, naming ``what``, when the build fails."""
    import subprocess
    import tempfile

    firmware = firmware or firmware_dir()
    out = Path(out) if out is not None else build_dir(firmware)
    wanted = [out / o for o in outputs]
    if all(p.is_file() for p in wanted):
        return out
    if not have("make", *tools):
        raise BuildError(missing or f"{what or target} needs make and {', '.join(tools) or 'a C compiler'}")
    if not (firmware / "Makefile").is_file():
        raise BuildError(f"the C sources are missing from this installation (looked in {firmware})")
    with _THREADS, file_lock(out / ".lock"):
        if all(p.is_file() for p in wanted):  # another process built them while this one waited
            return out
        with tempfile.TemporaryDirectory(prefix=".building-", dir=out) as scratch:
            proc = subprocess.run(["make", "-s", "-C", str(firmware), f"BUILD={scratch}", target],
                                  capture_output=True, text=True, stdin=subprocess.DEVNULL)
            if proc.returncode != 0:
                said = " ".join((proc.stderr or proc.stdout).split())[-400:]
                raise BuildError(f"{what or target} does not build: {said}")
            for name, dest in zip(outputs, wanted, strict=True):
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(Path(scratch) / name, dest)
    return out
