"""Where `term` keeps its own log: a file in the platform's log directory, and the simulated board's stderr.

While the TUI owns the terminal nothing can be printed, so what bleak, bumble, Textual and we log would vanish;
``setup_logging`` sends it to ``term.log`` in ``log_dir()`` instead (warnings and up; everything of ours with
``--verbose``). ``child_log`` opens the file a child process's stderr goes to (``fcb-sim.log`` for ``term
--sim``), kept after the child ends. ``QUADRUPEL_LOG_DIR`` overrides the directory (tests, portable installs).

Logging never stops `term` from flying: a directory that cannot be made means no log file, not an error.
Files are bounded: a file past ``MAX_BYTES`` is rotated to ``NAME.1`` when it is next opened.
"""

from __future__ import annotations

import logging
import logging.handlers
import os
import time
from pathlib import Path
from typing import IO

APP_NAME = "quadrupel"
ENV_DIR = "QUADRUPEL_LOG_DIR"
MAX_BYTES = 1_000_000  # per file; one older copy is kept
FORMAT = "%(asctime)s %(process)d %(levelname)s %(name)s: %(message)s"
_handler: logging.Handler | None = None  # ours on the root logger: replaced, never stacked, by a second setup


def log_dir() -> Path:
    """``$QUADRUPEL_LOG_DIR``, else the platform's user log directory (e.g. ``~/.local/state/quadrupel/log``)."""
    override = os.environ.get(ENV_DIR)
    if override:
        return Path(override).expanduser()
    from platformdirs import user_log_path

    return user_log_path(APP_NAME, appauthor=False)


def _rotate(path: Path) -> None:
    try:
        if path.stat().st_size > MAX_BYTES:
            os.replace(path, path.with_name(path.name + ".1"))
    except OSError:
        pass


def setup_logging(verbose: bool = False, name: str = "term.log") -> Path | None:
    """Log to ``log_dir()/name``: warnings from every library, and with ``verbose`` INFO from them and DEBUG
    from ours. Returns the file's path, or None if it cannot be written (then nothing is logged to a file)."""
    path = log_dir() / name
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _rotate(path)
        handler = logging.FileHandler(path, encoding="utf-8", delay=not verbose)
    except OSError:
        return None
    handler.setFormatter(logging.Formatter(FORMAT))
    global _handler
    root = logging.getLogger()
    if _handler is not None:
        root.removeHandler(_handler)
        _handler.close()
    root.addHandler(handler)
    _handler = handler
    root.setLevel(logging.INFO if verbose else logging.WARNING)
    logging.getLogger("term").setLevel(logging.DEBUG if verbose else logging.WARNING)
    logging.captureWarnings(True)  # DeprecationWarning and friends from the libraries: into the file too
    if verbose:
        logging.getLogger("term").info("term started, log level DEBUG")
    return path


def child_log(name: str) -> tuple[IO[bytes] | None, int]:
    """A file in ``log_dir()`` for a child process's stderr, opened for appending, with a header line, and the
    offset where this run's output starts (None, 0 if it cannot be opened)."""
    path = log_dir() / name
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _rotate(path)
        f = open(path, "a+b")  # noqa: SIM115 (the child appends; the caller reads it back and closes it)
    except OSError:
        return None, 0
    f.write(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')} started by term (pid {os.getpid()})\n".encode())
    f.flush()
    return f, f.tell()
