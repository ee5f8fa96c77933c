"""Ending a command-line process without the interpreter's teardown.

After ``term``'s screens close, Python's own exit frees every object of Textual, bumble and the session one by one
(modules cleared, the garbage collected): 0.3-0.7 s of CPU with nothing left to do, most of what quitting cost
(issue 22). ``exit_now`` runs what an orderly exit promises (the atexit handlers: logging's flush, weakref
finalizers) and flushes stdout and stderr, then ends the process at once. While another non-daemon thread runs it
exits as usual instead, since the normal exit waits for that thread.

Only the entry points call it (``term``, ``python -m term``, the simulated board's child): never a library function,
and never a test's process.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import sys
import threading
from typing import NoReturn


def exit_now(code: int | None) -> NoReturn:
    """End the process with ``code`` (None is 0) after the atexit handlers and a flush of stdout and stderr."""
    code = int(code or 0)
    main = threading.main_thread()
    if any(t is not main and not t.daemon and t.is_alive() for t in threading.enumerate()):
        sys.exit(code)  # the normal exit joins it
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # (a closed pipe: nothing more can be said)
            stream.flush()
    os._exit(code)
