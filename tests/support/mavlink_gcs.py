"""A ground station made of pymavlink for the MAVLink tests and bench: it listens (``udpin``, as QGroundControl
does on 14550) on a free loopback port, a thread of its own reads every message into ``got`` with its arrival time
(``time.monotonic``), and the test asks and waits without blocking the app's loop (``seen``, ``last``)."""

from __future__ import annotations

import threading
import time
from typing import Any


class Gcs:
    def __init__(self, kind: str = "udpin") -> None:
        from pymavlink import mavutil

        self.conn = mavutil.mavlink_connection(f"{kind}:127.0.0.1:0", source_system=255, source_component=190,
                                               dialect="common")
        self.port = self.conn.port.getsockname()[1]
        self.mav = self.conn.mav
        self.got: list[tuple[float, Any]] = []
        self._lock = threading.Lock()
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="test gcs", daemon=True)
        self._thread.start()

    @property
    def address(self) -> str:
        return f"udp:127.0.0.1:{self.port}"

    def _run(self) -> None:
        while not self._stop:
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.05)
            except OSError:
                continue
            if msg is not None and msg.get_type() != "BAD_DATA":
                with self._lock:
                    self.got.append((time.monotonic(), msg))

    def seen(self, kind: str, cond: Any = None) -> list[Any]:
        with self._lock:
            items = list(self.got)
        return [m for _, m in items if m.get_type() == kind and (cond is None or cond(m))]

    def timed(self, kind: str) -> list[tuple[float, Any]]:
        with self._lock:
            return [(t, m) for t, m in self.got if m.get_type() == kind]

    def last(self, kind: str) -> Any:
        found = self.seen(kind)
        return found[-1] if found else None

    def texts(self) -> list[str]:
        """The STATUSTEXT lines, chunks (MAVLink 2: same id, chunk_seq in order) joined."""
        out: list[str] = []
        parts: dict[int, list[str]] = {}
        for m in self.seen("STATUSTEXT"):
            if not getattr(m, "id", 0):
                out.append(m.text)
            else:
                parts.setdefault(m.id, []).append(m.text)
        return out + ["".join(p) for p in parts.values()]

    def heartbeat(self) -> None:
        m = self.mav
        m.heartbeat_send(6, 8, 0, 0, 0)  # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID

    def close(self) -> None:
        self._stop = True
        self._thread.join(1.0)
        self.conn.close()
