"""Exit codes and the usage error: how `term` ends when the user can fix the cause.

Imported by every part that can end the program (the CLI, the app, the station); imports nothing of ours, so no
core module needs the CLI. A ``UsageError`` is printed as one line (``term: <message>``) and ends with
``EXIT_USAGE``; a board that speaks another protocol version ends with ``EXIT_VERSION``.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_USAGE = 2  # a problem the user can fix: a bad option, a missing port, a board that will not start
EXIT_VERSION = 3  # a board that speaks another protocol version
EXIT_INTERRUPTED = 130  # Ctrl+C before the screen took over (128 + SIGINT)


class UsageError(Exception):
    """A problem the user can fix; printed as one line."""
