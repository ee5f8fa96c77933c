"""Shared fixtures: a real pseudo-terminal pair, and a small scripted board peer speaking term.core.protocol.

The scripted board is not the simulated board (fcb_sim.board.board): it is the least that exercises the link: it
sends heartbeats, answers Hello with Hello and every Command with an Ack (or a chosen NAK), executing a retried
command only once (it remembers only its last command, as the firmware does), and it can stream numbered
filler frames so loss can be counted.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import tempfile
import termios
import tty
from collections.abc import Callable, Iterator

import pytest

from term.core.protocol import (
    PROTOCOL_VERSION,
    Ack,
    Command,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Hello,
    Joystick,
    Nak,
    Status,
)


def pytest_configure(config: pytest.Config) -> None:
    _share_the_firmware_build(config)
    _one_gc_collection(config)


def _share_the_firmware_build(config: pytest.Config) -> None:
    """The C side's test build (tests/support/firmware.py) in one folder for the run: made here by the controller
    before it starts its workers (they inherit the environment), removed by it at the end. A worker finds the
    folder made: 4.5 s of CPU each that a build of its own cost."""
    from tests.support.firmware import SHARED_BUILD_ENV

    if hasattr(config, "workerinput") or os.environ.get(SHARED_BUILD_ENV):
        return
    folder = tempfile.mkdtemp(prefix="qp-firmware-")
    os.environ[SHARED_BUILD_ENV] = folder

    def remove() -> None:
        shutil.rmtree(folder, ignore_errors=True)
        os.environ.pop(SHARED_BUILD_ENV, None)

    config.add_cleanup(remove)


def _one_gc_collection(config: pytest.Config) -> None:
    """One full collection at the end, not pytest's five (each walks a worker's whole heap of a run: about 1 s, so
    5 s of each worker's last seconds). An exception raised in a finaliser is still reported; one that only a
    second collection would reach is not. (A private key of pytest 8.4: where it is missing, pytest's default
    stands.)"""
    try:
        from _pytest.unraisableexception import gc_collect_iterations_key
    except ImportError:
        return
    config.stash[gc_collect_iterations_key] = 1


@pytest.hookimpl(tryfirst=True)
def pytest_collection(session: pytest.Session) -> None:
    """Each xdist worker imports the test modules from its own share on (tests/support/staggered_imports.py): a
    fresh clone's workers compile the bytecode once between them."""
    from tests.support.staggered_imports import import_this_workers_share_first

    import_this_workers_share_first(session.config)


@pytest.fixture(autouse=True, scope="session")
def _the_c_filter_built_first() -> None:
    """The simulator's RAW filter is C built on first use (fcb_sim.estimation.native): built here, before any test
    starts a simulator whose link would time out while it compiles. Without a compiler the Python filter runs.
    It goes where every run's does (fcb_sim/cbuild.py: the user's cache, one folder per version of the sources),
    so a session builds it only when a source changed; the tests that check the building itself use their own
    folders."""
    from fcb_sim.estimation.native import library

    library()


@pytest.fixture(autouse=True, scope="session")
def _user_data_in_a_temporary_directory(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """term records every session in the platform's user data directory: a test run keeps its own apart
    (platformdirs reads XDG_DATA_HOME; child processes inherit it)."""
    old = os.environ.get("XDG_DATA_HOME")
    os.environ["XDG_DATA_HOME"] = str(tmp_path_factory.mktemp("xdg-data"))
    yield
    if old is None:
        os.environ.pop("XDG_DATA_HOME", None)
    else:
        os.environ["XDG_DATA_HOME"] = old


@pytest.fixture(autouse=True, scope="session")
def _term_log_in_a_temporary_directory(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """term's own log and the simulated board's stderr (term/session/applog.py): kept apart from the user's too."""
    old = os.environ.get("QUADRUPEL_LOG_DIR")
    os.environ["QUADRUPEL_LOG_DIR"] = str(tmp_path_factory.mktemp("log"))
    yield
    if old is None:
        os.environ.pop("QUADRUPEL_LOG_DIR", None)
    else:
        os.environ["QUADRUPEL_LOG_DIR"] = old


@pytest.fixture(autouse=True, scope="session")
def _pilot_waits_on_queues() -> Iterator[None]:
    """Textual's Pilot waits for the app's queues, not for an idle processor that a live link never gives
    (tests/support/textual_drain.py)."""
    from tests.support.textual_drain import pilot_waits_on_queues

    with pilot_waits_on_queues():
        yield


# --- a real pseudo-terminal ---------------------------------------------------------------------------------


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    """A pseudo-terminal, both sides raw from the start: yields (master_fd, slave_path), closes both after.

    The slave stays open here (so the master never sees a hang-up before the test opens it); pyserial opens
    the slave path like any serial device. Close ``master_fd`` early (os.close) to simulate the board going
    away; the fixture then skips it.
    """
    master, slave = os.openpty()
    for fd in (master, slave):
        tty.setraw(fd, termios.TCSANOW)  # raw at once: no echo, no line discipline eating bytes
    path = os.ttyname(slave)
    try:
        yield master, path
    finally:
        for fd in (master, slave):
            with contextlib.suppress(OSError):
                os.close(fd)


# --- a scripted board peer (sans-IO) ------------------------------------------------------------------------


class ScriptedBoard:
    """The board's side of the link, as little as tests need; time is passed in, like the session's."""

    def __init__(
        self,
        *,
        heartbeat_period: float | None = 0.1,
        filler_period: float | None = None,
        protocol: int = PROTOCOL_VERSION,
        answer: bool = True,
        nak: Callable[[Command], Nak] | None = None,
        start: float = 0.0,
    ) -> None:
        self.encoder = Encoder()
        self.decoder = Decoder()
        self.heartbeat_period = heartbeat_period
        self.filler_period = filler_period
        self.protocol = protocol
        self.answer = answer
        self.nak = nak
        self.silent = False  # stop everything outgoing (the board hangs)
        self.received: list[object] = []
        self.commands: list[Command] = []  # every Command frame that arrived, retries included
        self.executed: list[Command] = []  # each command once
        self.hb_acks: list[HeartbeatAck] = []
        self.joysticks: list[Joystick] = []
        self.hellos: list[Hello] = []
        self._last: tuple[Command, Ack] | None = None  # like the firmware: only the last command is remembered
        self._counter = 0
        self._next_hb = start
        self._next_filler = start
        self._filler = 0

    def receive(self, data: bytes, now: float) -> bytes:
        """Bytes from the terminal; returns the board's immediate replies."""
        out = []
        for pkt in self.decoder.feed(data):
            self.received.append(pkt)
            kind = type(pkt)
            if kind is Command:
                self.commands.append(pkt)
                ack = self._on_command(pkt, now)
                if ack is not None and self.answer and not self.silent:
                    out.append(ack)
            elif kind is HeartbeatAck:
                self.hb_acks.append(pkt)
            elif kind is Joystick:
                self.joysticks.append(pkt)
            elif kind is Hello:
                self.hellos.append(pkt)
                if not self.silent:
                    out.append(Hello(self.protocol, 1, 0, 1, 42))
        return self.encoder.encode_many(out)

    def _on_command(self, cmd: Command, now: float) -> Ack | None:
        if self._last is not None and self._last[0] == cmd:
            return self._last[1]  # a retry of the command just executed: answer again, do not execute again
        status = self.nak(cmd) if self.nak is not None else Nak.OK
        self.executed.append(cmd)
        ack = Ack(cmd.cmd_id, cmd.op, int(status), cmd.arg * 10 if status == Nak.OK else 0)
        self._last = (cmd, ack)
        return ack

    def tick(self, now: float) -> bytes:
        """Periodic output due by ``now``: heartbeats and filler frames."""
        out = []
        if self.heartbeat_period is not None:
            while self._next_hb <= now:
                if not self.silent:
                    out.append(Heartbeat(self._counter & 0xFFFF, int(self._next_hb * 1000) & 0xFFFFFFFF))
                self._counter += 1
                self._next_hb += self.heartbeat_period
        if self.filler_period is not None:
            while self._next_filler <= now:
                if not self.silent:
                    out.append(Status(0, self._filler & 0x7FFF, 0, 0, 0, 0, 0, 0))
                self._filler += 1
                self._next_filler += self.filler_period
        return self.encoder.encode_many(out)

    def next_deadline(self) -> float:
        times = []
        if self.heartbeat_period is not None:
            times.append(self._next_hb)
        if self.filler_period is not None:
            times.append(self._next_filler)
        return min(times, default=float("inf"))


@pytest.fixture
def scripted_board() -> Callable[..., ScriptedBoard]:
    return ScriptedBoard


# --- the scripted board on a pty master, on the asyncio loop ------------------------------------------------


class PtyBoard:
    """Runs a ScriptedBoard on a pty's master fd: non-blocking reads via the loop, heartbeats on a task."""

    def __init__(self, master_fd: int, board: ScriptedBoard, clock: Callable[[], float]) -> None:
        self.fd = master_fd
        self.board = board
        self.clock = clock
        self.changed = asyncio.Event()  # set whenever something arrives: tests wait on conditions with it
        self._task: asyncio.Task[None] | None = None
        self._reading = False

    async def start(self) -> None:
        os.set_blocking(self.fd, False)
        asyncio.get_running_loop().add_reader(self.fd, self._on_readable)
        self._reading = True
        self._task = asyncio.create_task(self._ticker())

    def _on_readable(self) -> None:
        try:
            data = os.read(self.fd, 4096)
        except BlockingIOError:
            return
        except OSError:  # EIO while the terminal side is not open: nothing to read
            data = b""
        if not data:
            return
        reply = self.board.receive(data, self.clock())
        if reply:
            self._write(reply)
        self.changed.set()

    def _write(self, data: bytes) -> None:
        with contextlib.suppress(OSError):
            os.write(self.fd, data)

    async def _ticker(self) -> None:
        while True:
            out = self.board.tick(self.clock())
            if out:
                self._write(out)
            await asyncio.sleep(min(3600.0, max(0.0, self.board.next_deadline() - self.clock())))

    async def wait_for(self, cond: Callable[[], bool], timeout: float = 5.0) -> None:
        """Wait until ``cond()`` holds; fails the test after ``timeout`` seconds."""
        async with asyncio.timeout(timeout):
            while not cond():
                self.changed.clear()
                await self.changed.wait()

    async def stop(self, close_fd: bool = False) -> None:
        if self._reading:
            asyncio.get_running_loop().remove_reader(self.fd)
            self._reading = False
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        if close_fd:
            os.close(self.fd)


# --- a discrete-event run of session + channels + board on a fake clock -------------------------------------


class LinkSim:
    """A LinkSession and a ScriptedBoard joined by two FaultyChannels, advanced on a fake clock.

    Every step goes to the next instant anything is due (a session deadline, a board tick, a byte arriving),
    so a run of simulated seconds costs milliseconds and is exactly repeatable.
    """

    def __init__(self, session, board: ScriptedBoard, up=None, down=None, now: float = 0.0) -> None:  # noqa: ANN001
        from term.transports.loopback import FaultyChannel

        self.session = session
        self.board = board
        self.up = up if up is not None else FaultyChannel()  # terminal -> board
        self.down = down if down is not None else FaultyChannel()  # board -> terminal
        self.now = now
        self.events: list[object] = []
        self.up.send(session.hello(), now)

    def step(self, t: float) -> None:
        s = self.session
        self.now = t
        self.events += s.poll(t)
        self.up.send(s.data_to_send(t), t)
        data = self.up.receive(t)
        reply = self.board.receive(data, t) if data else b""
        self.down.send(reply + self.board.tick(t), t)
        data = self.down.receive(t)
        if data:
            self.events += s.receive(data, t)
            self.up.send(s.data_to_send(t), t)

    def run_until(self, end: float, stop: Callable[[], bool] | None = None) -> None:
        while self.now < end:
            if stop is not None and stop():
                return
            times = [self.session.next_deadline(), self.board.next_deadline(), end]
            for ch in (self.up, self.down):
                nxt = ch.next_arrival()
                if nxt is not None:
                    times.append(nxt)
            t = min(max(x, self.now) for x in times)
            if t <= self.now:
                t = self.now + 1e-6  # something was already due: take it a microsecond later
            self.step(min(t, end))

    def of_type(self, kind: type) -> list:
        return [e for e in self.events if type(e) is kind]
