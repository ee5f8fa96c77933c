"""The instructor: what a flight school does to a training craft, and what only a simulator knows (the truth).

term --sim's lessons, room view and demo need two things a real board cannot give: where the craft really is
(position, velocity, attitude, ground contact) and a way to set up a situation (a breeze, a failing battery, a
stuck motor, a cable or radio that drops out). Neither is the board's: they travel beside it, on the
instructor channel (a line of JSON each way over a local TCP socket; its vocabulary, ``INSTRUCTOR_*``, is in
term/core/protocol/), never on the board's link, so a lesson that cuts the link still sees the craft.

Sans-IO ``Instructor(board)``, on the board's clock (seconds, ``board.now / 1e6``):

- ``apply(cmd, now)``: one situation command (a dict: ``{"do": "wind", "n": -1.5, ...}``, the verbs and their
  arguments in ``INSTRUCTOR_SITUATIONS``); returns None or why it cannot be done (one line). ``reset`` puts the
  craft back on the pad (the room's origin, nose north) with a fresh battery, still air and every fault cleared,
  the board's attitude and height estimates started again level on the pad, only while it stands on the floor in
  SAFE;
- ``tick(now)``: the battery's drain (a failing cell), called at the truth rate;
- ``cable_open(now)``: whether the cable carries bytes now (the server drops both ways while it does not);
- ``truth(now)``: the truth sample (``INSTRUCTOR_TRUTH`` fields) as a dict; ``truth_line(now)`` as a JSON line.

``InstructorServer`` is the asyncio edge for ``fcb-sim serve --instructor tcp-server:HOST:PORT``: the channel is
the simulator's and its terminal's alone. It listens on loopback only (another address needs ``public=True``,
``--instructor-public``, and is warned about), makes a random token and gives it in its address
(``tcp-client:HOST:PORT#TOKEN``, printed for term on a pipe); a client's first line must carry it
(``{"kind": "auth", "token": ...}``) within ``AUTH_TIMEOUT_S``, else it gets an error line and is dropped. One client
at a time: a second is refused while the first is there. A flood holds no harm for the flight: connections pass the
door of hosts/listeners.py (at most ``MAX_PENDING`` without the token, each dropped after its time, never a
descriptor past what serve's select() watches); an address that gave a wrong token waits a delay that doubles with
each wrong one before its next is looked at (``LoginThrottle``), and refusals are logged one line per interval. A
connection closed before it sent a byte guessed nothing and costs its address no delay: term's own client shares
127.0.0.1 with every port scan and idle flood on this machine. Then a hello line, and a truth line every
``1 / INSTRUCTOR_TRUTH_HZ`` s; each command line is applied and a refusal (a malformed line included: bad JSON,
2000 nested brackets, a 400-digit number) answered with one error line, never a traceback. A radio cut disconnects
the BLE central and stops advertising for a while. Cable and radio cuts add up to at most ``MAX_OUTAGE_S`` per
attempt (until a reset).
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import ipaddress
import json
import logging
import secrets
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from fcb_sim.errors import UsageError, parse_tcp_server
from fcb_sim.hosts.listeners import Door, GuardedServer, LoginThrottle
from fcb_sim.world import constants as P
from term.core.protocol import (
    INSTRUCTOR_AUTH,
    INSTRUCTOR_MAX_CUT_S,
    INSTRUCTOR_MAX_OUTAGE_S,
    INSTRUCTOR_TOKEN_SEP,
    INSTRUCTOR_TRUTH,
    INSTRUCTOR_TRUTH_HZ,
    INSTRUCTOR_VERSION,
    Mode,
    situation_problem,
)
from term.core.protocol.numbers import check_number, finite, shown_text

if TYPE_CHECKING:
    from fcb_sim.board.board import Board

log = logging.getLogger(__name__)

SOC_FLOOR = 0.03  # a failing cell's drain stops here (the pack is not drawn to nothing)
MAX_CUT_S = INSTRUCTOR_MAX_CUT_S  # the longest a cable or radio may be cut for
MAX_OUTAGE_S = INSTRUCTOR_MAX_OUTAGE_S  # cuts added up per attempt: 60 chained 60 s cuts must not make an hour
MAX_CUTS = 20  # cuts in one cable command
# Decimals a truth field is sent with (the rest: 4): angles finer, the pack and the touch-down coarser, the wind 2.
TRUTH_DECIMALS = {"phi": 5, "theta": 5, "psi": 5, "volts": 3, "touchdown": 3, "wind_n": 2, "wind_e": 2, "gust": 2}


class Instructor:
    """Situations for a board in its world, and the truth about it (module docstring)."""

    def __init__(self, board: Board, on_radio_cut: Callable[[float], str | None] | None = None) -> None:
        """``on_radio_cut(seconds)`` cuts the radio (the server's bumble radio; a test's own), returning why it
        cannot (None: done)."""
        self.board = board
        self.on_radio_cut = on_radio_cut
        self.drain = 0.0  # state of charge per second drawn by a failing cell, beside the motors' own
        self.cuts: list[tuple[float, float]] = []  # (from, until) board seconds: the cable carries nothing
        self._last_tick: float | None = None
        self.applied = 0  # commands applied (for tests and the server's log)
        self.outage = 0.0  # s of cable and radio cuts asked for since the last reset (this attempt's)
        self._touches, self._touch_seen = 0, -1.0  # ceiling and wall touches counted, the newest one's time
        self._touched, self._touch_speed = "", 0.0  # the newest one's surface and speed

    # --- situations ---------------------------------------------------------------------------------------

    def apply(self, cmd: dict[str, Any], now: float) -> str | None:
        """Carry out one command; None, or why not (one line)."""
        why = situation_problem(cmd)  # the protocol's check, the one term runs on a lesson file at load
        if why is not None:
            return why
        verb = cmd["do"]
        try:
            why = getattr(self, f"_do_{verb}")(cmd, now)
        except (TypeError, ValueError, ArithmeticError) as exc:
            return " ".join(f"{verb}: {exc}".split())[:300]
        if why is None:
            self.applied += 1
        return why

    def _do_reset(self, cmd: dict[str, Any], now: float) -> str | None:
        b, w = self.board, self.board.world
        if b.mode != Mode.SAFE or not w.on_ground:
            return "reset: only with the craft on the floor in SAFE (land, then 0)"
        soc = _number(cmd, "soc", P.BATTERY_SOC_START, 0.0, 1.0)
        # Carried back to the pad, nose north: the position and heading do not reach any sensor but the DMP's
        # yaw (a jump in SAFE, as when the craft is picked up and turned).
        w.n = w.e = 0.0
        w.vn = w.ve = w.vd = 0.0
        w.p = w.q = w.r = 0.0
        w.qw, w.qx, w.qy, w.qz = 1.0, 0.0, 0.0, 0.0
        w.gust = [0.0, 0.0, 0.0]
        # The board's estimators start again from the craft as it now stands (level, at rest): the flight core keeps
        # the angles of its last flight-mode step in SAFE, and its filters would spend a long while unlearning a
        # crash's tilt. Its height estimate starts again from the pad too.
        core = getattr(b, "core", None)  # (the C board keeps its own)
        if core is not None:
            core.filter.reset()
            core.phi = core.theta = 0.0
            if core.calibrated:
                core.height_est.reset(core.calibration.pressure)
                core.height = core.vz = 0.0
        w.set_wind(0.0, 0.0, 0.0, gust_std=0.0)
        for i in range(1, 5):
            w.stick_motor(i, None)
        w.pushes = []
        self._battery(soc)
        self.drain = 0.0
        self.cuts = []
        self.outage = 0.0  # a new attempt
        b.modes.battery_low_latched = False  # a fresh pack
        if getattr(b.modes, "crashed", False):
            b.modes.crashed = False  # a fresh craft: the instructor saw the crash
        return None

    def _do_wind(self, cmd: dict[str, Any], now: float) -> str | None:
        n = _number(cmd, "n", 0.0, -15.0, 15.0)
        e = _number(cmd, "e", 0.0, -15.0, 15.0)
        gust = _number(cmd, "gust", 0.0, 0.0, 5.0)
        self.board.world.set_wind(n, e, 0.0, gust_std=gust)
        return None

    def _do_battery(self, cmd: dict[str, Any], now: float) -> str | None:
        if "soc" in cmd:
            self._battery(_number(cmd, "soc", 0.9, 0.0, 1.0))
        self.drain = _number(cmd, "drain", 0.0, 0.0, 1.0)
        self._last_tick = now
        return None

    def _do_motor(self, cmd: dict[str, Any], now: float) -> str | None:
        index = int(_number(cmd, "motor", 0, 1, 4))
        level = int(_number(cmd, "level", -1, -1, P.AE_MAX))
        self.board.world.stick_motor(index, None if level < 0 else level)
        return None

    def _do_cable(self, cmd: dict[str, Any], now: float) -> str | None:
        cuts = cmd.get("cuts", [])
        if not isinstance(cuts, list):
            raise ValueError("cuts is a list of [after s, for s]")
        if len(cuts) > MAX_CUTS:
            raise ValueError(f"at most {MAX_CUTS} cuts at a time, got {len(cuts)}")
        out = []
        for c in cuts:
            if (not isinstance(c, list | tuple) or len(c) != 2 or not all(_finite(x) for x in c)
                    or not (0.0 <= c[0] <= 3600.0 and 0.0 < c[1] <= MAX_CUT_S)):
                raise ValueError(f"each cut is [after s (0..3600), for s (0..{MAX_CUT_S:g})], got {shown_text(c)}")
            out.append((now + float(c[0]), now + float(c[0]) + float(c[1])))
        why = self._outage(sum(b - a for a, b in out), "cable")
        if why is not None:
            return why
        self.cuts = sorted(out)  # an empty list: the cable is fine from now on
        return None

    def _outage(self, seconds: float, verb: str) -> str | None:
        """Count ``seconds`` of cut against this attempt's bound; why not, if it would pass it."""
        if self.outage + seconds > MAX_OUTAGE_S + 1e-9:
            return (f"{verb}: {seconds:g} s more would make {self.outage + seconds:g} s of outage in this attempt "
                    f"(at most {MAX_OUTAGE_S:g} s until a reset)")
        self.outage += seconds
        return None

    def _do_radio(self, cmd: dict[str, Any], now: float) -> str | None:
        seconds = _number(cmd, "cut", 5.0, 0.1, MAX_CUT_S)
        if self.on_radio_cut is None:
            return "radio: this board has no radio (fcb-sim serve without --ble-hci)"
        why = self._outage(seconds, "radio")
        if why is not None:
            return why
        why = self.on_radio_cut(seconds)
        if why is not None:
            self.outage -= seconds  # not cut after all
        return why

    def _battery(self, soc: float) -> None:
        w = self.board.world
        w.soc = soc
        w.volts = max(0.0, P.ocv(soc) - w.current * P.R_INTERNAL)

    # --- time ---------------------------------------------------------------------------------------------

    def tick(self, now: float) -> None:
        """The failing cell's drain since the last tick; cuts that are over are forgotten."""
        last, self._last_tick = self._last_tick, now
        if self.drain > 0.0 and last is not None and now > last:
            w = self.board.world
            if w.soc > SOC_FLOOR:
                self._battery(max(SOC_FLOOR, w.soc - self.drain * (now - last)))
        if self.cuts and self.cuts[0][1] <= now:
            self.cuts = [c for c in self.cuts if c[1] > now]

    def cable_open(self, now: float) -> bool:
        return not any(a <= now < b for a, b in self.cuts)

    # --- the truth ----------------------------------------------------------------------------------------

    def truth(self, now: float) -> dict[str, Any]:
        """What only the simulator knows, in SI units: the fields of the protocol's INSTRUCTOR_TRUTH, in its order
        (the world's true state by the same names, and the few the instructor keeps itself)."""
        w = self.board.world
        tr = w.truth
        own = {"t": now, "landings": len(w.landings), "touchdown": w.landings[-1][1] if w.landings else 0.0,
               "crashes": len(w.crashes), "cable": self.cable_open(now),
               "wind_n": w.wind_mean[0], "wind_e": w.wind_mean[1], "gust": w.gust_std, "contact": w.contact}
        for c in w.contacts[-8:]:  # (the newest few: a truth comes every 50 ms, a contact at most every 0.5 s)
            if c.where != "ground" and c.t > self._touch_seen:
                self._touches += 1
                self._touch_seen, self._touched, self._touch_speed = c.t, c.where, c.speed
        own |= {"touches": self._touches, "touched": self._touched, "touch_speed": self._touch_speed}
        out: dict[str, Any] = {"kind": "truth"}
        for name in INSTRUCTOR_TRUTH:
            v = own[name] if name in own else getattr(tr, name)
            out[name] = round(v, TRUTH_DECIMALS.get(name, 4)) if isinstance(v, float) else v
        return out

    def truth_line(self, now: float) -> bytes:
        return (json.dumps(self.truth(now), separators=(",", ":")) + "\n").encode()


def _finite(x: object) -> bool:
    return finite(x)  # an int of any size is finite and never converted before its range is checked


def _number(cmd: dict[str, Any], name: str, default: float, lo: float, hi: float) -> float:
    """The protocol's one strict number check (term/core/protocol/numbers.py): finite, in range, one line."""
    return float(check_number(cmd.get(name, default), name, lo, hi))


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a name: it may resolve to anything


# --- the asyncio edge -------------------------------------------------------------------------------------------

WRITE_BACKLOG = 65536  # bytes queued for a client that does not read: truth lines are skipped beyond this
MAX_LINE = 4096  # a command line longer than this is refused (and the client dropped)
AUTH_TIMEOUT_S = 5.0  # a client that has not given the token by then is dropped
MAX_PENDING = 8  # connections at once that have not given the token; the next is refused at once


class InstructorServer:
    """The instructor channel on a local TCP port (module docstring). ``radio``: the board's ``BoardRadio``."""

    def __init__(self, instructor: Instructor, *, radio: Any = None, token: str | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.instructor = instructor
        # the door (hosts/listeners.py): its own clock drops a silent client a second after our AUTH_TIMEOUT_S would
        self.door = Door("instructor", log, max_pending=MAX_PENDING, pending_timeout_s=AUTH_TIMEOUT_S + 1.0,
                         clock=clock)
        self.throttle = LoginThrottle(clock=clock)
        self.radio = radio
        if radio is not None:
            instructor.on_radio_cut = self._cut_radio
        self.token = token or secrets.token_hex(16)
        self._server: GuardedServer | None = None
        self._writer: asyncio.StreamWriter | None = None  # the one client, once it gave the token
        self._clients: set[asyncio.Task[Any]] = set()
        self._task: asyncio.Task[None] | None = None
        self._radio_task: asyncio.Task[None] | None = None
        self.address = ""
        self.skipped = 0  # truth lines not sent to a slow client

    @property
    def now(self) -> float:
        return self.instructor.board.now / 1e6

    async def start(self, spec: str, *, public: bool = False) -> str:
        """Listen on ``spec``; returns the address a client connects to (``tcp-client:HOST:PORT#TOKEN``). An
        address beyond this machine needs ``public`` (``--instructor-public``) and is warned about on stderr."""
        host, port = parse_tcp_server(spec, "--instructor")
        if not is_loopback(host):
            if not public:
                raise UsageError(f"--instructor {spec}: {host} is reachable from other machines; the channel cuts "
                                 "cables and stops motors, so it listens on loopback (127.0.0.1) unless you add "
                                 "--instructor-public")
            print(f"fcb-sim: warning: the instructor channel listens on {host} (--instructor-public): every "
                  "machine that can reach it and knows the token can set situations", file=sys.stderr, flush=True)
        try:
            loop = asyncio.get_running_loop()

            def stream() -> asyncio.Protocol:  # what asyncio.start_server makes, behind the door
                return asyncio.StreamReaderProtocol(asyncio.StreamReader(limit=MAX_LINE, loop=loop), self._client,
                                                    loop=loop)

            self._server = await GuardedServer.start(host, port, stream, self.door, refusal=_refusal_line)
        except OSError as exc:
            raise UsageError(f"--instructor {spec}: {exc.strerror or exc}") from None
        sock = self._server.sockets[0].getsockname()
        self.address = f"tcp-client:{sock[0]}:{sock[1]}{INSTRUCTOR_TOKEN_SEP}{self.token}"
        self._task = asyncio.create_task(self._ticker(), name="instructor truth")
        return self.address

    async def _ticker(self) -> None:
        period = 1.0 / INSTRUCTOR_TRUTH_HZ
        while True:
            await asyncio.sleep(period)
            now = self.now
            self.instructor.tick(now)
            w = self._writer
            if w is None or w.is_closing():
                continue
            if w.transport.get_write_buffer_size() > WRITE_BACKLOG:
                self.skipped += 1
                continue
            w.write(self.instructor.truth_line(now))

    @property
    def refused(self) -> int:
        """Clients turned away: no token, a wrong one, a second client, too many waiting, a throttled address."""
        return self.door.refused

    def _busy(self) -> bool:
        return self._writer is not None and not self._writer.is_closing()

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._clients.add(task)
        try:
            await self._session(reader, writer)
        except (ConnectionError, OSError):
            pass
        except asyncio.CancelledError:
            pass  # shutting down: the handler ends quietly (a cancelled handler is a traceback in asyncio)
        finally:
            if self._writer is writer:
                self._writer = None
            with contextlib.suppress(Exception):
                writer.close()
            if task is not None:
                self._clients.discard(task)

    async def _session(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self._busy():
            self._refuse(writer, "another instructor is connected (one at a time)")
            return
        peer = writer.get_extra_info("peername")
        address = str(peer[0]) if isinstance(peer, tuple) and peer else "?"
        wait = self.throttle.wait(address)
        if wait > 0:  # this address gave a wrong token lately: its next one waits (hosts/listeners.py)
            self._refuse(writer, f"too many wrong tokens from {address}: try again in {wait:.1f} s",
                         summary="a throttled address")
            return
        why = await self._auth(reader)
        if why == WENT_WITHOUT_A_WORD:  # guessed nothing (a port scan, an idle flood): no failure, no answer
            return
        if why is not None and why != TIMED_OUT_WHY:
            self.throttle.failed(address)
        elif why is None:
            self.throttle.succeeded(address)
            if self._busy():
                why = "another instructor is connected (one at a time)"
        if why is not None:
            self._refuse(writer, why)
            return
        self.door.authenticated(writer.transport)
        self._writer = writer
        writer.write((json.dumps({"kind": "hello", "version": INSTRUCTOR_VERSION,
                                  "hz": INSTRUCTOR_TRUTH_HZ}) + "\n").encode())
        while True:
            try:
                line = await reader.readline()
            except (ValueError, asyncio.LimitOverrunError):
                self._answer(writer, None, f"a command line longer than {MAX_LINE} bytes")
                break
            if not line:
                break
            self._answer(writer, *self._command(line))

    async def _auth(self, reader: asyncio.StreamReader) -> str | None:
        """None if the first line carries the token in time; else why not."""
        try:
            line = await asyncio.wait_for(reader.readline(), AUTH_TIMEOUT_S)
        except TimeoutError:
            return TIMED_OUT_WHY
        except (ValueError, asyncio.LimitOverrunError):
            return "the first line must give the token"
        if not line:
            return WENT_WITHOUT_A_WORD
        msg = _json_object(line)
        token = msg.get("token") if isinstance(msg, dict) and msg.get("kind") == INSTRUCTOR_AUTH else None
        if not isinstance(token, str) or not hmac.compare_digest(token.encode(), self.token.encode()):
            return "the first line must give this simulator's token ({\"kind\": \"auth\", \"token\": ...})"
        return None

    def _refuse(self, writer: asyncio.StreamWriter, why: str, summary: str | None = None) -> None:
        """Answer ``why``; counted and logged summarised under ``summary`` (default ``why``) by the door."""
        self.door.refuse(summary or why)
        self._answer(writer, None, why)

    def _command(self, line: bytes) -> tuple[str | None, str | None]:
        cmd = _json_object(line)
        if isinstance(cmd, str):
            return None, cmd
        verb = cmd.get("do")
        shown = verb if isinstance(verb, str) and len(verb) <= 20 else None
        try:
            why = self.instructor.apply(cmd, self.now)
        except Exception as exc:  # the channel never ends in a traceback: the line is answered
            log.warning("instructor: %s failed: %s", shown, exc)
            why = f"could not be carried out ({type(exc).__name__})"
        if why is None:
            log.info("instructor: %s", shown_text(cmd))
        return shown, why

    def _answer(self, writer: asyncio.StreamWriter, verb: str | None, why: str | None) -> None:
        if why is not None and not writer.is_closing():
            writer.write((json.dumps({"kind": "error", "do": verb, "why": why}) + "\n").encode())

    def _cut_radio(self, seconds: float) -> str | None:
        radio = self.radio
        if radio is None or radio.device is None:
            return "radio: not on the air"
        if self._radio_task is not None and not self._radio_task.done():
            self._radio_task.cancel()
        self._radio_task = asyncio.get_running_loop().create_task(self._radio_silence(seconds), name="radio cut")
        return None

    async def _radio_silence(self, seconds: float) -> None:
        """Out of range for ``seconds``: the connection drops (the board sees it lost) and nobody can connect."""
        radio = self.radio
        with contextlib.suppress(Exception):
            await radio.device.stop_advertising()
        conn = radio.connection
        if conn is not None:
            with contextlib.suppress(Exception):
                await conn.disconnect()
        try:
            await asyncio.sleep(seconds)
        finally:
            with contextlib.suppress(Exception):
                await radio.advertise()

    async def close(self) -> None:
        for task in (self._task, self._radio_task, *self._clients):
            if task is not None:
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await task
        if self._writer is not None:
            with contextlib.suppress(Exception):
                self._writer.close()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await self._server.wait_closed()
        self.door.close()


TIMED_OUT_WHY = f"no token within {AUTH_TIMEOUT_S:g} s"
WENT_WITHOUT_A_WORD = "closed before it sent a byte"


def _refusal_line(why: str) -> bytes:
    """The error line a client refused at the door gets (too many waiting for the token)."""
    return (json.dumps({"kind": "error", "do": None, "why": why}) + "\n").encode()


def _json_object(line: bytes) -> dict[str, Any] | str:
    """A command line as a JSON object, or why it is not one (one line). 2000 nested brackets are a refusal, not a
    RecursionError; a 400-digit number parses (and is refused by its range later)."""
    try:
        cmd = json.loads(line)
    except (ValueError, UnicodeDecodeError):
        return "not a JSON line"
    except RecursionError:
        return "not a usable JSON line: it nests too deeply"
    if not isinstance(cmd, dict):
        return "a command is a JSON object with \"do\""
    return cmd
