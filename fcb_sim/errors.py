"""Exit codes and the usage error: how `fcb-sim` ends when the user can fix the cause; and the one reader of a
listening address the user types (``parse_tcp_server``: ``--instructor``, ``--ble-hci``).

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


def parse_tcp_server(spec: str, option: str, example: str = "tcp-server:127.0.0.1:0") -> tuple[str, int]:
    """``tcp-server:HOST:PORT`` (PORT 0: any free port) -> (host, port); a UsageError naming ``option`` otherwise."""
    kind, _, rest = spec.partition(":")
    host, _, port = rest.rpartition(":")
    if kind != "tcp-server" or not host or not port.isdigit() or int(port) > 65535:
        raise UsageError(f"{option} {spec!r}: expected tcp-server:HOST:PORT (PORT 0 to 65535, 0 for any free port), "
                         f"e.g. {example}")
    return host, int(port)
