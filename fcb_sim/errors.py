"""Exit codes and the usage error: how `fcb-sim` ends when the user can fix the cause.

Imported by any part that can refuse a user's input (the board's profile bench, the scenarios, the replay, the
server, the radio); imports nothing of ours, so no core module needs the CLI. The CLI prints a ``UsageError`` as
one line (``fcb-sim: <message>``) and exits with ``EXIT_USAGE``.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_USAGE = 2  # a problem the user can fix: a bad option, a missing file, a port that will not open
EXIT_INTERRUPTED = 130  # Ctrl+C (128 + SIGINT)


class UsageError(Exception):
    """A problem the user can fix; its message is printed as one line."""
