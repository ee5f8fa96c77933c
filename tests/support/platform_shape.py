"""Another platform's shape for a child process on Linux (tests/platform): the environment that puts
tests/platform/shapes/NAME/sitecustomize.py first on the child's PYTHONPATH, with this checkout after it, and a
home, data and log folders of its own (a shaped platformdirs looks under HOME, not XDG)."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SHAPES = ROOT / "tests" / "platform" / "shapes"


def shaped_env(shape: str, home: Path, **extra: str) -> dict[str, str]:
    """os.environ for a child shaped as ``shape`` ("darwin" or "win32"), its home in ``home``."""
    path = [str(SHAPES / shape), str(ROOT)]
    if os.environ.get("PYTHONPATH"):
        path.append(os.environ["PYTHONPATH"])
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path), "HOME": str(home), "PYTHONUNBUFFERED": "1",
            **extra}
