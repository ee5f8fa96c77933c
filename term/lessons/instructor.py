"""The terminal's end of the simulator's instructor channel (term --sim only): the truth in, situations out.

The simulated board (``fcb-sim serve --instructor``, fcb_sim/hosts/instructor.py) knows where the craft really is and
can set up a situation (wind, a failing battery, a stuck motor, a cable or radio cut); a real board can do
neither, so this channel runs beside the board's link, never on it (a lesson that cuts the link still sees the
craft). One JSON object per line each way; the vocabulary (``INSTRUCTOR_*``) is in term/core/protocol/.

- ``Truth``: one truth sample in SI units, with the derived figures the lessons and the room view use
  (``tilt_deg``, ``heading_deg``, ``vz`` up, horizontal ``speed``). ``parse_line(bytes)`` gives a ``Truth``, a
  ``Refused`` (the simulator could not carry out a situation: why), a ``Hello``, or None for anything else (a
  bad line is skipped, never raised: the channel is a view, not a control path);
- ``InstructorClient``: the asyncio TCP client (``tcp-client:HOST:PORT#TOKEN``, the address the child prints; the
  token is the first line it sends, and the simulator refuses a client without it or a second one). It keeps
  the latest truth (``truth``), calls ``on_truth`` for each sample and ``on_refused`` for each refusal, and sends
  situations (``send``). Lost, it says why once (``lost``) and stays down: the child board is gone too.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields
from typing import Any

from term.core.protocol import (
    INSTRUCTOR_AUTH,
    INSTRUCTOR_TOKEN_SEP,
    INSTRUCTOR_TRUTH,
    INSTRUCTOR_VERSION,
    situation_problem,
)

MAX_LINE = 65536


@dataclass(frozen=True, slots=True)
class Truth:
    """Where the craft really is (INSTRUCTOR_TRUTH: earth NED from the pad, body FRD, SI units)."""

    t: float
    n: float
    e: float
    h: float
    vn: float
    ve: float
    vd: float
    phi: float
    theta: float
    psi: float
    p: float
    q: float
    r: float
    on_ground: bool
    volts: float
    soc: float
    landings: int
    touchdown: float
    crashes: int
    cable: bool
    wind_n: float = 0.0
    wind_e: float = 0.0
    gust: float = 0.0
    contact: str = ""  # what it touches now: "ground", "ceiling", "wall" or ""
    touches: int = 0  # touches of the ceiling or a wall so far (a short bounce between two truths too)
    touched: str = ""  # the last one's surface: "ceiling", "wall" or ""
    touch_speed: float = 0.0  # its speed into it (m/s)

    @property
    def vz(self) -> float:
        """Vertical speed, up positive (m/s)."""
        return -self.vd

    @property
    def speed(self) -> float:
        """Horizontal speed (m/s)."""
        return math.hypot(self.vn, self.ve)

    @property
    def tilt_deg(self) -> float:
        """Angle between the body's z axis and the vertical (deg)."""
        c = max(-1.0, min(1.0, math.cos(self.phi) * math.cos(self.theta)))
        return math.degrees(math.acos(c))

    @property
    def heading_deg(self) -> float:
        """0..360, 0 north, 90 east."""
        return math.degrees(self.psi) % 360.0

    @property
    def yaw_rate_dps(self) -> float:
        return math.degrees(self.r)


_FIELDS = tuple(f.name for f in fields(Truth))
_REQUIRED = frozenset(f.name for f in fields(Truth) if f.default is MISSING)
assert set(_FIELDS) == set(INSTRUCTOR_TRUTH), "Truth and INSTRUCTOR_TRUTH name the same fields"


@dataclass(frozen=True, slots=True)
class Refused:
    """The simulator could not carry out a situation."""

    verb: str
    why: str


@dataclass(frozen=True, slots=True)
class Hello:
    version: int
    hz: float


def truth_from(obj: dict[str, Any]) -> Truth | None:
    """A Truth from a decoded truth object, or None if a field is missing or not a finite number."""
    values: dict[str, Any] = {}
    for name in _FIELDS:
        if name not in obj:
            if name in _REQUIRED:
                return None
            continue
        v = obj[name]
        if name in ("on_ground", "cable"):
            if not isinstance(v, bool):
                return None
        elif name == "contact":
            if v not in ("", "ground", "ceiling", "wall"):
                return None
        elif name == "touched":
            if v not in ("", "ceiling", "wall"):
                return None
        elif name in ("landings", "crashes", "touches"):
            if not isinstance(v, int) or isinstance(v, bool):
                return None
        elif not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
            return None
        values[name] = v
    return Truth(**values)


def parse_line(line: bytes) -> Truth | Refused | Hello | None:
    try:
        obj = json.loads(line)
    except (ValueError, UnicodeDecodeError, RecursionError):  # skipped, like any bad line
        return None
    if not isinstance(obj, dict):
        return None
    kind = obj.get("kind")
    if kind == "truth":
        return truth_from(obj)
    if kind == "error":
        return Refused(str(obj.get("do")), str(obj.get("why", "")))
    if kind == "hello" and isinstance(obj.get("version"), int):
        hz = obj.get("hz")
        return Hello(obj["version"], float(hz) if isinstance(hz, int | float) else 0.0)
    return None


def check_situation(cmd: dict[str, Any]) -> str | None:
    """Why ``cmd`` is not a situation the simulator accepts (its verb, its argument names, each value's range: the
    protocol's ``situation_problem``, which the simulator runs too), or None. A lesson file is checked so at load."""
    return situation_problem(cmd)


def parse_address(address: str) -> tuple[str, int, str]:
    """``tcp-client:HOST:PORT#TOKEN`` (what the simulator prints) -> (host, port, token)."""
    where, _, token = address.partition(INSTRUCTOR_TOKEN_SEP)
    kind, _, rest = where.partition(":")
    host, _, port = rest.rpartition(":")
    if kind != "tcp-client" or not host or not port.isascii() or not port.isdigit() or int(port) > 65535:
        raise ValueError(f"instructor address {where!r}: expected tcp-client:HOST:PORT#TOKEN")
    return host, int(port), token


class InstructorClient:
    """The instructor channel from the terminal (module docstring)."""

    def __init__(self, address: str, *, on_truth: Callable[[Truth], None] | None = None,
                 on_refused: Callable[[Refused], None] | None = None,
                 on_lost: Callable[[str], None] | None = None) -> None:
        self.address = address
        self.host, self.port, self.token = parse_address(address)
        self.on_truth = on_truth
        self.on_refused = on_refused
        self.on_lost = on_lost
        self.truth: Truth | None = None
        self.samples = 0
        self.lost = ""  # why the channel is down ("" while it is up or not yet opened)
        self.version: int | None = None
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._task: asyncio.Task[None] | None = None

    @property
    def up(self) -> bool:
        return self._writer is not None and not self.lost

    async def open(self, timeout: float = 5.0) -> None:
        """Connect; OSError (or TimeoutError) if the simulator does not answer."""
        self._reader, self._writer = await asyncio.wait_for(
            asyncio.open_connection(self.host, self.port, limit=MAX_LINE), timeout)
        # the simulator's token first: the channel is its and ours alone (term/core/protocol/instructor.py)
        self._writer.write((json.dumps({"kind": INSTRUCTOR_AUTH, "token": self.token}) + "\n").encode())
        self._task = asyncio.get_running_loop().create_task(self._read(), name="instructor channel")

    async def _read(self) -> None:
        assert self._reader is not None
        why = "the simulator closed the instructor channel"
        try:
            while True:
                line = await self._reader.readline()
                if not line:
                    break
                self.feed(line)
        except (ConnectionError, OSError, ValueError, asyncio.LimitOverrunError) as exc:
            why = f"instructor channel: {exc}"
        self._gone(why)

    def feed(self, line: bytes) -> None:
        """One line from the simulator (the read loop's; a test may feed lines itself)."""
        msg = parse_line(line)
        if isinstance(msg, Truth):
            self.truth = msg
            self.samples += 1
            if self.on_truth is not None:
                self.on_truth(msg)
        elif isinstance(msg, Refused):
            if self.version is None:  # before the hello: the simulator turned us away (token, a second client)
                self._gone(f"the simulator refused the instructor channel: {msg.why}")
            elif self.on_refused is not None:
                self.on_refused(msg)
        elif isinstance(msg, Hello):
            self.version = msg.version
            if msg.version != INSTRUCTOR_VERSION:
                self._gone(f"the simulator's instructor channel is v{msg.version}, this terminal's "
                           f"v{INSTRUCTOR_VERSION}")

    def _gone(self, why: str) -> None:
        if self.lost:
            return
        self.lost = why
        if self.on_lost is not None:
            self.on_lost(why)

    def send(self, cmd: dict[str, Any]) -> str | None:
        """Send one situation; None, or why it was not sent."""
        bad = check_situation(cmd)
        if bad is not None:
            return bad
        if self._writer is None or self.lost or self._writer.is_closing():
            return f"no instructor channel ({self.lost or 'not connected'})"
        self._writer.write((json.dumps(cmd, separators=(",", ":")) + "\n").encode())
        return None

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
            self._task = None
        if self._writer is not None:
            with contextlib.suppress(Exception):
                self._writer.close()
                await self._writer.wait_closed()
            self._writer = None
