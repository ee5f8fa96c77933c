"""Another platform's shape for a child process on Linux (tests/platform): the environment that puts
tests/platform/shapes/NAME/sitecustomize.py first on the child's PYTHONPATH, with this checkout after it (the data
and log folders are the test run's own: tests/conftest.py sets them in the environment)."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SHAPES = ROOT / "tests" / "platform" / "shapes"


def shaped_env(shape: str, home: Path | None = None, **extra: str) -> dict[str, str]:
    """os.environ for a child shaped as ``shape`` ("darwin" or "win32"); with ``home`` its HOME there (the darwin
    shape's platformdirs looks under ~/Library, not at XDG's variables)."""
    path = [str(SHAPES / shape), str(ROOT)]
    if os.environ.get("PYTHONPATH"):
        path.append(os.environ["PYTHONPATH"])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path), "PYTHONUNBUFFERED": "1", **extra}
    if home is not None:
        env["HOME"] = str(home)
    return env
