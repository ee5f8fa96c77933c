"""The board's own debug lines: ``qb_log(parts, level, fmt, *args)``, the Python twin of the C board's ``qb_log``
(firmware/board/qb_console.c). A line goes to the terminal as Text packets (term.core.protocol.text_packets: 13
bytes each, a long line in several), so a team prints without breaking the link, over the cable and over BLE.

A line is cut at QB_LOG_MAX bytes (as the C board's buffer), and a line that finds the transmit side full (what
the log download also waits for: fcb_sim/board/transmit.py) is dropped whole and counted, never half sent and never
in the way of a heartbeat or an answer.
"""

from __future__ import annotations

from typing import Any

from term.core.protocol import LEVEL_INFO, text_packets

QB_LOG_MAX = 64  # bytes of one line (the C board's buffer)


class BoardConsole:
    """Counts what ``qb_log`` sent and dropped, per board."""

    def __init__(self) -> None:
        self.sent = 0
        self.dropped = 0


def qb_log(parts: Any, level: int, fmt: str, *args: object) -> bool:
    """Send ``fmt % args`` (printf style) as a debug line at ``level`` (1 debug .. 5 fatal); False if dropped."""
    console = parts.console
    try:
        line = fmt % args if args else fmt
    except (TypeError, ValueError):
        line = fmt  # a bad format is the caller's bug: the format itself still says where
    data = line.encode("utf-8", "replace")[:QB_LOG_MAX]
    if not parts.tx.bulk_room(parts.now):
        console.dropped += 1
        return False
    for pkt in text_packets(data, level or LEVEL_INFO):
        parts.tx.send(pkt, parts.now)
    console.sent += 1
    return True
